#pragma once
// The progress line's time to go: from the recent rate of simulated time per
// wall second, smoothed, not from the average since the start. A run whose
// step cost grows (a slump whose viscous step limit tightens, a flow reaching
// a fine mesh) is then estimated from how fast it goes now.
namespace sabo::coupler {

class EtaEstimate {
 public:
  // tau: the smoothing time, s of wall time (a sample's weight halves every 0.69 tau).
  explicit EtaEstimate(double tau = 10.0) : tau_(tau) {}

  // A progress sample: wall seconds since the start and the simulated time reached, s.
  void observe(double wall, double time);
  // Wall seconds to reach end_time at the smoothed rate; negative while there is no rate yet.
  [[nodiscard]] double seconds_to(double end_time) const;
  // Simulated seconds per wall second, smoothed; 0 before two samples.
  [[nodiscard]] double rate() const { return rate_; }

 private:
  double tau_;
  double last_wall_ = 0, last_time_ = 0;
  double rate_ = 0;
  bool started_ = false, have_rate_ = false;
};

}  // namespace sabo::coupler
