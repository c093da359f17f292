#pragma once
// Material and checks shared by the FEM tests.
#include <algorithm>
#include <utility>
#include <vector>

#include "fem_solver/body_common.hpp"
#include "fem_solver/materials/plastic_kinematic.hpp"

namespace sabo::fem::test {

// Elastic structural steel.
inline MaterialParameters steel() {
  MaterialParameters m;
  m.density = 7850;
  m.youngs_modulus = 210e9;
  m.poisson_ratio = 0.3;
  return m;
}

// The hourglass criterion (hourglass energy below 10% of the internal energy)
// over a whole run: observe() every step; worst() is the largest ratio over
// the steps whose internal energy is at least `floor_fraction` of the run's
// largest (near zero internal energy, e.g. as a vibration passes its rest
// position, the ratio of two vanishing numbers says nothing).
class HourglassMonitor {
 public:
  explicit HourglassMonitor(double floor_fraction = 0.1) : floor_fraction_(floor_fraction) {}
  void observe(const SolidEnergies& e) { samples_.emplace_back(e.internal, e.hourglass); }
  [[nodiscard]] double worst() const {
    double peak = 0;
    for (const auto& [internal, hourglass] : samples_) peak = std::max(peak, internal);
    double worst = 0;
    for (const auto& [internal, hourglass] : samples_) {
      if (internal > floor_fraction_ * peak && internal > 0) worst = std::max(worst, hourglass / internal);
    }
    return worst;
  }

 private:
  double floor_fraction_;
  std::vector<std::pair<double, double>> samples_;  // (internal, hourglass), J
};

}  // namespace sabo::fem::test
