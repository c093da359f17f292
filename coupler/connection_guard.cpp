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
constexpr int kEvents = ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_CLOSED;

}  // namespace

ConnectionGuard::ConnectionGuard(zmq::context_t& context, protocol::Socket& socket, ConnectionLimits limits)
    : socket_(socket),
      limits_(limits),
      events_(context, zmq::socket_type::pair),
      address_(fmt::format("inproc://sabo-connection-guard-{}", static_cast<const void*>(this))) {
  socket_.monitor(address_, kEvents);
  events_.set(zmq::sockopt::linger, 0);
  events_.set(zmq::sockopt::rcvhwm, 0);  // no limit on the events queued between two ticks: none is lost
  events_.connect(address_);
  reserve_fd_ = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
}

ConnectionGuard::~ConnectionGuard() {
  release_reserve();
  try {
    socket_.monitor("", 0);  // stops the monitor
  } catch (const std::exception&) {
  }
}

void ConnectionGuard::release_reserve() {
  if (reserve_fd_ >= 0) ::close(reserve_fd_);
  reserve_fd_ = -1;
}

void ConnectionGuard::registered(int fd) {
  if (fd < 0) return;
  // The monitor's "accepted" event of this connection may still be queued (the guard reads them at most
  // every 100 ms): read it first, or it would later file the solver's connection as unregistered.
  drain();
  registered_.insert(fd);
  open_.erase(fd);
}

void ConnectionGuard::drain() {
  zmq::message_t head, address;
  while (true) {
    try {
      if (!events_.recv(head, zmq::recv_flags::dontwait)) return;
      if (head.more()) (void)events_.recv(address, zmq::recv_flags::none);
    } catch (const zmq::error_t&) {
      return;
    }
    if (head.size() < 6) continue;
    std::uint16_t event = 0;
    std::int32_t fd = -1;
    std::memcpy(&event, head.data(), sizeof event);
    std::memcpy(&fd, static_cast<const char*>(head.data()) + 2, sizeof fd);
    if (event == ZMQ_EVENT_ACCEPTED) {
      ++stats_.accepted;
      registered_.erase(fd);  // a descriptor number ZeroMQ gave to a new connection
      open_[fd] = Clock::now();
      stats_.most_unregistered = std::max(stats_.most_unregistered, open_.size());
    } else {
      open_.erase(fd);
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
