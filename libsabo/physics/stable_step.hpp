#pragma once
// The stable step of a penalty spring, paper eq. 7's DEM term: 0.2 pi sqrt(m / k), a tenth of the period of a
// mass m on a spring k. Its one home: the dem_solver, the coupler's contact pairs, the particle-surface contact
// and the scene check all bound their steps with it. (The Rayleigh bound of Hertz contacts is each caller's,
// with its own precomputed factors.)
#include <cmath>
#include <numbers>

namespace sabo::physics {

inline constexpr double kSpringStepFraction = 0.2 * std::numbers::pi;

// s, for a mass (kg) on a spring (N/m).
inline double spring_stable_dt(double mass, double stiffness) {
  return kSpringStepFraction * std::sqrt(mass / stiffness);
}

// N/m: the stiffness whose spring_stable_dt on `mass` is `dt`.
inline double stiffness_for_stable_dt(double mass, double dt) {
  return mass * std::pow(kSpringStepFraction / dt, 2);
}

}  // namespace sabo::physics
