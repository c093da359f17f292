#pragma once
// Fuzzed frames against a coupler running in this process (tests/fuzz, bench/fuzz_campaign.cpp): from
// peers that never registered while a scripted dem_solver runs the scene (the run must complete, whatever
// they send), and from the registered solver itself (a mutated state: the run goes on if it is valid, or
// ends with an error naming the solver; never a crash or a hang).
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>
#include <zmq.hpp>

#include "coupler/coupler.hpp"
#include "libsabo/protocol/wire.hpp"
#include "tests/support/fuzz.hpp"
#include "tests/support/one_boulder.hpp"

namespace sabo::testing::fuzz {

// A scene of one DEM boulder, for the coupler alone (no solver process: the test scripts it).
scene::Scene one_boulder_scene(const std::filesystem::path& dir);

sabo::v1::Register boulder_registration();
using sabo::testing::boulder_state;

// A raw DEALER speaking the wire format: header and body frames as given, replies as (type, body).
class RawPeer {
 public:
  RawPeer(zmq::context_t& context, const std::string& endpoint) : socket_(context, zmq::socket_type::dealer) {
    socket_.set(zmq::sockopt::linger, 0);
    socket_.connect(endpoint);
  }
  void send_frames(const std::vector<std::string>& frames) {
    for (std::size_t k = 0; k < frames.size(); ++k) {
      socket_.send(zmq::buffer(frames[k]), k + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
    }
  }
  void send(sabo::v1::MessageType type, const std::string& body) { send_frames({header(type), body}); }
  // The next reply within `timeout`: its type (0: none) and body.
  std::pair<int, std::string> receive(std::chrono::milliseconds timeout) {
    zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
    if (zmq::poll(&item, 1, timeout) == 0) return {0, {}};
    std::vector<zmq::message_t> parts;
    do {
      parts.emplace_back();
      (void)socket_.recv(parts.back());
    } while (parts.back().more());
    if (parts.size() != 2 || parts[0].size() != protocol::kHeaderSize) return {-1, {}};
    std::uint16_t type = 0;
    std::memcpy(&type, static_cast<const char*>(parts[0].data()) + 6, sizeof type);
    return {type, parts[1].to_string()};
  }
  // Replies waiting now, read and dropped; how many.
  std::size_t drain() {
    std::size_t count = 0;
    while (receive(std::chrono::milliseconds(0)).first != 0) ++count;
    return count;
  }
  static std::string header(int type, std::uint16_t version = protocol::kProtocolVersion) {
    std::array<std::uint8_t, protocol::kHeaderSize> bytes{};
    protocol::encode_header({version, static_cast<sabo::v1::MessageType>(type)}, bytes);
    return std::string(bytes.begin(), bytes.end());
  }

 private:
  zmq::socket_t socket_;
};

// The coupler of `scene` in a thread, its events in a temporary file.
class CouplerRun {
 public:
  CouplerRun(const scene::Scene& scene, const std::filesystem::path& dir)
      : scene_(scene), endpoint_("ipc://" + (dir / "c.sock").string()), dir_(dir), events_file_(std::tmpfile()) {
    result_ = std::async(std::launch::async, [this] {
      coupler::EventStream events(events_file_);
      coupler::CouplerOptions options;
      options.endpoint = endpoint_;
      options.out_dir = dir_;
      options.registration_timeout = std::chrono::milliseconds(5000);
      coupler::Coupler c(scene_, options, events);
      return c.run();
    });
  }
  ~CouplerRun() {
    if (result_.valid()) result_.wait();
    std::fclose(events_file_);
  }
  CouplerRun(const CouplerRun&) = delete;
  CouplerRun& operator=(const CouplerRun&) = delete;
  [[nodiscard]] const std::string& endpoint() const { return endpoint_; }
  // The exit code, waiting at most `timeout` (-1: still running).
  int wait(std::chrono::seconds timeout) {
    if (result_.wait_for(timeout) != std::future_status::ready) return -1;
    return result_.get();
  }
  [[nodiscard]] std::vector<nlohmann::json> events() const {
    std::fflush(events_file_);
    std::rewind(events_file_);
    std::vector<nlohmann::json> out;
    char line[8192];
    while (std::fgets(line, sizeof line, events_file_) != nullptr) {
      auto event = nlohmann::json::parse(line, nullptr, false);
      if (!event.is_discarded()) out.push_back(std::move(event));
    }
    return out;
  }

 private:
  scene::Scene scene_;
  std::string endpoint_;
  std::filesystem::path dir_;
  std::FILE* events_file_;
  std::future<int> result_;
};

struct FrameOutcome {
  std::size_t frames = 0, answered = 0, hit_and_run = 0;
  std::uint64_t steps = 0;
  int exit_code = -1;
  std::vector<std::string> failures;
};

// One frame from a peer that never registered: raw bytes, a header with random bytes, or a valid message
// mutated (a registration, a state, a goodbye, an error).
std::vector<std::string> fuzzed_frames(Mutator& m);

// `count` fuzzed frames from 8 peers that never register (one in ten from a peer that sends one frame and
// leaves) while the scene's dem_solver runs: the run must complete.
FrameOutcome fuzz_unregistered_frames(std::size_t count, std::uint64_t seed, const std::filesystem::path& dir);

struct StateOutcome {
  std::size_t runs = 0, completed = 0, refused = 0;
  std::vector<std::string> failures;
};

// `count` runs in each of which the registered dem_solver sends one mutated state (at step 0, 1 or 2): the
// run completes (a valid mutant), or ends with exit code 3 and an error event naming the dem_solver.
StateOutcome fuzz_registered_states(std::size_t count, std::uint64_t seed, const std::filesystem::path& dir);

}  // namespace sabo::testing::fuzz
