#pragma once
// Keeps peers that do not register from taking the coupler's connections
// (issue 18: 1,500 idle connections exhausted its file descriptors, after
// which the real solvers could not register).
//
// ZeroMQ offers no limit on a ROUTER's connections. What it does offer:
// ZMQ_HANDSHAKE_IVL closes a connection that has not completed the ZMTP
// greeting in time (a raw TCP client that sends nothing), ZMQ_MAXMSGSIZE
// closes one that announces a larger frame, and a socket monitor reports each
// accepted connection with its file descriptor (ZMQ_EVENT_ACCEPTED) and each
// one that ends (ZMQ_EVENT_DISCONNECTED, ZMQ_EVENT_CLOSED). A message carries
// the descriptor it came in on (ZMQ_SRCFD). The guard uses these: a
// connection that has not carried an accepted registration within `window`,
// or beyond the `max_unregistered` most recent such connections (judged from the
// tick after the one that reads its "accepted" event, so that a Register already
// queued is read first), is shut down (shutdown(2), SHUT_RDWR: ZeroMQ then sees the end of the stream and closes
// it as if the peer had left). The connections of registered solvers are never
// touched. A DEALER that is cut off reconnects by itself.
//
// The same monitor reports each handshake that fails (a peer without this run's keys or token, or with
// none: ZMQ_EVENT_HANDSHAKE_FAILED_*); the guard logs it with the peer's address, read from the connection
// when it was accepted. And it reports the end of a registered solver's connection: with ZMTP heartbeats
// (security.hpp) also one whose host vanished or whose process stopped; the coupler takes those from lost().
//
// What it cannot do: a flood of new connections faster than one tick (100 ms)
// can fill the descriptors between two ticks (ZeroMQ then retries its accept;
// the coupler raises RLIMIT_NOFILE to its hard limit at start); the descriptor
// of a connection that ZeroMQ closes at the very moment the guard shuts it may
// already belong to a new connection (the monitor reports the close after the
// fact), which is then cut off once and reconnects.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "coupler/authenticator.hpp"
#include "libsabo/protocol/socket.hpp"

namespace sabo::coupler {

struct ConnectionLimits {
  std::chrono::milliseconds window{10000};  // to register, from the connection's start
  std::size_t max_unregistered = 64;        // connections not registered, kept at once
};

struct ConnectionStats {
  std::uint64_t accepted = 0;
  std::uint64_t dropped_unregistered = 0;  // shut after `window` without a registration
  std::uint64_t dropped_over_limit = 0;    // shut as the oldest beyond max_unregistered
  std::size_t most_unregistered = 0;       // the largest number open at once
  std::uint64_t refused_handshakes = 0;    // closed at the handshake: no valid key or token
};

// Connections closed at their handshake, from one peer for one reason (a refused ZeroMQ client tries again
// every 100 ms: logged once, counted).
struct RefusedConnection {
  std::string address;  // of the first: "10.0.0.3:41234", "pid 1234" (ipc), or "unknown"
  std::string reason;
  std::uint64_t count = 0;
};

class ConnectionGuard {
 public:
  // Monitors `socket` (before it binds); `context` is the socket's.
  // `authenticator`: the coupler's ZAP handler (null: none), which says why it refused a handshake.
  ConnectionGuard(zmq::context_t& context, protocol::Socket& socket, ConnectionLimits limits,
                  Authenticator* authenticator = nullptr);
  ~ConnectionGuard();
  ConnectionGuard(const ConnectionGuard&) = delete;
  ConnectionGuard& operator=(const ConnectionGuard&) = delete;

  // The connection a registered solver's message came in on (Inbound::source_fd): never shut.
  void registered(int fd);
  // Reads the monitor's events and shuts the connections beyond the limits; does the work at most every
  // 100 ms, so that it may be called for every message.
  void tick();

  // The connections of registered solvers that ended since the last call (their descriptors).
  [[nodiscard]] std::vector<int> take_lost();
  // The handshakes refused so far, one entry per peer host and reason (the first 100), for summary.json.
  [[nodiscard]] const std::vector<RefusedConnection>& refused() const { return refused_; }

  // Closes the descriptor kept in reserve from the start (on /dev/null), so that a file can still be opened
  // when connections have taken every other one (the coupler's summary.json at the end).
  void release_reserve();

  [[nodiscard]] const ConnectionStats& stats() const { return stats_; }
  [[nodiscard]] std::size_t unregistered() const { return open_.size(); }

 private:
  void drain();
  void shut(int fd);
  // The relay thread: reads the monitor's events as they come and passes them on with the peer's address of
  // each accepted connection, read at once (a connection refused at its handshake is gone a moment later).
  void relay();

  protocol::Socket& socket_;
  ConnectionLimits limits_;
  Authenticator* authenticator_;
  zmq::socket_t monitor_;  // the relay thread's: the monitor's events
  zmq::socket_t relay_;    // the relay thread's: the events passed on
  zmq::socket_t events_;   // what the guard reads
  std::string address_;
  std::map<int, std::chrono::steady_clock::time_point> open_;  // unregistered: fd -> accepted at
  std::map<int, std::string> addresses_;                       // unregistered: fd -> the peer's address
  std::set<int> registered_;
  std::vector<int> lost_;
  std::string handshake_failure_;  // the reason of the last failed handshake, for the disconnection that follows
  std::vector<RefusedConnection> refused_;
  std::chrono::steady_clock::time_point last_tick_{};
  int reserve_fd_ = -1;
  std::atomic<bool> stop_relay_{false};
  std::thread relay_thread_;
  ConnectionStats stats_;
};

}  // namespace sabo::coupler
