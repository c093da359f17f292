#pragma once
// Inflows of the sph_solver (docs/physics.md, "Inflows"; the scene's [[inflows]]): fluid that enters through
// a cross-section at the rate of a hydrograph.
//
// Each inflow owns a pool of particles from the start, lattice layers of InflowLattice::per_layer()
// particles in the order they will enter. Behind the section, a buffer of InflowLattice::buffer_layers
// layers moves along the section's direction at U(t) = Q(t) / A (A = InflowLattice::area): its particles'
// velocities and densities are prescribed (the hydrostatic density of their row, or the rest density),
// their positions follow the buffer's advance X(t) = integral of U, so that layer l sits at
// s_l = X - (l + 1/2) dx along the direction from the section. Every other force acts on them as on any
// particle, and they on the fluid: the buffer is a piston of fluid. After each step
//   * a layer whose s_l >= 0 is released: its particles are free fluid from then on;
//   * the next layer of the pool enters the buffer once s_l >= -buffer_layers dx;
//   * when the hydrograph has ended (t past its last point, where Q is 0 for good) the buffer's
//     particles are taken out.
// The released volume is then (released layers) A dx = X A to within one layer, and X A is the integral
// of Q (the midpoint rule, exact where Q is linear over a step).
//
// Energy: the buffer's particles count in the fluid's energies. What the prescription does to them is
// the inflow's account (Energies::inflow): their energy on entering, the work of the force that keeps
// their velocity, F = m (v_{n+1/2} - v_{n-1/2}) / dt_avg - (m a_n + F_external), over
// (v_{n-1/2} + v_{n+1/2}) dt_avg / 2 as the energy audit counts outside work, and m (e(rho_set) - e(rho))
// of each density reset, less the energy of a buffer taken out. Their pair forces with the fluid are
// internal: the fluid's energy audit (energy_audit.hpp) then closes with the account added.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::sph {

// SphModel::active() per particle.
enum ParticleState : std::uint8_t {
  kOut = 0,       // not in the simulation: left the domain, waits in an inflow's pool, or its buffer ended
  kFree = 1,      // fluid
  kBuffer = 2,    // in an inflow's buffer: velocity and density prescribed
  kEntering = 3,  // entered an inflow's buffer after the last step: kBuffer from the next integrate()
};

struct InflowState {
  std::string name;         // the body's
  std::uint32_t body = 0;   // its index in Scene::fluids
  std::uint32_t first = 0;  // id of its first particle; its pool is [first, first + lattice.particles())
  scene::InflowSection section;
  scene::InflowLattice lattice;
  double spacing = 0;               // m, dx
  std::vector<double> row_density;  // kg/m^3, per row up the section: the buffer's prescribed density
  double advance = 0;               // m, X: how far the buffer has moved since t = 0
  double speed = 0;                 // m/s, U of the last step (v_{n+1/2} of the buffer)
  double previous_speed = 0;        // m/s, U of the step before (v_{n-1/2})
  std::size_t entered = 0;          // layers that entered the buffer
  std::size_t released = 0;         // layers released into the flow
  bool ended = false;               // the hydrograph ended and the buffer was taken out

  // The particle id of particle k (k = row * lattice.across + column) of layer `layer`.
  [[nodiscard]] std::uint32_t id(std::size_t layer, std::size_t k) const {
    return first + static_cast<std::uint32_t>(layer * lattice.per_layer() + k);
  }
  // Where particle k of layer `layer` is when the buffer has advanced `x` (m).
  [[nodiscard]] Vec3 position(std::size_t layer, std::size_t k, double x) const {
    const double column = static_cast<double>(k % lattice.across) + 0.5 - 0.5 * static_cast<double>(lattice.across);
    const double row = static_cast<double>(k / lattice.across) + 0.5;
    const double along = x - (static_cast<double>(layer) + 0.5) * spacing;
    return section.position + spacing * column * section.across() + spacing * row * section.up() +
           along * section.direction;
  }
  // The fluid volume released through the section so far, m^3 (each particle's lattice cell, dx^3).
  [[nodiscard]] double released_volume() const {
    return static_cast<double>(released * lattice.per_layer()) * spacing * spacing * spacing;
  }
};

}  // namespace sabo::sph
