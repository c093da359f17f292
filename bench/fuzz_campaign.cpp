// bench_fuzz_campaign: the long fuzz campaign of issue 18 (the ctest tests/fuzz runs a few thousand of each
// kind). Mutated scenes and meshes, fuzzed frames from peers that never register during a run, mutated
// states from the registered solver, and a flood of idle connections; per kind the inputs, what was
// accepted and refused, the failures (expected none), the time, and this process's resident memory and
// open file descriptors before and after (the coupler runs in this process). Last line: JSON.
//
//   build/bin/bench_fuzz_campaign [--scenes N] [--meshes N] [--frames N] [--states N] [--idle N] [--seed S]
#include <dirent.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/support/fuzz_coupler.hpp"
#include "tests/support/fuzz_targets.hpp"

namespace {

using namespace sabo::testing::fuzz;
using Clock = std::chrono::steady_clock;

double rss_mb() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0;
}

int open_fds() {
  int count = 0;
  if (DIR* dir = ::opendir("/proc/self/fd")) {
    while (const dirent* entry = ::readdir(dir)) count += entry->d_name[0] != '.' ? 1 : 0;
    ::closedir(dir);
    --count;  // the one opendir holds
  }
  return count;
}

struct Probe {
  double rss_before = rss_mb();
  int fds_before = open_fds();
  Clock::time_point start = Clock::now();
  nlohmann::json finish(nlohmann::json row) const {
    row["seconds"] = std::chrono::duration<double>(Clock::now() - start).count();
    row["rss_mb_before"] = rss_before;
    row["rss_mb_after"] = rss_mb();
    row["fds_before"] = fds_before;
    row["fds_after"] = open_fds();
    return row;
  }
};

void print(const nlohmann::json& row) {
  std::cout << row["kind"].get<std::string>() << ": " << row["inputs"] << " inputs, " << row.value("accepted", 0)
            << " accepted, " << row.value("refused", 0) << " refused, " << row["failures"] << " failures, "
            << row["seconds"].get<double>() << " s; RSS " << row["rss_mb_before"].get<double>() << " -> "
            << row["rss_mb_after"].get<double>() << " MB, open fds " << row["fds_before"] << " -> " << row["fds_after"]
            << std::endl;
}

std::filesystem::path work(const std::string& name) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("sabo-fuzz-campaign-" + std::to_string(::getpid()) + "-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

nlohmann::json outcome_row(const char* kind, const Outcome& out, const Probe& probe) {
  nlohmann::json row{{"kind", kind},
                     {"inputs", out.inputs},
                     {"accepted", out.accepted},
                     {"refused", out.refused},
                     {"failures", out.failures.size()},
                     {"slowest_seconds", out.slowest},
                     {"slowest_input", out.slowest_input}};
  for (std::size_t k = 0; k < out.failures.size() && k < 5; ++k) std::cout << "  " << out.failures[k] << "\n";
  return probe.finish(row);
}

// `count` idle connections (ZeroMQ peers that never send), then the solver registers and runs: it must get
// through, and the connections must all be closed again afterwards.
nlohmann::json idle_flood(std::size_t count, const std::filesystem::path& dir) {
  const Probe probe;
  nlohmann::json row{{"kind", "idle connections"}, {"inputs", count}};
  std::size_t failures = 0;
  std::uint64_t steps = 0;
  {
    CouplerRun run(one_boulder_scene(dir), dir);
    zmq::context_t context(1);
    context.set(zmq::ctxopt::max_sockets, static_cast<int>(count + 64));
    std::vector<std::unique_ptr<zmq::socket_t>> idle;
    for (std::size_t k = 0; k < count; ++k) {
      idle.push_back(std::make_unique<zmq::socket_t>(context, zmq::socket_type::dealer));
      idle.back()->set(zmq::sockopt::linger, 0);
      idle.back()->connect(run.endpoint());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    RawPeer dem(context, run.endpoint());
    dem.send(sabo::v1::MESSAGE_TYPE_REGISTER, boulder_registration().SerializeAsString());
    if (dem.receive(std::chrono::milliseconds(15000)).first != sabo::v1::MESSAGE_TYPE_REGISTER_REPLY) {
      ++failures;
      std::cout << "  the solver could not register\n";
    } else {
      double time = 0;
      for (std::uint64_t step = 0;; ++step) {
        dem.send(sabo::v1::MESSAGE_TYPE_STEP_STATE, boulder_state(step, time, 2e-3).SerializeAsString());
        const auto [type, body] = dem.receive(std::chrono::milliseconds(15000));
        sabo::v1::StepForces forces;
        if (type != sabo::v1::MESSAGE_TYPE_STEP_FORCES || !forces.ParseFromString(body)) {
          ++failures;
          break;
        }
        if (forces.stop()) {
          steps = step + 1;
          sabo::v1::Goodbye goodbye;
          goodbye.set_reason("completed");
          dem.send(sabo::v1::MESSAGE_TYPE_GOODBYE, goodbye.SerializeAsString());
          break;
        }
        time += forces.dt();
      }
    }
    const int code = run.wait(std::chrono::seconds(60));
    if (code != 0) ++failures;
    std::ifstream summary_file(dir / "summary.json");
    if (summary_file) row["coupler_connections"] = nlohmann::json::parse(summary_file)["connections"];
    row["exit_code"] = code;
  }
  row["steps"] = steps;
  row["failures"] = failures;
  return probe.finish(row);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The long fuzz campaign of issue 18 (bench/RESULTS.md, 'Fuzz campaign')."};
  std::size_t scenes = 40000, meshes = 40000, frames = 40000, states = 1000, idle = 1500;
  std::uint64_t seed = 1000;
  app.add_option("--scenes", scenes, "mutated scenes")->capture_default_str();
  app.add_option("--meshes", meshes, "mutated meshes")->capture_default_str();
  app.add_option("--frames", frames, "fuzzed frames from unregistered peers, during one run")->capture_default_str();
  app.add_option("--states", states, "runs with one mutated state from the registered solver")->capture_default_str();
  app.add_option("--idle", idle, "idle connections before the solver registers")->capture_default_str();
  app.add_option("--seed", seed, "first seed (each input: seed + its number)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  nlohmann::json rows = nlohmann::json::array();
  const nlohmann::json start{{"rss_mb", rss_mb()}, {"fds", open_fds()}};
  std::size_t failures = 0;
  auto add = [&](nlohmann::json row) {
    print(row);
    failures += row["failures"].get<std::size_t>();
    rows.push_back(std::move(row));
  };
  {
    const auto dir = work("scenes");
    const Probe probe;
    add(outcome_row("scenes", fuzz_scenes(scenes, seed, dir), probe));
    std::filesystem::remove_all(dir);
  }
  {
    const auto dir = work("meshes");
    const Probe probe;
    add(outcome_row("meshes", fuzz_meshes(meshes, seed, dir), probe));
    std::filesystem::remove_all(dir);
  }
  {
    const auto dir = work("frames");
    const Probe probe;
    const FrameOutcome out = fuzz_unregistered_frames(frames, seed, dir);
    for (const auto& failure : out.failures) std::cout << "  " << failure << "\n";
    add(probe.finish({{"kind", "frames from unregistered peers"},
                      {"inputs", out.frames},
                      {"answered", out.answered},
                      {"hit_and_run", out.hit_and_run},
                      {"run_steps", out.steps},
                      {"exit_code", out.exit_code},
                      {"failures", out.failures.size()}}));
    std::filesystem::remove_all(dir);
  }
  {
    const auto dir = work("states");
    const Probe probe;
    const StateOutcome out = fuzz_registered_states(states, seed, dir);
    for (std::size_t k = 0; k < out.failures.size() && k < 5; ++k) std::cout << "  " << out.failures[k] << "\n";
    add(probe.finish({{"kind", "mutated states from the registered solver"},
                      {"inputs", out.runs},
                      {"accepted", out.completed},
                      {"refused", out.refused},
                      {"failures", out.failures.size()}}));
    std::filesystem::remove_all(dir);
  }
  {
    const auto dir = work("idle");
    add(idle_flood(idle, dir));
    std::filesystem::remove_all(dir);
  }
  const nlohmann::json result{
      {"start", start}, {"end", {{"rss_mb", rss_mb()}, {"fds", open_fds()}}}, {"kinds", rows}, {"failures", failures}};
  std::cout << result.dump() << std::endl;
  return failures == 0 ? 0 : 1;
}
