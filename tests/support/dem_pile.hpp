#pragma once
// Test and benchmark support, not part of dem_solver: a dense pile of boulders settling in a
// closed box, the stability case of the DEM (a reduced one in the tests, the full 10 000 spheres
// for 10 s in bench/dem_pile.cpp). Boulders of the paper's size, diameters uniform in [1, 2] m, of
// granite with the moduli of intact rock (rho 2650, E 50 GPa, nu 0.25, typical laboratory values;
// the paper's boulders have rho 3000, E 30 GPa, nu 0.3), Hertz-Mindlin with restitution 0.3,
// friction 0.5, rolling friction 0.1; placed at 25 % solid fraction in a box `height_over_side` times as high as wide,
// and left to settle under gravity inside its six walls.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "dem_solver/dem_model.hpp"

namespace sabo::dem {

struct PileReport {
  std::int64_t steps = 0;
  double dt = 0;                   // s
  double initial_energy = 0;       // J
  double largest_energy_rise = 0;  // J, largest total energy above the initial one (<= 0: never above)
  std::size_t escaped = 0;  // over the checks every 100 steps: spheres whose half-radius core left the box (tunnelling)
  double final_largest_speed = 0;          // m/s
  double final_largest_overlap_ratio = 0;  // largest overlap over the smaller radius of its pair
  double final_mean_overlap_ratio = 0;
  std::size_t contacts = 0;
};

scene::Scene pile_scene(std::size_t count, double height_over_side, std::uint64_t seed);

// Settles the pile for `duration` s at beta * stable_dt.
PileReport settle_pile(const scene::Scene& scene, double duration, double beta);

}  // namespace sabo::dem
