#pragma once
// The coupler's ZAP handler (ZeroMQ RFC 27): ZeroMQ asks it, during each connection's handshake, whether the
// peer may join, and refuses the connection at the handshake when it says no. It accepts
//   CURVE (tcp): a client whose public key is one of the run's roles' (security.hpp), as that role;
//   PLAIN (ipc): a client that gives a role name of the scene and the run's token, as that role;
// and nothing else. The role it names becomes the connection's User-Id, which the coupler holds against the
// role a Register claims (a dem_solver's key cannot register a fem_solver).
//
// It answers on its own thread: a handshake must not wait for a coupling step to end. It must exist before the
// coupler's socket binds: a CURVE or PLAIN server without a ZAP handler lets every client in.
#include <atomic>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "libsabo/protocol/security.hpp"

namespace sabo::coupler {

class Authenticator {
 public:
  struct Refusal {
    std::string address;    // the peer's IP address (tcp), empty for ipc
    std::string mechanism;  // "CURVE", "PLAIN", "NULL"
    std::string reason;
  };

  Authenticator(zmq::context_t& context, protocol::ServerCredentials credentials);
  ~Authenticator();
  Authenticator(const Authenticator&) = delete;
  Authenticator& operator=(const Authenticator&) = delete;

  // The oldest refusal not taken yet (the connection guard logs it with the connection's end).
  [[nodiscard]] std::optional<Refusal> take_refusal();
  [[nodiscard]] std::uint64_t accepted() const { return accepted_.load(); }
  [[nodiscard]] std::uint64_t refused() const { return refused_.load(); }

  // The decision for one request, without the sockets (what the thread runs; tested on its own): the role the
  // peer authenticates as, or nullopt and why not in `reason`.
  [[nodiscard]] std::optional<std::string> decide(const std::string& mechanism,
                                                  const std::vector<std::string>& credentials,
                                                  std::string& reason) const;

 private:
  void serve();

  protocol::ServerCredentials credentials_;
  zmq::socket_t socket_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> accepted_{0};
  std::atomic<std::uint64_t> refused_{0};
  std::mutex mutex_;
  std::deque<Refusal> refusals_;
  std::thread thread_;
};

}  // namespace sabo::coupler
