// Boulders in water through the SPH-DEM pairs, fluid and spheres coupled in
// one process (tests/support/sph_dem_harness.hpp): momentum and energy of
// boulders falling into a tank, Archimedes for a floating and a sinking
// sphere (its convergence with the resolution). Measured beside expected.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "tests/support/sph_dem_archimedes.hpp"
#include "tests/support/sph_dem_harness.hpp"

using namespace sabo;

namespace {

constexpr double kDx = 0.01;  // m

TEST(SphDemPhysics, BouldersFallingIntoWaterConserveMomentumAndNeverGainEnergy) {
  const double width = 0.15, depth = 0.05;
  std::vector<scene::Sphere> spheres;
  for (auto [x, y, z] : {std::tuple{0.05, 0.06, 0.08}, std::tuple{0.1, 0.09, 0.095}, std::tuple{0.075, 0.04, 0.11}}) {
    spheres.push_back({Vec3(x, y, z), 0.015, Vec3(0.2, -0.1, 0), Vec3(0, 5, 0)});
  }
  for (auto model : {scene::SphDemContact::Model::boundary_particles, scene::SphDemContact::Model::penalty}) {
    const bool boundary = model == scene::SphDemContact::Model::boundary_particles;
    SCOPED_TRACE(boundary ? "boundary_particles" : "penalty");
    sabo::testing::SphDemHarness run(
        sabo::testing::water_tank_scene(kDx, width, depth, 15.0, 0.0, spheres, 2650, model),
        sabo::testing::water_tank_walls(kDx, width, 0.13));
    sabo::testing::add_dem_tank_walls(run.dem(), width);
    bool touched_floor = false;
    while (run.time() < 0.12) {
      run.step();
      touched_floor = touched_floor || run.dem().wall_contact_count() > 0;
    }
    const Vec3 change = run.momentum() - run.initial_momentum();
    const Vec3 impulse = run.external_impulse();
    const double residual = (change - impulse).norm() / run.gravity_impulse().norm();
    std::cout << (boundary ? "boundary particles" : "penalty") << ": " << run.steps() << " steps to t = " << run.time()
              << " s; momentum change " << change.transpose() << " N s, impulse of gravity and walls "
              << impulse.transpose() << " N s: residual " << residual << " of the gravity impulse (held to 1e-6); "
              << "energy " << run.initial_energy() << " J at the start, at most "
              << run.max_energy() - run.initial_energy() << " J above it, " << run.energy() << " J at the end\n";
    EXPECT_FALSE(touched_floor) << "the spheres' walls would add an impulse the balance does not count";
    EXPECT_LT(residual, 1e-6);
    // The coupled system never gains energy: the measured rise, 5e-8 of the energy in the first steps, is the
    // leapfrog's, whose energy is invariant only at a constant step (the step follows the fluid's stable step).
    EXPECT_LE(run.max_energy() - run.initial_energy(), 1e-6 * run.initial_energy());
    // The boulders entered the water and were slowed by it.
    for (std::size_t j = 0; j < run.dem().size(); ++j) EXPECT_LT(run.dem().positions()[j].z(), depth);
  }
}

// Archimedes (tests/support/sph_dem_archimedes.hpp): a sphere of 500 kg/m^3 floats half submerged, one of
// 2650 kg/m^3 rests on the floor, which carries its weight less the buoyancy. Water 0.1 m deep in a tank 0.2 m
// (floating) or 0.16 m (resting) wide, a sphere 0.1 m across, viscosity 2 Pa s so that the heave decays within the
// run; the sphere starts where it will rest. bench_sph_dem_archimedes runs the finer resolutions and the penalty
// law (--model penalty; docs/physics.md, "SPH-DEM"). The tests step at cfl 0.5, half the steps of the bench's
// 0.25 (the step is the acoustic one, cfl h / c), with the tank's walls 1.5 water depths high instead of 2 (the
// water never reaches them): their figures are the bench's to 3e-4 (below).
void print(const char* law, double density, const sabo::testing::ArchimedesResult& r) {
  if (r.floats) {
    std::cout << law << ", " << density << " kg/m^3, D = " << 2 * r.radius / r.dx << " dx: centre " << r.centre_height
              << " m, free surface " << r.surface << " m, submerged fraction " << r.submerged_fraction << " (expected "
              << r.expected_fraction << ")\n";
  } else {
    std::cout << law << ", " << density << " kg/m^3, D = " << 2 * r.radius / r.dx << " dx: centre " << r.centre_height
              << " m, speed " << r.speed << " m/s, floor reaction " << r.floor_reaction
              << " N, expected weight - buoyancy " << r.expected_reaction << " N (" << 100 * r.error() << " %)\n";
  }
}

sabo::testing::ArchimedesResult archimedes(scene::SphDemContact::Model model, double density, double spacings) {
  sabo::testing::ArchimedesCase c;
  c.model = model;
  c.density = density;
  c.diameter_spacings = spacings;
  c.cfl = 0.5;
  c.wall_height_depths = 1.5;
  const auto r = sabo::testing::run_archimedes(c);
  print(model == scene::SphDemContact::Model::boundary_particles ? "boundary particles" : "penalty", density, r);
  return r;
}

// Floating, P1 (docs/benchmarks.md) asks 0.50 +- 0.05 from 10 spacings per diameter on: measured 0.450 at 10 dx (at
// the edge), 0.457 at 14, 0.467 at 20, 0.473 at 28 (bench_sph_dem_archimedes --density 500; this test's cfl 0.5:
// 0.4570 at 14 dx, 0.4503 at 10). The fluid stands about 0.6 dx off the convex surface, so the sphere acts
// 0.17-0.25 dx larger; the error shrinks as about dx^0.6. The sphere's rise at the start sets the tank sloshing
// (period about 0.5 s) and the fraction, measured from the surface at the tank's corners, swings with it: at 10 dx
// 0.405 at 0.22 s, 0.453 at 0.47 s, 0.438 at 0.70 s, 0.446 at 1 s; the run's end, 0.5 s, falls near a crest. A
// shorter run, a narrower tank (1.6 D, 10 dx: 0.444) or a larger viscosity (5 Pa s: 0.435; 30 Pa s in the 1.6 D
// tank: 0.468, the sphere still rising) each move it by more than the 0.007 left above 0.45 at 14 dx, so the test
// keeps the bench's case: 936 steps of 10 108 fluid particles.
TEST(SphDemPhysics, ArchimedesFloatingBoulder) {
  const auto r = archimedes(scene::SphDemContact::Model::boundary_particles, 500, 14);
  EXPECT_NEAR(r.submerged_fraction, 0.5, 0.05);
}

// Resting on the floor the fluid cannot follow the sphere into the gap of less than about dx around its contact
// with the floor, and that cap loses its pressure: the floor carries +21 % at D = 10 dx, and the cap's area, about
// 2 pi R dx, shrinks with dx. The error converges at first order to the weight less the buoyancy (measured: +21.2 %
// at 10 dx, +15.4 % at 14, order 0.94 between them, extrapolated limit +1.0 %; bench_sph_dem_archimedes: +10.1 % at
// 20 dx, +4.2 % at 40).
TEST(SphDemPhysics, ArchimedesBoulderRestingOnTheFloorConvergesAtFirstOrder) {
  const auto coarse = archimedes(scene::SphDemContact::Model::boundary_particles, 2650, 10);
  const auto fine = archimedes(scene::SphDemContact::Model::boundary_particles, 2650, 14);
  for (const auto* r : {&coarse, &fine}) EXPECT_NEAR(r->centre_height, r->radius, 0.05 * r->radius);
  const auto conv = sabo::testing::convergence(coarse.dx, coarse.error(), fine.dx, fine.error());
  std::cout << "floor reaction error " << 100 * coarse.error() << " % at 10 dx, " << 100 * fine.error()
            << " % at 14 dx: order " << conv.order << " (expected 1 +- 0.4), first-order limit " << 100 * conv.limit
            << " % (expected 0 +- 5 %)\n";
  EXPECT_GT(coarse.error(), fine.error());
  EXPECT_NEAR(conv.order, 1.0, 0.4);
  EXPECT_NEAR(conv.limit, 0.0, 0.05);
}

}  // namespace
