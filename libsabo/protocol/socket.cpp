#include "libsabo/protocol/socket.hpp"

#include <fmt/format.h>

#include <array>

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
  auto* hint = new ReleaseHint{state_, &state_->in_flight};
  return zmq::message_t(state_->bytes.data(), size, &release_buffer, hint);
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
    throw_zmq(error, fmt::format("cannot bind '{}' (is another run using it?)", endpoint));
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
  if (decoded->version != kProtocolVersion && decoded->type != sabo::v1::MESSAGE_TYPE_REGISTER) {
    inbound.problem = fmt::format("protocol version {} in the header, expected {}", decoded->version, kProtocolVersion);
    return true;
  }
  inbound.body.move(frames_[first + 1]);
  return true;
}

}  // namespace sabo::protocol
