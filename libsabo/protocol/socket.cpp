#include "libsabo/protocol/socket.hpp"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <array>
#include <cerrno>
#include <cstring>

namespace sabo::protocol {

namespace {

// Bodies below this size are copied: a copy is cheaper than the release handshake.
constexpr std::size_t kZeroCopyThreshold = 64 * 1024;

struct ReleaseHint {
  std::shared_ptr<void> keep_alive;
  std::atomic<bool>* in_flight;
};

void release_buffer(void* /*data*/, void* hint) {
  auto* release = static_cast<ReleaseHint*>(hint);
  release->in_flight->store(false, std::memory_order_release);
  delete release;
}

[[noreturn]] void throw_zmq(const zmq::error_t& error, const std::string& what) {
  throw LibraryError(fmt::format("ZeroMQ: {}: {} (errno {})", what, error.what(), error.num()));
}

}  // namespace

SendBuffer::SendBuffer() : state_(std::make_shared<State>()) {}

zmq::message_t SendBuffer::wrap(const google::protobuf::MessageLite& message) {
  const std::size_t size = message.ByteSizeLong();
  last_size_ = 0;
  if (size < kZeroCopyThreshold) {
    zmq::message_t copy(size);
    message.SerializeWithCachedSizesToArray(static_cast<std::uint8_t*>(copy.data()));
    return copy;
  }
  // In lock-step use over ipc or tcp the previous message was released before
  // its reply came back. When it was not (inproc hands the buffer itself to the
  // receiver), continue in a fresh buffer: the old one lives until released.
  if (state_->in_flight.load(std::memory_order_acquire)) state_ = std::make_shared<State>();
  if (state_->bytes.size() < size) state_->bytes.resize(size + size / 8);
  message.SerializeWithCachedSizesToArray(state_->bytes.data());
  state_->in_flight.store(true, std::memory_order_release);
  last_size_ = size;
  auto* hint = new ReleaseHint{state_, &state_->in_flight};
  return zmq::message_t(state_->bytes.data(), size, &release_buffer, hint);
}

std::span<const std::uint8_t> SendBuffer::last_body() const {
  return {state_->bytes.data(), last_size_};
}

void Inbound::parse(google::protobuf::MessageLite& out) const {
  if (!out.ParseFromArray(body.data(), static_cast<int>(body.size()))) {
    throw ProtocolError(fmt::format("{} message of {} bytes does not parse as {}", message_type_name(header.type),
                                    body.size(), out.GetTypeName()));
  }
}

Socket::Socket(zmq::context_t& context, zmq::socket_type kind)
    : socket_(context, kind), is_router_(kind == zmq::socket_type::router) {
  socket_.set(zmq::sockopt::linger, 2000);
  socket_.set(zmq::sockopt::sndhwm, 0);
  socket_.set(zmq::sockopt::rcvhwm, 0);
  if (is_router_) socket_.set(zmq::sockopt::router_mandatory, 1);
}

void Socket::bind(const std::string& endpoint) {
  try {
    socket_.bind(endpoint);
    endpoint_ = socket_.get(zmq::sockopt::last_endpoint);
  } catch (const zmq::error_t& error) {
    throw EndpointError(bind_problem(endpoint, error.num(), error.what()));
  }
}

std::string bind_problem(const std::string& endpoint, int error_number, const std::string& library_text) {
  const bool tcp = endpoint.starts_with("tcp://");
  const std::string rest = endpoint.substr(endpoint.find("://") == std::string::npos ? 0 : endpoint.find("://") + 3);
  const std::string host = tcp ? rest.substr(0, rest.rfind(':')) : std::string();
  const std::string port = tcp && rest.rfind(':') != std::string::npos ? rest.substr(rest.rfind(':') + 1) : "";
  std::string what, fix;
  switch (error_number) {
    case EADDRINUSE:
      what = tcp ? fmt::format("port {} is in use by another program (another run?)", port)
                 : "the socket is in use by another program (another run?)";
      fix = tcp ? "choose another port in the scene's run.endpoint, or stop the program that holds it (ss -ltnp "
                  "shows it)"
                : "give the run its own folder";
      break;
    case ENODEV:
      what = fmt::format(
          "'{}' is neither an IP address of this machine nor the name of one of its network "
          "interfaces",
          host);
      fix =
          "give an address of this machine in run.endpoint, e.g. tcp://127.0.0.1:5555 (this machine only) or "
          "tcp://0.0.0.0:5555 (every interface)";
      break;
    case EADDRNOTAVAIL:
      what = fmt::format("'{}' is not an address of this machine", host);
      fix = "give an address of this machine in run.endpoint (ip addr lists them), e.g. tcp://0.0.0.0:5555";
      break;
    case EACCES:
      what = tcp ? fmt::format("permission denied for port {} (ports below 1024 need root)", port)
                 : "permission denied for the socket's folder";
      fix = tcp ? "use a port from 1024 to 65535" : "run in a folder you can write";
      break;
    case ENOENT:
      what = "the socket's folder does not exist";
      fix = "create the folder first";
      break;
    case ENAMETOOLONG:
      what = "the socket's path is longer than a Unix socket takes (107 bytes)";
      fix = "use a shorter run folder";
      break;
    default:
      what = "it cannot be bound";
      fix = "check the endpoint (tcp://ADDRESS:PORT with an address of this machine, or ipc://PATH)";
      break;
  }
  return fmt::format("cannot listen on {}: {} (ZeroMQ: {}, errno {}). Fix: {}", endpoint, what, library_text,
                     error_number, fix);
}

void Socket::set_max_message_size(std::int64_t bytes) {
  socket_.set(zmq::sockopt::maxmsgsize, bytes);
}

void Socket::set_handshake_interval(std::chrono::milliseconds interval) {
  socket_.set(zmq::sockopt::handshake_ivl, static_cast<int>(interval.count()));
}

void Socket::secure_server(const ServerCredentials& credentials) {
  switch (credentials.mechanism) {
    case Mechanism::curve:
      socket_.set(zmq::sockopt::curve_server, 1);
      socket_.set(zmq::sockopt::curve_secretkey, credentials.own.secret_key);
      break;
    case Mechanism::plain: socket_.set(zmq::sockopt::plain_server, 1); break;
    case Mechanism::none: break;
  }
}

void Socket::secure_client(const ClientCredentials& credentials) {
  switch (credentials.mechanism) {
    case Mechanism::curve:
      socket_.set(zmq::sockopt::curve_serverkey, credentials.server_key);
      socket_.set(zmq::sockopt::curve_publickey, credentials.own.public_key);
      socket_.set(zmq::sockopt::curve_secretkey, credentials.own.secret_key);
      break;
    case Mechanism::plain:
      socket_.set(zmq::sockopt::plain_username, credentials.user);
      socket_.set(zmq::sockopt::plain_password, credentials.token);
      break;
    case Mechanism::none: break;
  }
}

void Socket::set_heartbeat(const Heartbeat& heartbeat) {
  socket_.set(zmq::sockopt::heartbeat_ivl, static_cast<int>(heartbeat.interval.count()));
  socket_.set(zmq::sockopt::heartbeat_timeout, static_cast<int>(heartbeat.timeout.count()));
  // The peer closes its side too when it hears nothing for as long.
  socket_.set(zmq::sockopt::heartbeat_ttl, static_cast<int>(heartbeat.timeout.count()));
}

std::optional<MonitorEvent> decode_monitor_event(const zmq::message_t& head) {
  if (head.size() < 6) return std::nullopt;
  MonitorEvent decoded;
  std::memcpy(&decoded.event, head.data(), sizeof decoded.event);
  std::memcpy(&decoded.value, static_cast<const char*>(head.data()) + 2, sizeof decoded.value);
  return decoded;
}

PeerInfo peer_info(int fd) {
  PeerInfo info;
  if (fd < 0) return info;
  sockaddr_storage address{};
  socklen_t size = sizeof(address);
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&address), &size) != 0) return info;
  std::array<char, INET6_ADDRSTRLEN> text{};
  if (address.ss_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(&address);
    ::inet_ntop(AF_INET, &in->sin_addr, text.data(), text.size());
    info.address = fmt::format("{}:{}", text.data(), ntohs(in->sin_port));
  } else if (address.ss_family == AF_INET6) {
    const auto* in = reinterpret_cast<const sockaddr_in6*>(&address);
    ::inet_ntop(AF_INET6, &in->sin6_addr, text.data(), text.size());
    info.address = fmt::format("[{}]:{}", text.data(), ntohs(in->sin6_port));
  } else if (address.ss_family == AF_UNIX) {
    ucred credentials{};
    socklen_t length = sizeof(credentials);
    if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &credentials, &length) == 0) {
      info.pid = credentials.pid;
      info.uid = static_cast<int>(credentials.uid);
      info.address = fmt::format("pid {}", credentials.pid);
    }
  }
  return info;
}

void Socket::monitor(const std::string& address, int events) {
  if (zmq_socket_monitor(socket_.handle(), address.empty() ? nullptr : address.c_str(), events) != 0) {
    throw LibraryError(
        fmt::format("ZeroMQ: cannot monitor the socket on '{}': {}", address, zmq_strerror(zmq_errno())));
  }
}

void Socket::connect(const std::string& endpoint) {
  try {
    socket_.connect(endpoint);
    endpoint_ = endpoint;
  } catch (const zmq::error_t& error) {
    throw_zmq(error, fmt::format("cannot connect to '{}'", endpoint));
  }
}

zmq::message_t Socket::copy_body(const google::protobuf::MessageLite& message) {
  zmq::message_t body(message.ByteSizeLong());
  message.SerializeWithCachedSizesToArray(static_cast<std::uint8_t*>(body.data()));
  return body;
}

void Socket::send_frames(MessageType type, zmq::message_t body, const std::string& peer) {
  std::array<std::uint8_t, kHeaderSize> header_bytes{};
  encode_header(Header{kProtocolVersion, type}, header_bytes);
  const std::size_t body_size = body.size();
  try {
    if (is_router_) socket_.send(zmq::buffer(peer), zmq::send_flags::sndmore);
    socket_.send(zmq::buffer(header_bytes), zmq::send_flags::sndmore);
    socket_.send(std::move(body), zmq::send_flags::none);
  } catch (const zmq::error_t& error) {
    throw_zmq(error, fmt::format("cannot send {} ({} bytes)", message_type_name(type), body_size));
  }
  bytes_sent_ += kHeaderSize + body_size;
}

bool Socket::receive(Inbound& inbound, std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
  try {
    if (zmq::poll(&item, 1, timeout) == 0) return false;
    frames_.resize(0);
    do {
      frames_.emplace_back();
      (void)socket_.recv(frames_.back(), zmq::recv_flags::none);
      bytes_received_ += frames_.back().size();
    } while (frames_.back().more());
  } catch (const zmq::error_t& error) {
    if (error.num() == EINTR) return false;
    throw_zmq(error, "cannot receive");
  }

  inbound.problem.clear();
  inbound.peer.clear();
  std::size_t first = 0;
  if (is_router_) {
    inbound.peer = frames_[0].to_string();
    inbound.source_fd = zmq_msg_get(frames_.back().handle(), ZMQ_SRCFD);  // -1 when none (inproc)
    inbound.user_id.clear();
    first = 1;
  }
  const std::size_t count = frames_.size() - first;
  if (count != 2) {
    inbound.problem = fmt::format("a Sabo message has 2 frames (header, body), this one has {}", count);
    return true;
  }
  const auto& header = frames_[first];
  auto decoded = decode_header({static_cast<const std::uint8_t*>(header.data()), header.size()}, inbound.problem);
  if (!decoded) return true;
  inbound.header = *decoded;
  if (is_router_ && decoded->type == sabo::v1::MESSAGE_TYPE_REGISTER) {
    const char* user = zmq_msg_gets(frames_[first + 1].handle(), "User-Id");
    if (user != nullptr) inbound.user_id = user;
  }
  if (decoded->version != kProtocolVersion && decoded->type != sabo::v1::MESSAGE_TYPE_REGISTER) {
    inbound.problem = fmt::format("protocol version {} in the header, expected {}", decoded->version, kProtocolVersion);
    return true;
  }
  inbound.body.move(frames_[first + 1]);
  return true;
}

}  // namespace sabo::protocol
