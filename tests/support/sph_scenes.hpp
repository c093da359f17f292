#pragma once
// Scenes, wall particles and run helpers for the SPH tests and benchmarks, built in memory
// (no coupler).
#include <cmath>
#include <string>
#include <type_traits>

#include "libsabo/physics/boundary_particles.hpp"
#include "libsabo/scene/scene.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph::testing {

// A scene with one water-like material "water" (Tait, rest density 1000) and no bodies.
scene::Scene water_scene(double dx, double sound_speed, double smoothing_ratio = 1.3);

scene::FluidBody box_body(const std::string& name, const Vec3& min, const Vec3& max);

// Wall particles on a lattice of spacing dx filling `layers` layers outside the
// faces of the container [min, max] (bottom and the four sides; the top is open
// up to max.z, or closed by a lid above max.z). Lattice points sit at min + (k + 1/2) dx
// like the fluid's.
physics::BoundaryParticles container_walls(const Vec3& min, const Vec3& max, double dx, int layers, bool lid = false);

// Steps the model with its own stable dt until `end_time`; on_step(t) after each step (a
// bool result of false stops the run). Returns the steps taken.
template <class OnStep>
int run_until(SphModel& model, double end_time, OnStep&& on_step) {
  double t = 0, dt_previous = 0;
  int steps = 0;
  while (t < end_time) {
    model.compute_internal_forces(dt_previous);
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    t += dt;
    dt_previous = dt;
    ++steps;
    if constexpr (std::is_same_v<std::invoke_result_t<OnStep, double>, bool>) {
      if (!on_step(t)) break;
    } else {
      on_step(t);
    }
  }
  return steps;
}

// Pressure error of water (rho 1000) at rest H deep against rho g (H - z), as an L2 norm over
// the particles, relative to rho g H.
double hydrostatic_pressure_error(const SphModel& model, double H, double g);

// The fluid's momentum change less gravity (N, the wall force on the fluid: the fluid pairs
// cancel) and the sum of the forces on the wall particles (N) in the last compute; opposite
// when action equals reaction; and the fluid's mass, kg.
struct WallForceBalance {
  Vec3 on_fluid = Vec3::Zero(), on_walls = Vec3::Zero();
  double mass = 0;
};
WallForceBalance wall_force_balance(const SphModel& model, const Vec3& gravity);

}  // namespace sabo::sph::testing
