#include "coupler/eta.hpp"

#include <algorithm>
#include <cmath>

namespace sabo::coupler {

void EtaEstimate::observe(double wall, double time) {
  if (!started_) {
    started_ = true;
    last_wall_ = wall;
    last_time_ = time;
    return;
  }
  const double elapsed = wall - last_wall_;
  if (!(elapsed > 0)) return;
  const double recent = (time - last_time_) / elapsed;
  // An exponential average over wall time: the weight of this interval is 1 - exp(-elapsed / tau). The
  // first interval starts it, so that a short run is not estimated from nothing.
  const double weight = have_rate_ ? 1.0 - std::exp(-elapsed / tau_) : 1.0;
  rate_ += weight * (recent - rate_);
  have_rate_ = true;
  last_wall_ = wall;
  last_time_ = time;
}

double EtaEstimate::seconds_to(double end_time) const {
  if (!have_rate_ || !(rate_ > 0)) return -1.0;
  return std::max(0.0, end_time - last_time_) / rate_;
}

}  // namespace sabo::coupler
