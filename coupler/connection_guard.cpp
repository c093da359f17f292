#include "coupler/connection_guard.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <vector>

namespace sabo::coupler {
namespace {

using Clock = std::chrono::steady_clock;
constexpr std::chrono::milliseconds kTickInterval{100};
constexpr int kEvents =
    ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_CLOSED | protocol::kHandshakeFailedEvents;
constexpr std::size_t kRefusalsKept = 100;
// How long registered() waits for the "accepted" event of a connection (microseconds, normally).
constexpr std::chrono::milliseconds kSyncLimit{2000};

// "10.0.0.3:41234" -> "10.0.0.3" (a refused client tries again from another port); "pid 12" as it is.
std::string host_of(const std::string& address) {
  return address.starts_with("pid ") ? address : address.substr(0, address.rfind(':'));
}

std::string handshake_problem(std::uint16_t event, std::uint32_t value) {
  if (event == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH) {
    return fmt::format("its key or token is not one of this run's (authentication refused, ZAP status {})", value);
  }
  if (event == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL) {
    switch (value) {
      case ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH:
        return "it offers another security mechanism than this coupler's (no keys, or the wrong kind)";
      case ZMQ_PROTOCOL_ERROR_ZMTP_CRYPTOGRAPHIC:
        return "its CURVE handshake does not decrypt (a replayed or forged handshake, or the wrong coupler key)";
      case ZMQ_PROTOCOL_ERROR_ZMTP_KEY_EXCHANGE: return "its CURVE key exchange failed";
      default:
        return fmt::format(
            "its handshake breaks the protocol (replayed, forged or garbled; ZeroMQ protocol error {:#x})", value);
    }
  }
  // The peer gave up first (it saw this coupler's greeting ask for another mechanism, say): no detail but errno.
  return fmt::format(
      "it closed the connection during the handshake ({}): it offers another security mechanism, or none",
      value == 0 ? std::string("no detail") : zmq_strerror(static_cast<int>(value)));
}
}  // namespace

ConnectionGuard::ConnectionGuard(zmq::context_t& context, protocol::Socket& socket, ConnectionLimits limits,
                                 Authenticator* authenticator)
    : socket_(socket),
      limits_(limits),
      authenticator_(authenticator),
      monitor_(context, zmq::socket_type::pair),
      relay_(context, zmq::socket_type::pair),
      events_(context, zmq::socket_type::pair),
      address_(fmt::format("inproc://sabo-connection-guard-{}", static_cast<const void*>(this))) {
  const std::string monitor_address = address_ + "-monitor";
  socket_.monitor(monitor_address, kEvents);
  for (auto* pair : {&monitor_, &relay_, &events_}) {
    pair->set(zmq::sockopt::linger, 0);
    pair->set(zmq::sockopt::rcvhwm, 0);  // no limit on the events queued between two ticks: none is lost
    pair->set(zmq::sockopt::sndhwm, 0);
  }
  monitor_.connect(monitor_address);
  relay_.bind(address_);
  events_.connect(address_);
  relay_thread_ = std::thread([this] { relay(); });
  reserve_fd_ = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
}

ConnectionGuard::~ConnectionGuard() {
  stop_relay_ = true;
  if (relay_thread_.joinable()) relay_thread_.join();
  release_reserve();
  try {
    socket_.monitor("", 0);  // stops the monitor
  } catch (const std::exception&) {
  }
}

void ConnectionGuard::relay() {
  zmq::message_t head, endpoint;
  while (!stop_relay_) {
    zmq::pollitem_t item{monitor_.handle(), 0, ZMQ_POLLIN, 0};
    try {
      if (zmq::poll(&item, 1, kTickInterval) == 0) continue;
      if (!monitor_.recv(head, zmq::recv_flags::none)) continue;
      if (head.more()) (void)monitor_.recv(endpoint, zmq::recv_flags::none);
      std::string peer;
      if (const auto decoded = protocol::decode_monitor_event(head); decoded && decoded->event == ZMQ_EVENT_ACCEPTED) {
        peer = protocol::peer_info(decoded->fd()).address;
      }
      relay_.send(head, zmq::send_flags::sndmore);
      relay_.send(zmq::buffer(peer), zmq::send_flags::none);
    } catch (const zmq::error_t&) {
      return;  // the context is ending
    }
  }
}

void ConnectionGuard::release_reserve() {
  if (reserve_fd_ >= 0) ::close(reserve_fd_);
  reserve_fd_ = -1;
}

void ConnectionGuard::registered(int fd) {
  if (fd < 0) return;
  // The monitor's "accepted" event of this connection may still be queued (the guard reads them at most
  // every 100 ms), or still on its way through the relay thread: read up to it, or it would later file the
  // solver's connection as unregistered. The connection is open (its message just came), so the last event
  // of its descriptor is then its "accepted" one; whatever ended before under the same descriptor number (a
  // dead solver whose replacement this is, say) is no loss of this connection.
  drain();
  const auto deadline = Clock::now() + kSyncLimit;
  while (open_.count(fd) == 0 && Clock::now() < deadline) {
    zmq::pollitem_t item{events_.handle(), 0, ZMQ_POLLIN, 0};
    try {
      (void)zmq::poll(&item, 1, std::chrono::milliseconds(10));
    } catch (const zmq::error_t&) {
      break;
    }
    drain();
  }
  lost_.erase(std::remove(lost_.begin(), lost_.end(), fd), lost_.end());
  registered_.insert(fd);
  open_.erase(fd);
  addresses_.erase(fd);
}

std::vector<int> ConnectionGuard::take_lost() {
  // What tick() has read (every 100 ms): the coupler asks for every message, and a lost connection is
  // heartbeat_timeout old already.
  std::vector<int> lost;
  lost.swap(lost_);
  return lost;
}

void ConnectionGuard::drain() {
  zmq::message_t head, address;
  while (true) {
    try {
      if (!events_.recv(head, zmq::recv_flags::dontwait)) return;
      if (head.more()) (void)events_.recv(address, zmq::recv_flags::none);  // the relay's: the peer's address
    } catch (const zmq::error_t&) {
      return;
    }
    const auto decoded = protocol::decode_monitor_event(head);
    if (!decoded) continue;
    const std::uint16_t event = decoded->event;
    const int fd = decoded->fd();
    if (event == ZMQ_EVENT_ACCEPTED) {
      ++stats_.accepted;
      registered_.erase(fd);  // a descriptor number ZeroMQ gave to a new connection
      open_[fd] = Clock::now();
      addresses_[fd] = address.to_string();
      stats_.most_unregistered = std::max(stats_.most_unregistered, open_.size());
    } else if ((event & protocol::kHandshakeFailedEvents) != 0) {
      // The value is the reason, not the descriptor: the connection's end follows at once (one I/O thread).
      ++stats_.refused_handshakes;
      handshake_failure_ = handshake_problem(event, decoded->value);
      if (event == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH && authenticator_ != nullptr) {
        if (auto refusal = authenticator_->take_refusal()) handshake_failure_ = refusal->reason;
      }
    } else {
      if (!handshake_failure_.empty()) {
        const auto known = addresses_.find(fd);
        const std::string peer = known == addresses_.end() || known->second.empty() ? "unknown" : known->second;
        auto same = std::find_if(refused_.begin(), refused_.end(), [&](const RefusedConnection& r) {
          return r.reason == handshake_failure_ && host_of(r.address) == host_of(peer);
        });
        if (same != refused_.end()) {
          ++same->count;
        } else {
          spdlog::warn("refused a connection from {}: {} (the same again from there is counted, not logged)", peer,
                       handshake_failure_);
          if (refused_.size() < kRefusalsKept) refused_.push_back({peer, handshake_failure_, 1});
        }
        handshake_failure_.clear();
      }
      if (registered_.count(fd) != 0) lost_.push_back(fd);
      open_.erase(fd);
      addresses_.erase(fd);
      registered_.erase(fd);
    }
  }
}

void ConnectionGuard::shut(int fd) {
  // ZeroMQ owns the descriptor: only end the stream (it reads the end and closes the connection itself).
  if (::shutdown(fd, SHUT_RDWR) != 0) {
    spdlog::debug("shutdown of connection fd {} failed: {}", fd, std::strerror(errno));
  }
  open_.erase(fd);
}

void ConnectionGuard::tick() {
  const auto now = Clock::now();
  if (now - last_tick_ < kTickInterval) return;
  last_tick_ = now;
  drain();
  std::vector<int> late;
  for (const auto& [fd, since] : open_) {
    if (now - since > limits_.window) late.push_back(fd);
  }
  for (int fd : late) {
    shut(fd);
    ++stats_.dropped_unregistered;
  }
  if (open_.size() > limits_.max_unregistered) {
    // Only connections the guard knew before this tick: one it has just learnt of may have its Register
    // queued in the socket already, unread, and is judged at the next tick (with max_unregistered = 0
    // every solver's connection would otherwise race its own registration).
    std::vector<std::pair<Clock::time_point, int>> by_age;
    for (const auto& [fd, since] : open_) {
      if (since < now) by_age.emplace_back(since, fd);
    }
    std::sort(by_age.begin(), by_age.end());
    const std::size_t excess = std::min(open_.size() - limits_.max_unregistered, by_age.size());
    for (std::size_t k = 0; k < excess; ++k) {
      shut(by_age[k].second);
      ++stats_.dropped_over_limit;
    }
  }
  if (!late.empty()) {
    spdlog::info("closed {} connections that did not register within {} s ({} unregistered now)", late.size(),
                 std::chrono::duration<double>(limits_.window).count(), open_.size());
  }
}

}  // namespace sabo::coupler
