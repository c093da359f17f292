// The coupled step and each solver's steps in it (coupler/multirate.hpp, docs/architecture.md
// "Multirate"): lock-step is paper eq. 7; multirate exchanges each pair at its slower side's step,
// never above the pair's own limit, and every solver takes the fewest steps that keep its own step within
// its stable step.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <vector>

#include "coupler/multirate.hpp"

using sabo::coupler::PairRate;
using sabo::coupler::plan_rates;
using sabo::coupler::RateLimits;
using sabo::coupler::SolverRate;
using sabo::coupler::substeps_within;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
const RateLimits kNoLimits{.max_dt = std::nullopt, .fallback_dt = 0.01, .until_next_output = kInf};

// Steps in units of some base (exact binary numbers, so that the comparisons are exact).
// sph (slow, expensive), dem, fem (fast): the debris-flow scene's three solvers and its three pairs.
std::vector<SolverRate> three_solvers(double sph, double dem, double fem) {
  return {{.stable_step = sph, .max_substeps = 64},
          {.stable_step = dem, .max_substeps = 64},
          {.stable_step = fem, .max_substeps = 64}};
}
std::vector<PairRate> three_pairs() {
  return {
      {.a = 0, .b = 2, .stable_dt = kInf}, {.a = 1, .b = 2, .stable_dt = kInf}, {.a = 0, .b = 1, .stable_dt = kInf}};
}

}  // namespace

TEST(Multirate, LockStepIsTheSmallestStableStepOfAll) {
  const auto solvers = three_solvers(8.0, 3.0, 1.0);
  auto pairs = three_pairs();
  pairs[1].stable_dt = 2.0;
  const auto plan = plan_rates(solvers, pairs, kNoLimits, false);
  EXPECT_EQ(plan.exchange_dt, 1.0);
  EXPECT_EQ(plan.lock_step_dt, 1.0);
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 1}));
  EXPECT_EQ(plan.limit.text(), "solver 2");
  const auto capped =
      plan_rates(solvers, pairs, {.max_dt = 0.5, .fallback_dt = 0.01, .until_next_output = kInf}, false);
  EXPECT_EQ(capped.exchange_dt, 0.5);
  EXPECT_EQ(capped.limit.text(), "max_dt");
}

TEST(Multirate, TheStiffestStructureNoLongerSetsTheSlurrysStep) {
  // fem 8 times faster than the others: the exchange is the slower sides' step, the fem takes 8 steps.
  const auto plan = plan_rates(three_solvers(8.0, 9.0, 1.0), three_pairs(), kNoLimits, true);
  std::cout << "exchange " << plan.exchange_dt << " s (lock-step " << plan.lock_step_dt << " s), substeps sph "
            << plan.substeps[0] << " dem " << plan.substeps[1] << " fem " << plan.substeps[2] << "\n";
  EXPECT_EQ(plan.exchange_dt, 8.0);
  EXPECT_EQ(plan.lock_step_dt, 1.0);
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 8}));
  for (std::size_t i = 0; i < 3; ++i) {
    const double step = plan.exchange_dt / plan.substeps[i];
    EXPECT_LE(step, three_solvers(8.0, 9.0, 1.0)[i].stable_step) << "solver " << i;
    EXPECT_EQ(step * plan.substeps[i], plan.exchange_dt);
  }
  // Not a whole fraction of the exchange: the fem takes the ratio's ceiling, 6 steps of 4/3 where a power of two
  // would take 8 of 1.
  const auto odd = plan_rates(three_solvers(8.0, 9.0, 1.5), three_pairs(), kNoLimits, true);
  EXPECT_EQ(odd.substeps[2], 6u);
  EXPECT_LE(odd.exchange_dt / 6, 1.5);
  EXPECT_GT(odd.exchange_dt / 5, 1.5);
}

TEST(Multirate, TheWenjiaDamsTakeFiveStepsWhereFourAndAHalfWouldDo) {
  // The full-resolution Wenjia scene (bench/RESULTS.md, 6 December 2026): the boulders set a 1.133 ms exchange,
  // the dams' hexahedra allow 0.279 ms (0.251 ms with beta 0.9). A power of two took 8 steps.
  const std::vector<SolverRate> solvers{{.stable_step = 1.875e-3, .max_substeps = 1},
                                        {.stable_step = 1.133e-3, .max_substeps = 64},
                                        {.stable_step = 0.9 * 0.279e-3, .max_substeps = 64}};
  const auto plan = plan_rates(solvers, three_pairs(), kNoLimits, true);
  std::cout << "exchange " << plan.exchange_dt * 1e3 << " ms, fem steps " << plan.substeps[2] << " of "
            << plan.exchange_dt / plan.substeps[2] * 1e3 << " ms (its stable step " << solvers[2].stable_step * 1e3
            << " ms; a power of two: 8)\n";
  EXPECT_EQ(plan.exchange_dt, 1.133e-3);
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 5}));
}

TEST(Multirate, APairsOwnLimitHoldsTheExchangeBelowItsSlowerSide) {
  // A stiff penalty against a light particle: the pair is stable only at 2 although both its
  // sides step at 8 or more; the exchange keeps to the pair, the sides take power-of-two steps.
  auto pairs = three_pairs();
  pairs[2].stable_dt = 2.0;
  const auto plan = plan_rates(three_solvers(8.0, 9.0, 1.0), pairs, kNoLimits, true);
  EXPECT_EQ(plan.exchange_dt, 2.0);
  EXPECT_EQ(plan.limit.text(), "pair 2");
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 2}));
}

TEST(Multirate, APairWhoseForcesMayNotBeHeldIsExchangedAtItsFasterSidesStep) {
  // The sph-fem pair with boundary particles on a deformable structure (ContactPair::holding): the fem's step,
  // 1, sets the exchange although the slurry steps at 8; the others' rates do not matter.
  auto pairs = three_pairs();
  pairs[0].held = false;
  const auto plan = plan_rates(three_solvers(8.0, 9.0, 1.0), pairs, kNoLimits, true);
  EXPECT_EQ(plan.exchange_dt, 1.0);
  EXPECT_EQ(plan.limit.text(), "pair 0");
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 1}));
  // Lock-step is the same plan: the pair's own limit does not enter it.
  EXPECT_EQ(plan_rates(three_solvers(8.0, 9.0, 1.0), pairs, kNoLimits, false).exchange_dt, 1.0);
  // Held again: the slurry's step.
  pairs[0].held = true;
  EXPECT_EQ(plan_rates(three_solvers(8.0, 9.0, 1.0), pairs, kNoLimits, true).exchange_dt, 8.0);
}

TEST(Multirate, ASolverThatCannotSubcycleKeepsTheExchangeAtItsStep) {
  auto solvers = three_solvers(8.0, 9.0, 1.0);
  solvers[2].max_substeps = 1;  // registered max_substeps 0 or 1
  const auto plan = plan_rates(solvers, three_pairs(), kNoLimits, true);
  EXPECT_EQ(plan.exchange_dt, 1.0);
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 1}));
  // A cap of 6: the exchange at six of its steps.
  solvers[2].max_substeps = 6;
  const auto capped = plan_rates(solvers, three_pairs(), kNoLimits, true);
  EXPECT_EQ(capped.exchange_dt, 6.0);
  EXPECT_EQ(capped.substeps[2], 6u);
}

TEST(Multirate, NeverShorterThanLockStepAndStopsAtTheNextOutput) {
  const auto solvers = three_solvers(8.0, 9.0, 1.0);
  const auto near =
      plan_rates(solvers, three_pairs(), {.max_dt = std::nullopt, .fallback_dt = 0.01, .until_next_output = 3.0}, true);
  EXPECT_EQ(near.exchange_dt, 3.0);
  EXPECT_EQ(near.limit.text(), "next output");
  EXPECT_EQ(near.substeps[2], 3u);
  // The next output closer than lock-step's step: lock-step's step, as lock-step would take.
  const auto closer = plan_rates(solvers, three_pairs(),
                                 {.max_dt = std::nullopt, .fallback_dt = 0.01, .until_next_output = 0.01}, true);
  EXPECT_EQ(closer.exchange_dt, 1.0);
  EXPECT_EQ(closer.substeps, (std::vector<std::uint32_t>{1, 1, 1}));
  // Nothing limits anything (rigid parts only): the fallback, as lock-step.
  const std::vector<SolverRate> rigid{{.stable_step = kInf, .max_substeps = 64}};
  EXPECT_EQ(plan_rates(rigid, {}, kNoLimits, true).exchange_dt, 0.01);
  EXPECT_EQ(plan_rates(rigid, {}, kNoLimits, false).exchange_dt, 0.01);
}

TEST(Multirate, SubstepsWithin) {
  EXPECT_EQ(substeps_within(1.0, 1.0, 64), 1u);
  EXPECT_EQ(substeps_within(1.0, 0.5, 64), 2u);
  EXPECT_EQ(substeps_within(1.0, 0.49, 64), 3u);
  EXPECT_EQ(substeps_within(1.0, 0.2, 64), 5u);
  EXPECT_EQ(substeps_within(1.0, 0.2, 4), 4u);  // the cap, though its step is then above the stable one
  EXPECT_EQ(substeps_within(1.0, 1e-9, 64), 64u);
  EXPECT_EQ(substeps_within(1.0, 0.0, 64), 64u);
  EXPECT_EQ(substeps_within(1.0, kInf, 64), 1u);
  // The smallest m whose division is within, as the solver's step is computed: for every ratio up to the cap.
  for (std::uint32_t m = 1; m <= 64; ++m) {
    for (const double interval : {1.133e-3, 0.1, 7.0, 1.0 / 3.0}) {
      const double step = interval / m;
      const std::uint32_t got = substeps_within(interval, step, 64);
      EXPECT_LE(interval / got, step) << interval << " / " << m;
      if (got > 1) {
        EXPECT_GT(interval / (got - 1), step) << interval << " / " << m;
      }
      EXPECT_LE(got, m);
    }
  }
}

// Hold exchanges (docs/architecture.md, "Multirate"): a solver whose interval spans several exchanges steps at
// the first and holds at the others.
namespace {

std::vector<SolverRate> holding(std::vector<SolverRate> solvers) {
  for (auto& s : solvers) s.holds = true;
  return solvers;
}

// Every solver's interval is a whole number of exchanges within its limits, and the intervals nest.
void expect_consistent(const sabo::coupler::RatePlan& plan, const std::vector<SolverRate>& solvers) {
  const std::uint32_t block = *std::max_element(plan.intervals.begin(), plan.intervals.end());
  for (std::size_t i = 0; i < solvers.size(); ++i) {
    const std::uint32_t k = plan.intervals[i];
    EXPECT_EQ(k & (k - 1), 0u) << "solver " << i << ": a power of two";
    EXPECT_EQ(block % k, 0u) << "solver " << i;
    EXPECT_LE(k * plan.exchange_dt / plan.substeps[i], solvers[i].stable_step) << "solver " << i;
  }
}

}  // namespace

TEST(Multirate, HoldExchangesGiveTheSlurryItsOwnStepOnTheWenjiaScene) {
  // Full resolution (bench/RESULTS.md, 6 December 2026): the slurry 1.875 ms, the boulders 1.133 ms (their
  // step and their contact with the structures), the dams 0.251 ms; the sph-dem penalty pair allows 2.77 ms.
  const auto solvers = holding({{.stable_step = 1.875e-3, .max_substeps = 64},
                                {.stable_step = 1.133e-3, .max_substeps = 64},
                                {.stable_step = 0.251e-3, .max_substeps = 64}});
  auto pairs = three_pairs();
  pairs[2].stable_dt = 2.77e-3;
  pairs[1].stable_dt = 1.133e-3;
  const auto plan = plan_rates(solvers, pairs, kNoLimits, true);
  std::cout << "exchange " << plan.exchange_dt * 1e3 << " ms; sph every " << plan.intervals[0]
            << " exchanges (its step " << plan.intervals[0] * plan.exchange_dt * 1e3
            << " ms, expected 1.875), dem every " << plan.intervals[1] << ", fem " << plan.substeps[2]
            << " steps an exchange\n";
  // The slurry's interval halved once is within the boulders' 1.133 ms: it gains 1.875 / 1.133 = 1.65 times
  // fewer steps for 1.133 / 0.9375 = 1.21 times more exchanges of the others.
  EXPECT_EQ(plan.exchange_dt, 1.875e-3 / 2);
  EXPECT_EQ(plan.intervals, (std::vector<std::uint32_t>{2, 1, 1}));
  EXPECT_EQ(plan.substeps, (std::vector<std::uint32_t>{1, 1, 4}));
  EXPECT_EQ(plan.limit.text(), "pair 0");
  expect_consistent(plan, solvers);
  // Without hold exchanges (solvers that do not hold): every solver at the boulders' 1.133 ms, as before.
  auto lock = solvers;
  for (auto& s : lock) s.holds = false;
  const auto without = plan_rates(lock, pairs, kNoLimits, true);
  EXPECT_EQ(without.exchange_dt, 1.133e-3);
  EXPECT_EQ(without.intervals, (std::vector<std::uint32_t>{1, 1, 1}));
  EXPECT_EQ(without.substeps, (std::vector<std::uint32_t>{1, 1, 5}));
}

TEST(Multirate, HoldExchangesOnTheFinestGridWhereHalvingTheSlowestCostsMore) {
  // The slurry barely slower than the rest: halving it would double the others' exchanges for 6 % fewer
  // slurry steps. The finest interval stays the exchange; nobody holds.
  const auto close = plan_rates(holding(three_solvers(1.2, 1.133, 0.5)), three_pairs(), kNoLimits, true);
  EXPECT_EQ(close.exchange_dt, 1.133);
  EXPECT_EQ(close.intervals, (std::vector<std::uint32_t>{1, 1, 1}));
  // 4.5 times slower: four exchanges of the finest (a 4.5 / 4 gain against 1 / 0.5625 for halving it thrice).
  const auto solvers = holding(three_solvers(4.5, 1.0, 0.5));
  auto pairs = three_pairs();
  pairs[1].stable_dt = 1.0;
  const auto far = plan_rates(solvers, pairs, kNoLimits, true);
  EXPECT_EQ(far.exchange_dt, 1.0);
  EXPECT_EQ(far.intervals, (std::vector<std::uint32_t>{4, 1, 1}));
  EXPECT_EQ(far.substeps, (std::vector<std::uint32_t>{1, 1, 2}));
  expect_consistent(far, solvers);
}

TEST(Multirate, OnlyASolverThatHoldsAndNoBoundaryParticlePairHolds) {
  auto solvers = holding(three_solvers(8.0, 3.0, 1.0));
  auto pairs = three_pairs();
  pairs[1].stable_dt = 1.0;
  const auto plan = plan_rates(solvers, pairs, kNoLimits, true);
  EXPECT_EQ(plan.intervals[0], 8u);
  // The slurry registered holds = false: it exchanges at every step of the exchange it gets.
  solvers[0].holds = false;
  const auto no_hold = plan_rates(solvers, pairs, kNoLimits, true);
  EXPECT_EQ(no_hold.intervals[0], 1u);
  // A pair with boundary particles between the slurry and the boulders: both step at every exchange.
  solvers[0].holds = true;
  pairs[2].every_exchange = true;
  const auto walls = plan_rates(solvers, pairs, kNoLimits, true);
  EXPECT_EQ(walls.intervals[0], 1u);
  EXPECT_EQ(walls.intervals[1], 1u);
  // Lock-step never holds.
  EXPECT_EQ(plan_rates(holding(three_solvers(8.0, 3.0, 1.0)), three_pairs(), kNoLimits, false).intervals,
            (std::vector<std::uint32_t>{1, 1, 1}));
}

TEST(Multirate, ABlockOfHoldExchangesEndsAtTheNextOutput) {
  const auto solvers = holding(three_solvers(8.0, 3.0, 1.0));
  auto pairs = three_pairs();
  pairs[1].stable_dt = 1.0;
  const auto plan =
      plan_rates(solvers, pairs, {.max_dt = std::nullopt, .fallback_dt = 0.01, .until_next_output = 6.0}, true);
  const std::uint32_t block = *std::max_element(plan.intervals.begin(), plan.intervals.end());
  std::cout << "block of " << block << " exchanges of " << plan.exchange_dt << " s\n";
  EXPECT_LE(block * plan.exchange_dt, 6.0);
  // The slurry's 8 cut to the 6 left: halved three times (0.75) it gains 6 / 4 = 1.5 against 1 / 0.75 = 1.33.
  EXPECT_EQ(plan.exchange_dt, 0.75);
  EXPECT_EQ(plan.intervals[0], 8u);
  expect_consistent(plan, solvers);
}
