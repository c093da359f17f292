#pragma once
// The coupled step and each solver's steps within it (docs/architecture.md, "Multirate"): lock-step
// (paper eq. 7: every solver at the smallest stable step) or multirate (each solver at a whole fraction
// of its own interval, a power of two of exchanges, with the contact forces held in between).
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace sabo::coupler {

struct SolverRate {
  double stable_step = 0;          // s: beta * stable_dt; infinity: no limit (rigid parts only)
  std::uint32_t max_substeps = 1;  // Register.max_substeps: 0 is read as 1
  bool holds = false;              // Register.holds: it may step less often than it exchanges (hold exchanges)
};

struct PairRate {
  std::size_t a = 0, b = 0;     // indices of the two solvers it joins
  double stable_dt = 0;         // s: the pair's own limit (eq. 7 contact term); infinity: none
  bool held = true;             // false: its forces may not be held (ContactPair::holding): its faster side's step
  bool every_exchange = false;  // both sides step at every exchange (boundary particles: they go out every step)
};

// What set a plan's exchange step; text(): "solver 2", "pair 0", "max_dt", "next output", "nothing".
struct StepLimit {
  enum class Kind { nothing, solver, pair, max_dt, next_output };
  Kind kind = Kind::nothing;
  std::size_t index = 0;  // of the solver or the pair
  [[nodiscard]] std::string text() const;
};

// The largest number of exchanges one step interval of a solver spans (a power of two).
constexpr std::uint32_t kMaxHeldExchanges = 64;

struct RatePlan {
  double exchange_dt = 0;  // s: the interval between two exchanges, Delta_n (the tick)
  // Per solver: the exchanges its interval spans, k_i (a power of two; 1 in lock-step and for a solver that
  // does not hold). It steps at the first of them and holds at the k_i - 1 others.
  std::vector<std::uint32_t> intervals;
  // Per solver: steps of k_i exchange_dt / substeps in its interval.
  std::vector<std::uint32_t> substeps;
  double lock_step_dt = 0;  // s: what lock-step would take now (eq. 7)
  StepLimit limit;          // what set exchange_dt (nothing: the fallback, output_interval)
};

struct RateLimits {
  std::optional<double> max_dt;  // s: the scene's run.max_dt
  double fallback_dt = 0;        // s: the step when nothing limits it (the output interval)
  // s from now to the next output time (or the end): a multirate exchange step longer than lock-step's
  // stops there, so that output lands on its time. Infinity: no such cap.
  double until_next_output = 0;
};

// Lock-step: exchange_dt = min(stable steps, pair limits, max_dt), one step each. Multirate: each pair
// is exchanged at the step of the slower of its two sides (of the faster, for a pair whose forces may not be
// held) and never above its own limit, every solver at most max_substeps times its stable step: that gives
// each solver its interval I_i, the smallest over its pairs. Without hold exchanges (no solver holds, or all
// intervals alike) exchange_dt is the smallest interval and every solver exchanges each time. With them the
// plan is one of two grids of power-of-two intervals: the finest interval as the tick, each solver at the
// largest power of two of it within its interval; or the slowest solver's interval halved until it is within
// the finest. The second is taken when what it gains the slowest solver (as a ratio of its steps) exceeds
// what it costs the others (the tick's ratio). Each solver takes the fewest steps that keep its own step
// within its stable step.
[[nodiscard]] RatePlan plan_rates(std::span<const SolverRate> solvers, std::span<const PairRate> pairs,
                                  const RateLimits& limits, bool multirate);

// The smallest m >= 1 with interval / m <= step (as the solver computes its step), at most `cap` (>= 1).
[[nodiscard]] std::uint32_t substeps_within(double interval, double step, std::uint32_t cap);

}  // namespace sabo::coupler
