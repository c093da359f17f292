#pragma once
// Thin RAII layer over cppzmq for the Sabo wire format (wire.hpp): typed
// errors carrying ZeroMQ's own text, two-frame messages, and zero-copy sends
// from buffers that are reused from one step to the next.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "libsabo/core/error.hpp"
#include "libsabo/protocol/security.hpp"
#include "libsabo/protocol/wire.hpp"

namespace sabo::protocol {

// Storage for outgoing message bodies, handed to ZeroMQ without a copy and
// reused for the next message once ZeroMQ has released it.
class SendBuffer {
 public:
  SendBuffer();
  // Serializes `message` into the buffer and returns a ZeroMQ message over it.
  zmq::message_t wrap(const google::protobuf::MessageLite& message);
  // The body of the last wrap() when it was handed over without a copy (ZeroMQ only reads it), valid until
  // the next wrap(); empty when it was copied (a small body) or before the first: a caller that needs the
  // bytes as well (the coupler's restart journal) need not serialize the message a second time.
  [[nodiscard]] std::span<const std::uint8_t> last_body() const;

 private:
  struct State {
    std::atomic<bool> in_flight{false};
    std::vector<std::uint8_t> bytes;
  };
  std::shared_ptr<State> state_;
  std::size_t last_size_ = 0;  // of the last zero-copy body; 0: the last was copied
};

// One received message: the peer identity (ROUTER only), header and body.
struct Inbound {
  std::string peer;
  Header header;
  zmq::message_t body;
  std::string problem;  // non-empty: the frames were not a valid Sabo message
  int source_fd = -1;   // ROUTER: the file descriptor of the connection it came in on (ZMQ_SRCFD)
  // Register messages only: the name the connection authenticated as (ZAP's User-Id; empty without
  // authentication).
  std::string user_id;

  [[nodiscard]] bool valid() const { return problem.empty(); }
  // Parses the body into `out`; throws ProtocolError when it is not a valid message.
  void parse(google::protobuf::MessageLite& out) const;
};

// Who is at the other end of a connection (Inbound::source_fd): for tcp its address and port; for ipc the
// process and user the kernel names (SO_PEERCRED).
struct PeerInfo {
  std::string address;  // "10.0.0.2:41234"; ipc: "pid 1234"
  int pid = 0;          // ipc; 0: not known
  int uid = -1;         // ipc; -1: not known
};
[[nodiscard]] PeerInfo peer_info(int fd);

// A socket monitor's event (zmq_socket_monitor): its first frame holds the event (uint16) and a value (uint32:
// the descriptor of a connection's events, the reason of a failed handshake).
struct MonitorEvent {
  std::uint16_t event = 0;
  std::uint32_t value = 0;
  [[nodiscard]] int fd() const { return static_cast<int>(value); }
};
// nullopt when `head` is not such a frame.
[[nodiscard]] std::optional<MonitorEvent> decode_monitor_event(const zmq::message_t& head);
// The events of a handshake that failed: the peer's credentials (or the lack of them) refused.
inline constexpr int kHandshakeFailedEvents =
    ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL | ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL | ZMQ_EVENT_HANDSHAKE_FAILED_AUTH;

// What is wrong with `endpoint` when binding it failed with `error_number` (errno), and the fix: the text
// of the EndpointError that Socket::bind throws.
[[nodiscard]] std::string bind_problem(const std::string& endpoint, int error_number, const std::string& library_text);

class Socket {
 public:
  // kind: zmq::socket_type::router (coupler) or dealer (solver).
  Socket(zmq::context_t& context, zmq::socket_type kind);
  // Throws EndpointError (bind_problem) when the endpoint cannot be bound.
  void bind(const std::string& endpoint);
  // Before bind: frames larger than `bytes` make ZeroMQ close the connection they come on, unread
  // (ZMQ_MAXMSGSIZE; -1: no limit); a connection that has not completed ZeroMQ's greeting within `interval`
  // is closed (ZMQ_HANDSHAKE_IVL).
  void set_max_message_size(std::int64_t bytes);
  void set_handshake_interval(std::chrono::milliseconds interval);
  // Before bind or connect (security.hpp). The server: CURVE with the coupler's pair over tcp, PLAIN over ipc,
  // both answered by a ZAP handler in the same context (coupler/authenticator.hpp); without one ZeroMQ would
  // let every client in. The client: its pair and the server's key, or its role and the run's token.
  void secure_server(const ServerCredentials& credentials);
  void secure_client(const ClientCredentials& credentials);
  void set_heartbeat(const Heartbeat& heartbeat);
  // Publishes the socket's connection events `events` (ZMQ_EVENT_*) on the inproc `address` (a PAIR socket
  // reads them); an empty address stops it.
  void monitor(const std::string& address, int events);
  void connect(const std::string& endpoint);

  // Sends header + body (preceded by the peer identity on a ROUTER).
  template <class Message>
  void send(const Message& message, SendBuffer& buffer, const std::string& peer = {}) {
    send_frames(message_type_of<Message>(), buffer.wrap(message), peer);
  }
  // Sends a small message by copy (registration replies, errors, stops).
  template <class Message>
  void send(const Message& message, const std::string& peer = {}) {
    send_frames(message_type_of<Message>(), copy_body(message), peer);
  }

  // Waits up to `timeout` for one message. Returns false on timeout. Frames that
  // are not a Sabo message are returned with `problem` set, never thrown.
  bool receive(Inbound& inbound, std::chrono::milliseconds timeout);

  [[nodiscard]] std::uint64_t bytes_sent() const { return bytes_sent_; }
  [[nodiscard]] std::uint64_t bytes_received() const { return bytes_received_; }
  [[nodiscard]] const std::string& endpoint() const { return endpoint_; }

 private:
  static zmq::message_t copy_body(const google::protobuf::MessageLite& message);
  void send_frames(MessageType type, zmq::message_t body, const std::string& peer);

  zmq::socket_t socket_;
  bool is_router_;
  std::string endpoint_;
  std::uint64_t bytes_sent_ = 0;
  std::uint64_t bytes_received_ = 0;
  std::vector<zmq::message_t> frames_;
};

}  // namespace sabo::protocol
