// summary.json's coupling overhead (docs/architecture.md, "Contact pairs"): the pairs' seconds count only for
// what they lengthened an exchange, from each solver's compute and wait as its state reports them.
#include <gtest/gtest.h>

#include <iostream>
#include <vector>

#include "coupler/accounting.hpp"

using sabo::coupler::pairs_on_critical_path;
using sabo::coupler::SolverCycle;

namespace {

void expect_on_path(const char* what, const std::vector<SolverCycle>& cycles, double pairs, double expected) {
  const double measured = pairs_on_critical_path(cycles, pairs);
  std::cout << what << ": pairs " << pairs << " ms, on the critical path " << measured << " ms (expected " << expected
            << ")\n";
  EXPECT_NEAR(measured, expected, 1e-12) << what;
}

}  // namespace

// The slurry waits for its wall particles (boundary particles): it computes 6 ms after its forces come, the
// boulders 0.5 ms; the coupler's 3 ms of pairs and 1 ms of messages all lie on the path.
TEST(CouplingOverhead, PairsTheSlurryWaitsForAreAllOnThePath) {
  expect_on_path("slurry waiting", {{.compute = 6, .waited = 4}, {.compute = 0.5, .waited = 9.5}}, 3, 3);
}

// Penalty contacts: the slurry computes its own 6 ms of forces while the coupler's 3 ms of pairs run, and
// waits for nothing; the pairs lengthen nothing.
TEST(CouplingOverhead, PairsBesideTheSlurrysComputingAreOffThePath) {
  expect_on_path("slurry computing beside", {{.compute = 8, .waited = 0}, {.compute = 0.5, .waited = 7.5}}, 3, 0);
}

// The slurry computes 2 ms ahead of its forces; 3 ms of pairs and 0.5 ms of messages: it waits 1.5 ms, of which
// the pairs are 1.5 ms (without them it would not wait).
TEST(CouplingOverhead, PairsLongerThanTheSlurrysHeadStartCountForTheRest) {
  expect_on_path("slurry partly ahead", {{.compute = 6, .waited = 1.5}, {.compute = 0.5, .waited = 7}}, 3, 1.5);
}

// Another solver is the slowest at this exchange (it wrote its output: 9.5 ms computed, 0.5 ms waited): without
// the pairs the exchange would still take its 9.5 ms, so only the last 0.5 ms are the pairs'.
TEST(CouplingOverhead, ASlowerSolverHidesThePairsBehindItsOwnComputing) {
  expect_on_path("another solver slower", {{.compute = 6, .waited = 4}, {.compute = 9.5, .waited = 0.5}}, 3, 0.5);
}

// No pairs, or no solvers: nothing on the path.
TEST(CouplingOverhead, NothingToCount) {
  expect_on_path("no pairs", {{.compute = 6, .waited = 4}}, 0, 0);
  expect_on_path("no solvers", {}, 3, 0);
}
