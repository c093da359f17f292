// summary.json's coupling overhead (docs/architecture.md, "Contact pairs"): the pairs' seconds count only for
// what they lengthened an exchange, from each solver's compute and wait as its state reports them.
#include <gtest/gtest.h>

#include <iostream>
#include <optional>
#include <vector>

#include "coupler/accounting.hpp"

using sabo::coupler::pairs_on_critical_path;
using sabo::coupler::SolverCycle;

namespace {

SolverCycle cycle(double compute, double waited, std::optional<double> waited_for_forces = std::nullopt) {
  return {.compute = compute, .waited = waited, .waited_for_forces = waited_for_forces};
}

void expect_on_path(const char* what, const std::vector<SolverCycle>& cycles, double pairs, double expected,
                    double walls_ahead = 0) {
  const double measured = pairs_on_critical_path(cycles, {.all = pairs, .walls_ahead = walls_ahead});
  std::cout << what << ": pairs " << pairs << " ms (" << walls_ahead << " ms placing walls sent ahead), on the "
            << "critical path " << measured << " ms (expected " << expected << ")\n";
  EXPECT_NEAR(measured, expected, 1e-12) << what;
}

}  // namespace

// The slurry waits for its wall particles (boundary particles): it computes 6 ms after its forces come, the
// boulders 0.5 ms; the coupler's 3 ms of pairs and 1 ms of messages all lie on the path.
TEST(CouplingOverhead, PairsTheSlurryWaitsForAreAllOnThePath) {
  expect_on_path("slurry waiting", {cycle(6, 4), cycle(0.5, 9.5)}, 3, 3);
}

// Penalty contacts: the slurry computes its own 6 ms of forces while the coupler's 3 ms of pairs run, and
// waits for nothing; the pairs lengthen nothing.
TEST(CouplingOverhead, PairsBesideTheSlurrysComputingAreOffThePath) {
  expect_on_path("slurry computing beside", {cycle(8, 0), cycle(0.5, 7.5)}, 3, 0);
}

// The slurry computes 2 ms ahead of its forces; 3 ms of pairs and 0.5 ms of messages: it waits 1.5 ms, of which
// the pairs are 1.5 ms (without them it would not wait).
TEST(CouplingOverhead, PairsLongerThanTheSlurrysHeadStartCountForTheRest) {
  expect_on_path("slurry partly ahead", {cycle(6, 1.5), cycle(0.5, 7)}, 3, 1.5);
}

// Another solver is the slowest at this exchange (it wrote its output: 9.5 ms computed, 0.5 ms waited): without
// the pairs the exchange would still take its 9.5 ms, so only the last 0.5 ms are the pairs'.
TEST(CouplingOverhead, ASlowerSolverHidesThePairsBehindItsOwnComputing) {
  expect_on_path("another solver slower", {cycle(6, 4), cycle(9.5, 0.5)}, 3, 0.5);
}

// No pairs, or no solvers: nothing on the path.
TEST(CouplingOverhead, NothingToCount) {
  expect_on_path("no pairs", {cycle(6, 4)}, 0, 0);
  expect_on_path("no solvers", {}, 3, 0);
}

// Walls ahead: the slurry waited 1 ms for its walls, which the pairs placing them took 0.3 ms of (the rest is the
// states coming in and the walls going out), then computed while the other 2.7 ms of pairs ran, and its forces
// were there when it needed them: only the 0.3 ms lie on the path.
TEST(CouplingOverhead, WithWallsAheadOnlyThePairsPlacingThemLieOnThePath) {
  expect_on_path("walls ahead, forces in time", {cycle(6, 1, 0.0), cycle(0.5, 7)}, 3, 0.3, 0.3);
}

// Walls ahead, and the other pairs outlast the slurry's computing: it waited 0.8 ms for its walls and 1.2 ms for
// its forces after them; 0.3 ms of the first and the 1.2 ms of the second are the pairs'.
TEST(CouplingOverhead, WithWallsAheadTheOtherPairsCountForTheWaitAfterTheWalls) {
  expect_on_path("walls ahead, forces late", {cycle(6, 2, 1.2), cycle(0.5, 8)}, 3, 1.5, 0.3);
}
