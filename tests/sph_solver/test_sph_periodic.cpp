// Periodic boundaries of SphModel (sph.periodic_x / periodic_y, docs/physics.md "Periodic
// boundaries") and the benchmarks that need them: S5 start-up Poiseuille flow and the S8
// arrest on an infinite slope (Bingham and the paper's elastic-plastic slurry).
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <numbers>
#include <vector>

#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::water_scene;

// Steps the model with its own stable dt until `end_time`; on_step(t) after each step.
void run_until(SphModel& model, double end_time, const std::function<void(double)>& on_step) {
  double t = 0, dt_previous = 0;
  while (t < end_time) {
    model.compute_internal_forces(dt_previous);
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    t += dt;
    dt_previous = dt;
    on_step(t);
  }
}

// `layers` layers of wall particles on the lattice of spacing dx over [0, length) x [0, width),
// below z = 0 (normal +z) and, when ceiling > 0, above z = ceiling (normal -z).
physics::BoundaryParticles periodic_plates(double length, double width, double dx, int layers, double ceiling = 0) {
  physics::BoundaryParticles walls;
  const auto nx = static_cast<int>(std::lround(length / dx)), ny = static_cast<int>(std::lround(width / dx));
  const auto add = [&](double z, const Vec3& normal) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        walls.position.emplace_back((i + 0.5) * dx, (j + 0.5) * dx, z);
        walls.velocity.push_back(Vec3::Zero());
        walls.normal.push_back(normal);
        walls.acceleration.push_back(Vec3::Zero());
        walls.volume.push_back(dx * dx * dx);
      }
    }
  };
  for (int k = 0; k < layers; ++k) {
    add(-(k + 0.5) * dx, Vec3(0, 0, 1));
    if (ceiling > 0) add(ceiling + (k + 0.5) * dx, Vec3(0, 0, -1));
  }
  return walls;
}

// A water layer [0, 8 dx)^2 x [0, 6 dx] on a floor, periodic along x and y, hydrostatic.
scene::Scene periodic_layer_scene(double dx) {
  scene::Scene s = water_scene(dx, 20.0, 1.5);
  const double side = 8 * dx;
  s.fluids.push_back(box_body("layer", Vec3(0, 0, 0), Vec3(side, side, 6 * dx)));
  s.sph.periodic_x = std::array<double, 2>{0.0, side};
  s.sph.periodic_y = std::array<double, 2>{0.0, side};
  return s;
}

// The lattice of a periodic layer has no ends: every column is the same, so every particle
// of a row (same z) gets the same acceleration, whichever side of a seam it is on. Moving the
// whole lattice and floor by a fraction of a spacing (so that the seams cut it elsewhere)
// must not change any particle's acceleration either. Float positions: the pair terms of a
// particle differ by rounding only (held to 1e-4 g).
TEST(SphPeriodic, ShiftedLatticeSeesTheSameNeighboursAcrossTheSeam) {
  const double dx = 0.02, g = 9.81, side = 8 * dx;
  const scene::Scene s = periodic_layer_scene(dx);
  SphModel model(s), shifted(s);
  model.set_boundary(periodic_plates(side, side, dx, 3));
  const Vec3 shift(0.37 * dx, 0.61 * dx, 0);
  physics::BoundaryParticles floor = periodic_plates(side, side, dx, 3);
  for (Vec3& p : floor.position) {
    p += shift;
    for (int a = 0; a < 2; ++a) p[a] -= p[a] >= side ? side : 0.0;
  }
  shifted.set_boundary(floor);
  for (Vec3& p : shifted.positions()) p += shift;  // wrapped by the next compute
  model.compute_internal_forces(0);
  shifted.compute_internal_forces(0);
  EXPECT_GT(model.fluid_image_count(), 0u);
  EXPECT_GT(model.wall_image_count(), 0u);
  double row_spread = 0, shift_change = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    for (std::size_t j = 0; j < model.size(); ++j) {
      if (std::abs(model.positions()[i].z() - model.positions()[j].z()) < 1e-9) {
        row_spread = std::max(row_spread, (model.accelerations()[i] - model.accelerations()[j]).norm());
      }
    }
    shift_change = std::max(shift_change, (model.accelerations()[i] - shifted.accelerations()[i]).norm());
  }
  std::cout << "periodic layer, " << model.size() << " particles, " << model.fluid_image_count() << " fluid images, "
            << model.wall_image_count() << " wall images; largest difference of "
            << "acceleration within a row: measured " << row_spread / g << " g, after shifting the lattice by (0.37, "
            << "0.61) dx: " << shift_change / g << " g (expected 0, held to 1e-4 g)\n";
  EXPECT_LT(row_spread, 1e-4 * g);
  EXPECT_LT(shift_change, 1e-4 * g);
  // The wall force: the floor carries the layer's weight, and the fluid's momentum change
  // less gravity is minus the wall force (the fluid pairs across a seam cancel to float rounding).
  Vec3 fluid = Vec3::Zero(), wall = Vec3::Zero();
  double weight = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    fluid += model.masses()[i] * (model.accelerations()[i] - s.run.gravity);
    weight += model.masses()[i] * g;
  }
  for (const Vec3& f : model.boundary_forces()) wall += f;
  std::cout << "floor force " << wall.transpose() << " N, weight " << weight
            << " N (expected -weight along z within 2 %); fluid + wall " << (fluid + wall).norm()
            << " N (expected 0, held to 1e-5 weight)\n";
  EXPECT_NEAR(-wall.z(), weight, 0.02 * weight);
  EXPECT_LT((fluid + wall).norm(), 1e-5 * weight);
}

// A slab without gravity or walls translating diagonally through a box periodic in x and y:
// its particles cross the seams (several times) and nothing changes: the count, the
// densities and velocities (no pair has a relative velocity or pressure difference), and the
// unwrapped displacement is u t.
TEST(SphPeriodic, TranslatingSlabCrossesTheSeamsUnchanged) {
  const double dx = 0.02, side = 8 * dx;
  scene::Scene s = periodic_layer_scene(dx);
  s.run.gravity = Vec3::Zero();
  s.fluids[0].velocity = Vec3(0.8, 0.5, 0);
  SphModel model(s);
  const std::vector<Vec3> start(model.positions().begin(), model.positions().end());
  double t_end = 0;
  run_until(model, 0.3, [&](double t) { t_end = t; });
  double density_change = 0, velocity_change = 0, displacement_error = 0, outside = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    density_change = std::max(density_change, std::abs(model.densities()[i] / 1000.0 - 1.0));
    velocity_change = std::max(velocity_change, (model.velocities()[i] - s.fluids[0].velocity).norm());
    const Vec3 unwrapped = model.positions()[i] - model.wrap_offsets()[i];
    displacement_error = std::max(displacement_error, (unwrapped - start[i] - t_end * s.fluids[0].velocity).norm());
    for (int a = 0; a < 2; ++a) {
      outside = std::max({outside, -model.positions()[i][a], model.positions()[i][a] - side});
    }
  }
  std::cout << "slab at (0.8, 0.5) m/s for " << t_end << " s (" << t_end * 0.8 / side << " periods along x): active "
            << model.size() - model.lost_count() << " of " << model.size() << "; largest |rho/rho0 - 1| "
            << density_change << ", |v - u| " << velocity_change << " m/s, |unwrapped displacement - u t| "
            << displacement_error << " m (expected 0, held to 1e-9); farthest outside the span " << outside
            << " m (expected <= 0)\n";
  EXPECT_EQ(model.lost_count(), 0u);
  EXPECT_LT(density_change, 1e-9);
  EXPECT_LT(velocity_change, 1e-9);
  EXPECT_LT(displacement_error, 1e-9);
  EXPECT_LE(outside, 0.0);
}

// Elastic-plastic layer on a floor under tilted gravity, periodic in x and y (the S8
// scene): it flows across the seams with stresses, gradients and wall images. Same bits on
// 1 and 2 threads; the momentum balance with the floor holds across the seams.
TEST(SphPeriodic, RunsAreDeterministicOnOneAndTwoThreads) {
  const double dx = 0.015, side = 10 * dx, g = 9.81, theta = 0.35;
  scene::Scene s = water_scene(dx, 10.0, 1.5);
  s.run.gravity = Vec3(g * std::sin(theta), 0.3, -g * std::cos(theta));
  scene::Material& m = s.materials[0];
  m.rheology = scene::Material::Rheology::elastic_plastic;
  m.yield_stress = 300;
  m.fluid_shear_modulus = 1e5;
  m.viscosity = 0.05;
  s.fluids.push_back(box_body("layer", Vec3(0, 0, 0), Vec3(side, side, 8 * dx)));
  s.sph.periodic_x = std::array<double, 2>{0.0, side};
  s.sph.periodic_y = std::array<double, 2>{0.0, side};
  const auto run = [&](int threads, SphModel& model) {
    omp_set_num_threads(threads);
    model.set_boundary(periodic_plates(side, side, dx, 3));
    run_until(model, 0.03, [](double) {});
    model.compute_internal_forces(0);
  };
  SphModel one(s), two(s);
  ASSERT_GT(one.size(), 512u);  // the parallel paths
  run(1, one);
  run(2, two);
  omp_set_num_threads(2);
  for (std::size_t i = 0; i < one.size(); ++i) {
    ASSERT_EQ(one.positions()[i], two.positions()[i]) << "particle " << i;
    ASSERT_EQ(one.velocities()[i], two.velocities()[i]) << "particle " << i;
    ASSERT_EQ(one.densities()[i], two.densities()[i]) << "particle " << i;
    for (int q = 0; q < 6; ++q) ASSERT_EQ(one.deviatoric_stress()[6 * i + q], two.deviatoric_stress()[6 * i + q]);
  }
  for (std::size_t b = 0; b < one.boundary().size(); ++b) ASSERT_EQ(one.boundary_forces()[b], two.boundary_forces()[b]);
  Vec3 fluid = Vec3::Zero(), wall = Vec3::Zero();
  double weight = 0;
  for (std::size_t i = 0; i < one.size(); ++i) {
    fluid += one.masses()[i] * (one.accelerations()[i] - s.run.gravity);
    weight += one.masses()[i] * g;
  }
  for (const Vec3& f : one.boundary_forces()) wall += f;
  std::cout << "flowing periodic layer: wall force on the fluid " << fluid.transpose() << " N, on the walls "
            << wall.transpose() << " N (expected opposite, held to 1e-5 of the weight " << weight << " N)\n";
  EXPECT_LT((fluid + wall).norm(), 1e-5 * weight);
}

}  // namespace
}  // namespace sabo::sph
