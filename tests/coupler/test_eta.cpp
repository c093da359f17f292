// The progress line's time to go (issue 17, item 6): a run whose steps get slower halfway is estimated from
// its recent rate, not from its average since the start.
#include <gtest/gtest.h>

#include <iostream>

#include "coupler/eta.hpp"

using sabo::coupler::EtaEstimate;

namespace {

// A run of 10 simulated seconds whose rate drops from 0.1 to 0.025 s per wall second at t = 5 s (a step
// limit that tightened): it needs 50 + 200 = 250 wall seconds. Samples every 0.5 s of wall time.
struct Sample {
  double wall, time;
};
Sample at(double wall) {
  return wall <= 50 ? Sample{wall, 0.1 * wall} : Sample{wall, 5.0 + 0.025 * (wall - 50)};
}

}  // namespace

TEST(EtaEstimate, FollowsTheRecentRateWhenTheStepsSlowDown) {
  EtaEstimate eta;
  EXPECT_LT(eta.seconds_to(10), 0);  // no rate yet
  for (double wall = 0; wall <= 120; wall += 0.5) eta.observe(at(wall).wall, at(wall).time);
  const double truth = 250 - 120;
  const double average = 120 * (10 - at(120).time) / at(120).time;  // the estimate from the start
  std::cout << "at 120 s of 250: to go " << eta.seconds_to(10) << " s (truth " << truth << " s; from the average since "
            << "the start " << average << " s)\n";
  EXPECT_NEAR(eta.seconds_to(10), truth, 0.05 * truth);
  EXPECT_LT(average, 0.6 * truth);  // what the progress line said before
}

TEST(EtaEstimate, SteadyRunIsEstimatedExactlyAndTheEndIsZero) {
  EtaEstimate eta;
  for (double wall = 0; wall <= 30; wall += 0.5) eta.observe(wall, 0.2 * wall);
  EXPECT_NEAR(eta.seconds_to(10), 20.0, 1e-9);
  EXPECT_NEAR(eta.rate(), 0.2, 1e-12);
  eta.observe(60, 12);
  EXPECT_EQ(eta.seconds_to(10), 0.0);
}
