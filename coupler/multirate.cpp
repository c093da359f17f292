#include "coupler/multirate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <optional>

namespace sabo::coupler {

std::uint32_t substeps_within(double interval, double step, std::uint32_t cap) {
  assert(cap >= 1);
  if (!(interval > step)) return 1;  // within it already, or an infinite step (no limit)
  // The ratio's ceiling, then the smallest m whose division, the solver's step, is within (the ratio and
  // interval / m each round).
  const double ratio = std::ceil(interval / step);
  auto m = std::max<std::uint32_t>(static_cast<std::uint32_t>(std::min(ratio, static_cast<double>(cap))), 1);
  while (m > 1 && interval / (m - 1) <= step) --m;
  while (m < cap && interval / m > step) ++m;
  return m;
}

std::string StepLimit::text() const {
  switch (kind) {
    case Kind::solver: return fmt::format("solver {}", index);
    case Kind::pair: return fmt::format("pair {}", index);
    case Kind::max_dt: return "max_dt";
    case Kind::next_output: return "next output";
    case Kind::nothing: break;
  }
  return "nothing";
}

RatePlan plan_rates(std::span<const SolverRate> solvers, std::span<const PairRate> pairs, const RateLimits& limits,
                    bool multirate) {
  using Kind = StepLimit::Kind;
  RatePlan plan;
  plan.substeps.assign(solvers.size(), 1);
  plan.intervals.assign(solvers.size(), 1);
  double dt = std::numeric_limits<double>::infinity();
  StepLimit limit;
  const auto take = [&](double candidate, StepLimit why) {
    if (candidate < dt) dt = candidate, limit = why;
  };
  for (std::size_t i = 0; i < solvers.size(); ++i) take(solvers[i].stable_step, {Kind::solver, i});
  for (std::size_t j = 0; j < pairs.size(); ++j) take(pairs[j].stable_dt, {Kind::pair, j});
  if (limits.max_dt) take(*limits.max_dt, {Kind::max_dt, 0});
  if (!std::isfinite(dt)) dt = limits.fallback_dt;
  plan.lock_step_dt = dt;
  if (!multirate) {
    plan.exchange_dt = dt;
    plan.limit = limit;
    return plan;
  }

  // Register.max_substeps: 0 is one step.
  const auto cap = [&](std::size_t i) { return std::max<std::uint32_t>(solvers[i].max_substeps, 1); };
  // Each solver's interval and what sets it.
  const std::size_t n = solvers.size();
  std::vector<double> interval(n);
  std::vector<StepLimit> why(n);
  std::vector<bool> every_exchange(n, false);
  for (std::size_t i = 0; i < n; ++i) interval[i] = solvers[i].stable_step * cap(i), why[i] = {Kind::solver, i};
  for (std::size_t j = 0; j < pairs.size(); ++j) {
    const PairRate& pair = pairs[j];
    const double a = solvers[pair.a].stable_step, b = solvers[pair.b].stable_step;
    const double rate = std::min(pair.stable_dt, pair.held ? std::max(a, b) : std::min(a, b));
    for (const std::size_t side : {pair.a, pair.b}) {
      if (rate < interval[side]) interval[side] = rate, why[side] = {Kind::pair, j};
      if (pair.every_exchange) every_exchange[side] = true;
    }
  }
  // Never shorter than lock-step's step (rounding), and no longer than the way to the next output time
  // when that is longer than lock-step's step: output lands on its time as often as lock-step's does.
  const double until = std::max(limits.until_next_output, plan.lock_step_dt);
  for (std::size_t i = 0; i < n; ++i) {
    if (limits.max_dt && *limits.max_dt < interval[i]) interval[i] = *limits.max_dt, why[i] = {Kind::max_dt, 0};
    if (interval[i] < plan.lock_step_dt) interval[i] = plan.lock_step_dt;
    if (interval[i] > plan.lock_step_dt && until < interval[i]) interval[i] = until, why[i] = {Kind::next_output, 0};
  }
  dt = std::numeric_limits<double>::infinity();
  limit = {};
  for (std::size_t i = 0; i < n; ++i) take(interval[i], why[i]);  // each already within max_dt
  if (!std::isfinite(dt)) {
    // Nothing limits anything (rigid parts only): the fallback, within the next output as above.
    dt = std::max(plan.lock_step_dt, std::min(limits.fallback_dt, until));
    limit = {};
  }
  const double finest = dt;
  plan.exchange_dt = finest;
  plan.limit = limit;

  // Hold exchanges: the slowest solver that may hold, and its interval (an unlimited one spans the most).
  std::optional<std::size_t> slowest;
  const auto may_hold = [&](std::size_t i) { return solvers[i].holds && !every_exchange[i]; };
  for (std::size_t i = 0; i < n; ++i) {
    if (!may_hold(i) || !std::isfinite(interval[i])) continue;
    if (!slowest || interval[i] > interval[*slowest]) slowest = i;
  }
  if (slowest && interval[*slowest] > finest) {
    const auto grid = [&](double tick, std::uint32_t most) {
      std::vector<std::uint32_t> k(n, 1);
      for (std::size_t i = 0; i < n; ++i) {
        if (!may_hold(i)) continue;
        while (k[i] < most && 2.0 * k[i] * tick <= interval[i]) k[i] *= 2;
      }
      return k;
    };
    // The finest interval as the tick.
    const std::vector<std::uint32_t> from_finest = grid(finest, kMaxHeldExchanges);
    // The slowest interval halved until within the finest.
    const double slow = interval[*slowest];
    std::uint32_t halvings = 1;
    while (halvings < kMaxHeldExchanges && slow / halvings > finest) halvings *= 2;
    const double tick = slow / halvings;
    const double gain = slow / (from_finest[*slowest] * finest);  // the slowest's fewer steps
    const double cost = finest / tick;                            // the others' more exchanges
    if (tick <= finest && gain > cost) {
      plan.exchange_dt = tick;
      plan.intervals = grid(tick, halvings);
      plan.limit = why[*slowest];
    } else {
      plan.intervals = from_finest;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    plan.substeps[i] = substeps_within(plan.intervals[i] * plan.exchange_dt, solvers[i].stable_step, cap(i));
  }
  return plan;
}

}  // namespace sabo::coupler
