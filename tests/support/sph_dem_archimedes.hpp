#pragma once
// Archimedes through an SPH-DEM pair, fluid and sphere coupled in one process
// (sph_dem_harness.hpp): a sphere lighter than the water floats with the
// submerged volume fraction rho_s / rho_f; a heavier one rests on the floor,
// which carries its weight less the buoyancy. Water at rest in a closed square
// tank, the sphere started where it will rest (the fluid leaves its place
// free), a viscosity that damps the heave within the run. Used by
// bench/sph_dem_archimedes.cpp and tests/coupler/test_sph_dem_physics.cpp.
//
// The resolution is D / dx with the tank's size fixed in diameters, so that a
// run at several D / dx measures how the error converges. At rest the answer
// does not depend on the tank's width (hydrostatics), only on the water's depth.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "libsabo/physics/boundary_particles.hpp"
#include "libsabo/scene/scene.hpp"
#include "tests/support/sph_dem_harness.hpp"

namespace sabo::testing {

// Water (rho 1000, viscosity `viscosity` Pa s; 0: inviscid) `depth` deep in a square tank `width` wide at
// spacing `dx`, and the listed spheres of `density` (material "rock") through an SPH-DEM pair of `model`.
scene::Scene water_tank_scene(double dx, double width, double depth, double sound_speed, double viscosity,
                              const std::vector<scene::Sphere>& spheres, double density,
                              scene::SphDemContact::Model model);
// The tank's floor and sides as 3 layers of the fluid's wall particles, `height` high.
physics::BoundaryParticles water_tank_walls(double dx, double width, double height);
// The same floor and sides as plane walls of the spheres.
void add_dem_tank_walls(dem::DemModel& model, double width);

struct ArchimedesCase {
  scene::SphDemContact::Model model = scene::SphDemContact::Model::boundary_particles;
  double density = 2650;          // kg/m^3 (the water's is 1000)
  double diameter_spacings = 10;  // D / dx
  double radius = 0.05;           // m
  double depth_diameters = 1.0;   // water depth / D (before the sphere is put in)
  double width_diameters = 0;     // tank width / D; 0: 2.0 for a floating sphere, 1.6 for a resting one
  double sound_speed = 10;        // m/s
  double viscosity = 2;           // Pa s
  double end_time = 0;            // s; 0: 0.5 floating, 0.2 resting
  double cfl = 0;                 // the fluid's step factor (sph.cfl); 0: the scene's, 0.25
  double wall_height_depths = 2;  // the tank's walls' height / water depth (the water stays below 1.5)
};

struct ArchimedesResult {
  bool floats = false;
  double dx = 0, width = 0, depth = 0, radius = 0;
  std::size_t fluid_particles = 0;
  std::uint64_t steps = 0;
  double time = 0, wall_seconds = 0;
  double centre_height = 0, speed = 0;  // m: the sphere's mean over the last quarter of the run; m/s: at the end
  // Floating: the free surface far from the sphere and the walls, m, and the submerged volume fraction.
  double surface = 0, submerged_fraction = 0, expected_fraction = 0;
  // Resting: the floor's reaction (weight less the fluid's push, averaged over the last quarter of the run)
  // and the weight less the buoyancy, N.
  double floor_reaction = 0, expected_reaction = 0;
  [[nodiscard]] double error() const {
    return floats ? submerged_fraction / expected_fraction - 1.0 : floor_reaction / expected_reaction - 1.0;
  }
};

ArchimedesResult run_archimedes(const ArchimedesCase& c);

// The first-order fit e(dx) = a + b dx through two runs, for the convergence check: order p of the error
// between them (log of the ratio over log of the spacing ratio) and the limit a (the error at dx -> 0 if
// it is first order).
struct Convergence {
  double order = 0, limit = 0;
};
Convergence convergence(double coarse_dx, double coarse_error, double fine_dx, double fine_error);

}  // namespace sabo::testing
