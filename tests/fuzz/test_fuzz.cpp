// Issue 18, item 6: seeded fuzzing of every input Sabo reads from outside, a few thousand of each kind
// (the longer campaign: bench/fuzz_campaign.cpp, figures in bench/RESULTS.md). Each failure prints its seed
// and mutation; SABO_FUZZ_SEED changes the seeds (default 1).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "tests/support/fuzz_coupler.hpp"
#include "tests/support/fuzz_targets.hpp"

namespace {

using namespace sabo::testing::fuzz;

std::uint64_t base_seed() {
  const char* text = std::getenv("SABO_FUZZ_SEED");
  return text != nullptr ? std::strtoull(text, nullptr, 10) : 1;
}

std::filesystem::path work(const char* name) {
  const auto dir = std::filesystem::temp_directory_path() / ("sabo-fuzz-" + std::to_string(::getpid()) + "-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

void report(const char* kind, const Outcome& out) {
  std::cout << kind << ": " << out.inputs << " mutants, " << out.accepted << " accepted, " << out.refused
            << " refused with a typed error, " << out.failures.size() << " failures (expected 0); " << out.seconds
            << " s in all, slowest " << out.slowest << " s (" << out.slowest_input << ")\n";
  for (std::size_t k = 0; k < out.failures.size() && k < 10; ++k) std::cout << "  " << out.failures[k] << "\n";
}

// 3000 mutants of the scenes of configs/: each is loaded, or refused with a SceneError (every line with its
// fix) or a FileError; never another exception (std::bad_alloc, std::length_error), never a crash.
TEST(Fuzz, ScenesAreLoadedOrRefusedWithTheirFix) {
  const auto dir = work("scenes");
  const Outcome out = fuzz_scenes(3000, base_seed(), dir);
  report("scenes", out);
  EXPECT_TRUE(out.failures.empty());
  EXPECT_GT(out.refused, out.inputs / 10);  // the mutations do reach the checks
  EXPECT_LT(out.slowest, 2.0);
  std::filesystem::remove_all(dir);
}

// 3000 mutants of STL (ASCII and binary) and Gmsh meshes: each is read, or refused with a FileError that
// says how to fix it.
TEST(Fuzz, MeshesAreReadOrRefusedWithAFileError) {
  const auto dir = work("meshes");
  const Outcome out = fuzz_meshes(3000, base_seed(), dir);
  report("meshes", out);
  EXPECT_TRUE(out.failures.empty());
  EXPECT_GT(out.refused, out.inputs / 10);
  EXPECT_LT(out.slowest, 2.0);
  std::filesystem::remove_all(dir);
}

// 3000 fuzzed frames from peers that never register (some leaving at once) while the dem_solver runs: the
// run completes, the solver never sees anything but its forces.
TEST(Fuzz, FramesFromPeersThatDidNotRegisterDoNotDisturbTheRun) {
  const auto dir = work("frames");
  const FrameOutcome out = fuzz_unregistered_frames(3000, base_seed(), dir);
  std::cout << "frames: " << out.frames << " sent (" << out.hit_and_run << " by peers that left at once), "
            << out.answered << " answered; the run: " << out.steps << " steps, exit code " << out.exit_code
            << " (expected 0)\n";
  for (const auto& failure : out.failures) std::cout << "  " << failure << "\n";
  EXPECT_TRUE(out.failures.empty());
  EXPECT_EQ(out.exit_code, 0);
  EXPECT_GT(out.answered, 0u);
  std::filesystem::remove_all(dir);
}

// 100 runs whose registered dem_solver sends one mutated state: each completes or ends naming the solver.
TEST(Fuzz, AMutatedStateFromTheSolverEndsTheRunNamingItOrIsValid) {
  const auto dir = work("states");
  const StateOutcome out = fuzz_registered_states(100, base_seed(), dir);
  std::cout << "states: " << out.runs << " runs, " << out.completed << " completed (a valid mutant), " << out.refused
            << " ended naming the dem_solver, " << out.failures.size() << " failures (expected 0)\n";
  for (const auto& failure : out.failures) std::cout << "  " << failure << "\n";
  EXPECT_TRUE(out.failures.empty());
  EXPECT_EQ(out.runs, 100u);
  EXPECT_GT(out.refused, 0u);
  std::filesystem::remove_all(dir);
}

}  // namespace
