#include "tests/support/fuzz_coupler.hpp"

namespace sabo::testing::fuzz {

scene::Scene one_boulder_scene(const std::filesystem::path& dir) {
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

sabo::v1::Register boulder_registration() {
  return sabo::testing::boulder_registration("fuzz dem");
}

std::vector<std::string> fuzzed_frames(Mutator& m) {
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

FrameOutcome fuzz_unregistered_frames(std::size_t count, std::uint64_t seed, const std::filesystem::path& dir) {
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

StateOutcome fuzz_registered_states(std::size_t count, std::uint64_t seed, const std::filesystem::path& dir) {
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
