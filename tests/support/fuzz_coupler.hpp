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
inline scene::Scene one_boulder_scene(const std::filesystem::path& dir) {
  scene::Scene scene;
  scene.file = dir / "scene.toml";
  std::ofstream(scene.file) << "# fuzz scene\n";
  scene.recording.enabled = false;
  scene.run.end_time = 0.01;
  scene.run.output_interval = 0.005;
  scene.run.hang_timeout = 5.0;
  add_one_boulder(scene);
  return scene;
}

inline sabo::v1::Register boulder_registration() {
  return sabo::testing::boulder_registration("fuzz dem");
}
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
inline std::vector<std::string> fuzzed_frames(Mutator& m) {
  switch (m.below(5)) {
    case 0: {
      std::vector<std::string> frames(1 + m.below(3));
      for (auto& frame : frames) frame = m.bytes(m.below(200));
      return frames;
    }
    case 1: return {RawPeer::header(static_cast<int>(m.below(10)), m.chance(0.1) ? 7 : 1), m.bytes(m.below(300))};
    case 2:
      return {RawPeer::header(sabo::v1::MESSAGE_TYPE_REGISTER),
              m.mutate_bytes(boulder_registration().SerializeAsString())};
    case 3:
      return {RawPeer::header(sabo::v1::MESSAGE_TYPE_STEP_STATE),
              m.mutate_bytes(boulder_state(0, 0, 1e-3).SerializeAsString())};
    default: {
      sabo::v1::Goodbye goodbye;
      goodbye.set_reason("fuzz");
      goodbye.set_steps(3);
      return {RawPeer::header(m.chance(0.5) ? sabo::v1::MESSAGE_TYPE_GOODBYE : sabo::v1::MESSAGE_TYPE_ERROR),
              m.mutate_bytes(goodbye.SerializeAsString())};
    }
  }
}

// `count` fuzzed frames from 8 peers that never register (one in ten from a peer that sends one frame and
// leaves) while the scene's dem_solver runs: the run must complete.
inline FrameOutcome fuzz_unregistered_frames(std::size_t count, std::uint64_t seed, const std::filesystem::path& dir) {
  FrameOutcome out;
  std::filesystem::create_directories(dir);
  CouplerRun run(one_boulder_scene(dir), dir);
  zmq::context_t context(1);
  RawPeer dem(context, run.endpoint());
  dem.send(sabo::v1::MESSAGE_TYPE_REGISTER, boulder_registration().SerializeAsString());
  const auto [type, body] = dem.receive(std::chrono::milliseconds(10000));
  sabo::v1::RegisterReply reply;
  if (type != sabo::v1::MESSAGE_TYPE_REGISTER_REPLY || !reply.ParseFromString(body) || !reply.accepted()) {
    out.failures.push_back("the dem_solver could not register: " + reply.error());
    return out;
  }
  std::atomic<bool> fuzzing{true};
  auto solver = std::async(std::launch::async, [&] {
    double time = 0;
    for (std::uint64_t step = 0;; ++step) {
      // A small step while the fuzzing goes on, then one that reaches end_time.
      dem.send(sabo::v1::MESSAGE_TYPE_STEP_STATE, boulder_state(step, time, fuzzing ? 1e-7 : 1.0).SerializeAsString());
      const auto [t, b] = dem.receive(std::chrono::milliseconds(20000));
      sabo::v1::StepForces forces;
      if (t != sabo::v1::MESSAGE_TYPE_STEP_FORCES || !forces.ParseFromString(b) || forces.step() != step) {
        return std::make_pair(step, "step " + std::to_string(step) + ": the dem_solver got message type " +
                                        std::to_string(t) + " instead of its forces");
      }
      if (forces.stop()) {
        sabo::v1::Goodbye goodbye;
        goodbye.set_steps(step + 1);
        goodbye.set_reason("completed");
        dem.send(sabo::v1::MESSAGE_TYPE_GOODBYE, goodbye.SerializeAsString());
        return std::make_pair(step + 1, std::string());
      }
      time += forces.dt();
    }
  });
  {
    std::vector<std::unique_ptr<RawPeer>> peers;
    for (int k = 0; k < 8; ++k) peers.push_back(std::make_unique<RawPeer>(context, run.endpoint()));
    for (std::size_t k = 0; k < count; ++k) {
      Mutator m(seed + k);
      const auto frames = fuzzed_frames(m);
      if (m.chance(0.1)) {
        RawPeer once(context, run.endpoint());
        once.send_frames(frames);
        ++out.hit_and_run;
      } else {
        peers[m.below(peers.size())]->send_frames(frames);
      }
      ++out.frames;
      if (k % 64 == 63) {
        for (auto& peer : peers) out.answered += peer->drain();
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    for (auto& peer : peers) out.answered += peer->drain();
  }
  fuzzing = false;
  const auto [steps, problem] = solver.get();
  out.steps = steps;
  if (!problem.empty()) out.failures.push_back(problem);
  out.exit_code = run.wait(std::chrono::seconds(30));
  if (out.exit_code != coupler::kCompleted) {
    out.failures.push_back("the coupler ended with " + std::to_string(out.exit_code) + " (expected 0: completed)");
  }
  return out;
}

struct StateOutcome {
  std::size_t runs = 0, completed = 0, refused = 0;
  std::vector<std::string> failures;
};

// `count` runs in each of which the registered dem_solver sends one mutated state (at step 0, 1 or 2): the
// run completes (a valid mutant), or ends with exit code 3 and an error event naming the dem_solver.
inline StateOutcome fuzz_registered_states(std::size_t count, std::uint64_t seed, const std::filesystem::path& dir) {
  StateOutcome out;
  for (std::size_t k = 0; k < count; ++k) {
    Mutator m(seed + k);
    const auto run_dir = dir / ("run" + std::to_string(k));
    std::filesystem::create_directories(run_dir);
    const std::string label = "seed " + std::to_string(seed + k);
    {
      CouplerRun run(one_boulder_scene(run_dir), run_dir);
      zmq::context_t context(1);
      RawPeer dem(context, run.endpoint());
      dem.send(sabo::v1::MESSAGE_TYPE_REGISTER, boulder_registration().SerializeAsString());
      if (dem.receive(std::chrono::milliseconds(10000)).first != sabo::v1::MESSAGE_TYPE_REGISTER_REPLY) {
        out.failures.push_back(label + ": no registration reply");
        continue;
      }
      const std::uint64_t mutated_step = m.below(3);
      double time = 0;
      bool stopped = false;
      for (std::uint64_t step = 0; step < 200 && !stopped; ++step) {
        std::string body = boulder_state(step, time, 2e-3).SerializeAsString();
        if (step == mutated_step) body = m.mutate_bytes(body);
        dem.send(sabo::v1::MESSAGE_TYPE_STEP_STATE, body);
        const auto [t, b] = dem.receive(std::chrono::milliseconds(20000));
        sabo::v1::StepForces forces;
        if (t == sabo::v1::MESSAGE_TYPE_STEP_FORCES && forces.ParseFromString(b)) {
          if (forces.stop()) {
            sabo::v1::Goodbye goodbye;
            goodbye.set_reason("completed");
            dem.send(sabo::v1::MESSAGE_TYPE_GOODBYE, goodbye.SerializeAsString());
            stopped = true;
          }
          time += forces.dt();
        } else {
          stopped = true;  // Stop, or an Error: the run is over
          sabo::v1::Goodbye goodbye;
          goodbye.set_reason("stopped");
          dem.send(sabo::v1::MESSAGE_TYPE_GOODBYE, goodbye.SerializeAsString());
        }
      }
      const int code = run.wait(std::chrono::seconds(30));
      ++out.runs;
      if (code == coupler::kCompleted) {
        ++out.completed;
      } else if (code == coupler::kSolverFailed) {
        ++out.refused;
        bool named = false;
        for (const auto& event : run.events()) {
          if (event.value("event", "") == "error" && event.value("process", "") == "dem_solver") named = true;
        }
        if (!named) out.failures.push_back(label + ": exit code 3 without an error event naming the dem_solver");
      } else {
        out.failures.push_back(label + ": the coupler ended with " + std::to_string(code) +
                               " (expected 0, or 3 naming the dem_solver)");
      }
    }
    std::filesystem::remove_all(run_dir);
  }
  return out;
}

}  // namespace sabo::testing::fuzz
