#include "libsabo/protocol/solver_link.hpp"

#include <fmt/format.h>

#include "libsabo/core/signals.hpp"

namespace sabo::protocol {

namespace {
constexpr std::chrono::milliseconds kPollSlice{100};
}

SolverLink::SolverLink(const std::string& endpoint, std::chrono::milliseconds reply_timeout,
                       const ClientCredentials& credentials, const Heartbeat& heartbeat)
    : context_(1),
      socket_(context_, zmq::socket_type::dealer),
      monitor_(context_, zmq::socket_type::pair),
      mechanism_(credentials.mechanism),
      reply_timeout_(reply_timeout) {
  const std::string address = fmt::format("inproc://sabo-solver-link-{}", static_cast<const void*>(this));
  socket_.monitor(address, kHandshakeFailedEvents);
  monitor_.set(zmq::sockopt::linger, 0);
  monitor_.connect(address);
  socket_.secure_client(credentials);
  socket_.set_heartbeat(heartbeat);
  socket_.connect(endpoint);
}

void SolverLink::check_handshake() {
  zmq::message_t head, endpoint;
  try {
    if (!monitor_.recv(head, zmq::recv_flags::dontwait)) return;
    if (head.more()) (void)monitor_.recv(endpoint, zmq::recv_flags::none);
  } catch (const zmq::error_t&) {
    return;
  }
  const auto decoded = decode_monitor_event(head);
  if (!decoded) return;
  const std::uint16_t event = decoded->event;
  const std::uint32_t value = decoded->value;
  const char* keys = mechanism_ == Mechanism::none ? "this solver was started without keys (--keys DIR)"
                                                   : "the keys given with --keys are not the ones of the coupler's run";
  std::string why;
  if (event == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH) {
    why = "it does not know this solver's key or token";
  } else if (event == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL && value == ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH) {
    why = mechanism_ == Mechanism::none ? "it asks for keys" : "it expects another security mechanism";
  } else if (event == ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL) {
    why = fmt::format(
        "it closed the connection during the handshake ({}): it takes another security mechanism, "
        "or keys it does not know",
        zmq_strerror(static_cast<int>(value)));
  } else {
    why = fmt::format("the handshake failed (ZeroMQ event {:#x}, value {:#x})", event, value);
  }
  throw ProtocolError(fmt::format(
      "the coupler at {} refused the connection: {}; {}. Fix: start the solver with --keys RUN_DIR/keys (over tcp "
      "from another host: a copy of RUN_DIR/keys/coupler.key and of this role's .key_secret, docs/security.md)",
      socket_.endpoint(), why, keys));
}

const Inbound& SolverLink::wait_for(MessageType expected, const std::string& what) {
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    if (stop_requested())
      throw StopRequested(fmt::format("stopped by signal {} while waiting for {}", stop_signal(), what));
    if (socket_.receive(inbound_, kPollSlice)) break;
    check_handshake();
    if (std::chrono::steady_clock::now() - start > reply_timeout_) {
      throw LibraryError(fmt::format("the coupler at {} did not answer within {} s while waiting for {}",
                                     socket_.endpoint(), static_cast<double>(reply_timeout_.count()) / 1000.0, what));
    }
  }
  wait_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!inbound_.valid()) throw ProtocolError(fmt::format("invalid message from the coupler: {}", inbound_.problem));
  const auto type = inbound_.header.type;
  if (type == sabo::v1::MESSAGE_TYPE_STOP) {
    sabo::v1::Stop stop;
    inbound_.parse(stop);
    throw StopRequested(fmt::format("the coupler asked to stop: {}", stop.reason()));
  }
  if (type == sabo::v1::MESSAGE_TYPE_ERROR) {
    sabo::v1::Error error;
    inbound_.parse(error);
    throw ProtocolError(fmt::format("the coupler reported an error: {}", error.message()));
  }
  if (type != expected) {
    throw ProtocolError(
        fmt::format("expected {} from the coupler, got {}", message_type_name(expected), message_type_name(type)));
  }
  return inbound_;
}

const sabo::v1::RegisterReply& SolverLink::register_solver(const sabo::v1::Register& registration) {
  socket_.send(registration, state_buffer_);
  wait_for(sabo::v1::MESSAGE_TYPE_REGISTER_REPLY, "the registration reply").parse(register_reply_);
  if (!register_reply_.accepted()) {
    throw ProtocolError(fmt::format("the coupler refused the registration of {}: {}", role_name(registration.role()),
                                    register_reply_.error()));
  }
  return register_reply_;
}

void SolverLink::send_state(const sabo::v1::StepState& state) {
  socket_.send(state, state_buffer_);
}

const sabo::v1::StepForces& SolverLink::receive_forces(std::uint64_t step) {
  wait_for(sabo::v1::MESSAGE_TYPE_STEP_FORCES, fmt::format("the forces of step {}", step)).parse(forces_);
  if (forces_.step() != step) {
    throw ProtocolError(
        fmt::format("the coupler sent the forces of step {} while this solver is at step {}", forces_.step(), step));
  }
  return forces_;
}

void SolverLink::send_goodbye(const sabo::v1::Goodbye& goodbye) {
  try {
    socket_.send(goodbye);
  } catch (const LibraryError&) {
  }
}

void SolverLink::send_error(sabo::v1::Error::Code code, const std::string& message) {
  sabo::v1::Error error;
  error.set_code(code);
  error.set_message(message);
  error.set_fatal(true);
  try {
    socket_.send(error);
  } catch (const LibraryError&) {
  }
}

}  // namespace sabo::protocol
