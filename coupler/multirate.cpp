#include "coupler/multirate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

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
  dt = std::numeric_limits<double>::infinity();
  limit = {};
  for (std::size_t i = 0; i < solvers.size(); ++i) take(solvers[i].stable_step * cap(i), {Kind::solver, i});
  for (std::size_t j = 0; j < pairs.size(); ++j) {
    const PairRate& pair = pairs[j];
    const double a = solvers[pair.a].stable_step, b = solvers[pair.b].stable_step;
    take(std::min(pair.stable_dt, pair.held ? std::max(a, b) : std::min(a, b)), {Kind::pair, j});
  }
  if (limits.max_dt) take(*limits.max_dt, {Kind::max_dt, 0});
  if (!std::isfinite(dt)) dt = limits.fallback_dt;
  // Never shorter than lock-step's step (rounding), and no longer than the way to the next output time
  // when that is longer than lock-step's step: output lands on its time as often as lock-step's does.
  if (dt < plan.lock_step_dt) dt = plan.lock_step_dt;
  if (dt > plan.lock_step_dt && limits.until_next_output < dt) {
    const double until = std::max(limits.until_next_output, plan.lock_step_dt);
    if (until < dt) dt = until, limit = {Kind::next_output, 0};
  }
  plan.exchange_dt = dt;
  plan.limit = limit;
  for (std::size_t i = 0; i < solvers.size(); ++i) {
    plan.substeps[i] = substeps_within(dt, solvers[i].stable_step, cap(i));
  }
  return plan;
}

}  // namespace sabo::coupler
