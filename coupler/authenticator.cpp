#include "coupler/authenticator.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "libsabo/core/error.hpp"

namespace sabo::coupler {

namespace {

constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";  // fixed by RFC 27
constexpr std::chrono::milliseconds kPollSlice{100};

// Equal strings, in a time that does not depend on where they differ.
bool same_secret(const std::string& a, const std::string& b) {
  unsigned char difference = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::max(a.size(), b.size());
  for (std::size_t k = 0; k < n; ++k) {
    const auto x = static_cast<unsigned char>(k < a.size() ? a[k] : 0);
    const auto y = static_cast<unsigned char>(k < b.size() ? b[k] : 0);
    difference |= static_cast<unsigned char>(x ^ y);
  }
  return difference == 0;
}

std::string z85_of(const std::string& key) {
  std::array<char, 41> text{};
  if (key.size() != 32 || zmq_z85_encode(text.data(), reinterpret_cast<const std::uint8_t*>(key.data()), 32) == nullptr)
    return "(not a 32-byte key)";
  return text.data();
}

}  // namespace

Authenticator::Authenticator(zmq::context_t& context, protocol::ServerCredentials credentials)
    : credentials_(std::move(credentials)), socket_(context, zmq::socket_type::rep) {
  socket_.set(zmq::sockopt::linger, 0);
  try {
    socket_.bind(kZapEndpoint);
  } catch (const zmq::error_t& error) {
    throw LibraryError(fmt::format("ZeroMQ: cannot start the authenticator on {}: {} (errno {})", kZapEndpoint,
                                   error.what(), error.num()));
  }
  thread_ = std::thread([this] { serve(); });
}

Authenticator::~Authenticator() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

std::optional<Authenticator::Refusal> Authenticator::take_refusal() {
  std::lock_guard lock(mutex_);
  if (refusals_.empty()) return std::nullopt;
  Refusal oldest = std::move(refusals_.front());
  refusals_.pop_front();
  return oldest;
}

std::optional<std::string> Authenticator::decide(const std::string& mechanism,
                                                 const std::vector<std::string>& credentials,
                                                 std::string& reason) const {
  using protocol::Mechanism;
  if (mechanism == "CURVE" && credentials_.mechanism == Mechanism::curve) {
    if (credentials.size() != 1) {
      reason = "a CURVE handshake without the client's key";
      return std::nullopt;
    }
    if (auto it = credentials_.clients.find(credentials[0]); it != credentials_.clients.end()) return it->second;
    reason = fmt::format("its CURVE key {} is not one of this run's (keys/*.key)", z85_of(credentials[0]));
    return std::nullopt;
  }
  if (mechanism == "PLAIN" && credentials_.mechanism == Mechanism::plain) {
    if (credentials.size() != 2) {
      reason = "a PLAIN handshake without a name and a token";
      return std::nullopt;
    }
    const std::string& user = credentials[0];
    const bool known =
        std::find(credentials_.roles.begin(), credentials_.roles.end(), user) != credentials_.roles.end();
    // Compare the token first, whatever the name: the answer's time then tells nothing of the token.
    const bool token = same_secret(credentials[1], credentials_.token);
    if (!token) {
      reason = fmt::format("'{}' gave a token that is not this run's (keys/ipc.token)", excerpt(user, 40));
      return std::nullopt;
    }
    if (!known) {
      reason = fmt::format("'{}' is not a role of this scene", excerpt(user, 40));
      return std::nullopt;
    }
    return user;
  }
  reason = fmt::format("it offers the {} mechanism; this coupler takes only {}", mechanism,
                       credentials_.mechanism == Mechanism::curve ? "CURVE keys" : "the run's token");
  return std::nullopt;
}

void Authenticator::serve() {
  std::vector<zmq::message_t> frames;
  while (!stop_) {
    zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
    try {
      if (zmq::poll(&item, 1, kPollSlice) == 0) continue;
      frames.clear();
      do {
        frames.emplace_back();
        (void)socket_.recv(frames.back(), zmq::recv_flags::none);
      } while (frames.back().more());
    } catch (const zmq::error_t& error) {
      if (error.num() == EINTR) continue;
      return;  // the context is ending
    }
    // version, request id, domain, address, identity, mechanism, credentials...
    std::string status = "400", text = "malformed ZAP request", user;
    std::string request_id, address, mechanism = "?";
    if (frames.size() >= 6 && frames[0].to_string() == "1.0") {
      request_id = frames[1].to_string();
      address = frames[3].to_string();
      mechanism = frames[5].to_string();
      std::vector<std::string> credentials;
      for (std::size_t k = 6; k < frames.size(); ++k) credentials.push_back(frames[k].to_string());
      std::string reason;
      if (auto role = decide(mechanism, credentials, reason)) {
        status = "200";
        text = "OK";
        user = *role;
        ++accepted_;
      } else {
        text = reason;
      }
    }
    if (status != "200") {
      ++refused_;
      std::lock_guard lock(mutex_);
      if (refusals_.size() < 1000) refusals_.push_back({address, mechanism, text});
    }
    try {
      socket_.send(zmq::str_buffer("1.0"), zmq::send_flags::sndmore);
      socket_.send(zmq::buffer(request_id), zmq::send_flags::sndmore);
      socket_.send(zmq::buffer(status), zmq::send_flags::sndmore);
      socket_.send(zmq::buffer(text), zmq::send_flags::sndmore);
      socket_.send(zmq::buffer(user), zmq::send_flags::sndmore);
      socket_.send(zmq::str_buffer(""), zmq::send_flags::none);
    } catch (const zmq::error_t&) {
      return;
    }
  }
}

}  // namespace sabo::coupler
