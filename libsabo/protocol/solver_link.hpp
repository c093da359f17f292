#pragma once
// Solver side of the protocol: connect to the coupler, register, then one
// StepState / StepForces exchange per step (docs/protocol.md).
#include <chrono>
#include <string>

#include "libsabo/protocol/socket.hpp"

namespace sabo::protocol {

class SolverLink {
 public:
  // reply_timeout: how long to wait for any single reply before declaring the
  // coupler gone. SIGINT/SIGTERM end every wait at once (StopRequested).
  // credentials: what the process proves itself with (security.hpp; mechanism none: nothing).
  SolverLink(const std::string& endpoint, std::chrono::milliseconds reply_timeout,
             const ClientCredentials& credentials = {}, const Heartbeat& heartbeat = {});

  // Sends the registration and waits for the reply. Throws ProtocolError with
  // the coupler's reason when the registration is refused.
  const sabo::v1::RegisterReply& register_solver(const sabo::v1::Register& registration);

  void send_state(const sabo::v1::StepState& state);
  // Waits for the forces of `step`. Throws StopRequested when the coupler sends
  // Stop or a stop signal arrives, ProtocolError on an Error message or a reply
  // that breaks the protocol, LibraryError when the coupler does not answer.
  const sabo::v1::StepForces& receive_forces(std::uint64_t step);

  // Best effort: the coupler may already be gone.
  void send_goodbye(const sabo::v1::Goodbye& goodbye);
  void send_error(sabo::v1::Error::Code code, const std::string& message);

  [[nodiscard]] double wait_seconds() const { return wait_seconds_; }
  [[nodiscard]] const Socket& socket() const { return socket_; }

 private:
  // Waits for the next valid message; handles Stop and Error messages.
  const Inbound& wait_for(MessageType expected, const std::string& what);
  // Throws ProtocolError when the coupler refused the handshake (the socket's monitor says so): ZeroMQ would
  // otherwise try again and again, and the solver wait for a reply that cannot come.
  void check_handshake();

  zmq::context_t context_;
  Socket socket_;
  zmq::socket_t monitor_;
  Mechanism mechanism_;
  SendBuffer state_buffer_;
  Inbound inbound_;
  sabo::v1::RegisterReply register_reply_;
  sabo::v1::StepForces forces_;
  std::chrono::milliseconds reply_timeout_;
  double wait_seconds_ = 0;
};

}  // namespace sabo::protocol
