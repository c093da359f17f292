#pragma once
// Node, energy and erosion bookkeeping shared by SolidBody and ShellBody.
#include <cstdint>
#include <limits>
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

// Erosion accounts of a body.
struct ErosionAccounts {
  double energy = 0;                    // J, internal + hourglass energy of eroded elements when they failed
  std::size_t count = 0;                // elements eroded so far
  std::uint64_t topology_revision = 0;  // incremented whenever elements erode (the exterior surface changed)
};

// Erodes the still active elements that `failed` flags (after the element
// loop): their energy goes to `accounts`, clear_slots(e) zeroes their nodal
// forces, their step no longer limits dt. Returns the number eroded now.
template <typename ElementState, typename ClearSlots>
std::size_t erode_failed_elements(std::span<const std::uint8_t> failed, const std::vector<ElementState>& states,
                                  std::vector<std::uint8_t>& active, std::vector<double>& element_dt,
                                  ErosionAccounts& accounts, ClearSlots clear_slots) {
  std::size_t newly_eroded = 0;
  for (std::size_t e = 0; e < states.size(); ++e) {
    if (failed[e] == 0 || active[e] == 0) continue;
    active[e] = 0;
    accounts.energy += states[e].internal_energy + states[e].hourglass_energy;
    clear_slots(e);
    element_dt[e] = std::numeric_limits<double>::infinity();
    ++newly_eroded;
  }
  if (newly_eroded > 0) {
    accounts.count += newly_eroded;
    ++accounts.topology_revision;
  }
  return newly_eroded;
}

// The step's per-node kinetic energies and external works, summed in node
// order (the same bits on any number of threads): kinetic replaced, work added.
inline void add_step_energies(std::span<const double> node_kinetic, std::span<const double> node_work, double& kinetic,
                              double& external_work) {
  kinetic = 0;
  for (std::size_t i = 0; i < node_kinetic.size(); ++i) {
    kinetic += node_kinetic[i];
    external_work += node_work[i];
  }
}

// The body's energies: element energies (plastic work of every element,
// internal and hourglass of the active ones), the gravity potential and the
// body's own accounts.
template <typename ElementState>
[[nodiscard]] SolidEnergies body_energies(const std::vector<ElementState>& states, std::span<const std::uint8_t> active,
                                          std::span<const double> masses, std::span<const Vec3> positions,
                                          const Vec3& gravity, double kinetic, double external_work,
                                          const ErosionAccounts& erosion) {
  SolidEnergies e;
  for (std::size_t k = 0; k < states.size(); ++k) {
    e.plastic_work += states[k].plastic_work;
    if (active[k] == 0) continue;
    e.internal += states[k].internal_energy;
    e.hourglass += states[k].hourglass_energy;
  }
  for (std::size_t i = 0; i < positions.size(); ++i) e.potential -= masses[i] * gravity.dot(positions[i]);
  e.kinetic = kinetic;
  e.eroded = erosion.energy;
  e.external_work = external_work;
  return e;
}

}  // namespace sabo::fem
