#pragma once
// Node and energy bookkeeping shared by SolidBody and ShellBody.
#include <cstdint>
#include <span>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::fem {

struct SolidEnergies {
  double kinetic = 0;        // J, with v_n = (v_{n-1/2} + v_{n+1/2}) / 2 after integrate()
  double internal = 0;       // J, stress work of the active elements (elastic + plastic)
  double plastic_work = 0;   // J, of every element, eroded included
  double hourglass = 0;      // J, active elements
  double eroded = 0;         // J, internal + hourglass energy of eroded elements when they failed
  double external_work = 0;  // J, of gravity and the contact forces
  double potential = 0;      // J, -sum m g . x
  // Kinetic + internal + hourglass + eroded - external work - initial kinetic: zero for a perfect balance.
  [[nodiscard]] double total() const { return kinetic + internal + hourglass + eroded - external_work; }
};

// Calls fix(i) for every node inside `box`; returns how many nodes.
template <typename Fix>
std::size_t fix_nodes_in_box(std::span<const Vec3> positions, const Aabb& box, Fix fix) {
  std::size_t count = 0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (box.contains(positions[i])) {
      fix(i);
      ++count;
    }
  }
  return count;
}

[[nodiscard]] inline double sum_masses(std::span<const double> masses) {
  double sum = 0;
  for (double m : masses) sum += m;
  return sum;
}

// Element energies (plastic work of every element, internal and hourglass of
// the active ones) and the gravity potential; the caller fills kinetic,
// eroded and external work.
template <typename ElementState>
[[nodiscard]] SolidEnergies element_energies(const std::vector<ElementState>& states,
                                             std::span<const std::uint8_t> active, std::span<const double> masses,
                                             std::span<const Vec3> positions, const Vec3& gravity) {
  SolidEnergies e;
  for (std::size_t k = 0; k < states.size(); ++k) {
    e.plastic_work += states[k].plastic_work;
    if (active[k] == 0) continue;
    e.internal += states[k].internal_energy;
    e.hourglass += states[k].hourglass_energy;
  }
  for (std::size_t i = 0; i < positions.size(); ++i) e.potential -= masses[i] * gravity.dot(positions[i]);
  return e;
}

}  // namespace sabo::fem
