// DemModel's contact laws against the benchmarks (D1, D2, D4 of the validation cases):
// D1 Hertz impact (tests 1 and 2) through DemModel, D4 sliding to rolling and
// rolling resistance (constant and viscous), the pair kernel against the physics
// functions, walls, and the scene-driven size distributions, polygon regions
// and settling.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <iostream>
#include <numbers>

#include "dem_solver/dem_model.hpp"
#include "dem_test_scene.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/physics/hertz_mindlin.hpp"
#include "tests/support/dem_pile.hpp"
#include "tests/support/measure.hpp"

namespace sabo::dem {
namespace {

using testing::fill_set;
using testing::list_set;

void step(DemModel& model, double& dt_previous, double dt) {
  model.compute_internal_forces(dt_previous);
  model.integrate(dt_previous, dt);
  dt_previous = dt;
}

scene::Scene material_scene(double density, double youngs, double poisson) {
  scene::Scene scene;
  scene.file = "/tmp/dem-test/laws.toml";
  scene::Material material;
  material.name = "m";
  material.density = density;
  material.youngs_modulus = youngs;
  material.poisson_ratio = poisson;
  scene.materials.push_back(material);
  scene.run.gravity = Vec3::Zero();
  return scene;
}

// Hertz-Mindlin without damping, friction or rolling resistance: the D1 impacts.
scene::Scene undamped_hertz_scene(double density, double youngs, double poisson) {
  scene::Scene scene = material_scene(density, youngs, poisson);
  scene.dem_contact.model = scene::DemLaw::hertz_mindlin;
  scene.dem_contact.restitution = 1.0;
  scene.dem_contact.friction = 0;
  scene.dem_contact.rolling_friction = 0;
  return scene;
}

scene::ParticleSet spheres(std::vector<scene::Sphere> list) {
  scene::ParticleSet set = list_set("s", std::move(list));
  set.material = "m";
  return set;
}

scene::ParticleSet fill(std::string name, const Aabb& region, std::size_t count, double diameter_min,
                        double diameter_max, std::uint64_t seed) {
  scene::ParticleSet set = fill_set(std::move(name), region, count, diameter_min, diameter_max, seed);
  set.material = "m";
  return set;
}

struct Impact {
  double peak_force = 0, largest_overlap = 0, contact_time = 0, restitution = 0;
};

// Runs until the contact opens; overlap of sphere 0 with sphere 1, or with the wall z = 0 when there is
// one sphere. Contact start and end interpolated on the overlap's sign change.
Impact impact(DemModel& model, double dt, double approach_speed) {
  Impact result;
  auto overlap = [&] {
    const auto x = model.positions();
    const auto r = model.radii();
    return model.size() == 1 ? r[0] - x[0].z() : r[0] + r[1] - (x[0] - x[1]).norm();
  };
  double dt_previous = 0, t = 0, start = -1, end = -1, previous = overlap();
  while (end < 0 && t < 1.0) {
    model.compute_internal_forces(dt_previous);
    result.peak_force = std::max(result.peak_force, model.forces()[0].norm());
    model.integrate(dt_previous, dt);
    dt_previous = dt;
    t += dt;
    const double now = overlap();
    result.largest_overlap = std::max(result.largest_overlap, now);
    if (start < 0 && previous <= 0 && now > 0) start = t - dt * now / (now - previous);
    if (start >= 0 && previous > 0 && now <= 0) end = t - dt * now / (now - previous);
    previous = now;
  }
  result.contact_time = end - start;
  const auto v = model.velocities();
  const double separation_speed = model.size() == 1 ? v[0].z() : (v[1] - v[0]).x();
  result.restitution = separation_speed / approach_speed;
  return result;
}

using sabo::testing::expect_relative;

TEST(DemLawsD1, HertzImpactOfTwoGlassSpheres) {
  // Chung & Ooi 2011 test 1: E 48 GPa, nu 0.2, rho 2800, R 10 mm, 10 m/s each, no damping.
  scene::Scene scene = undamped_hertz_scene(2800, 48e9, 0.2);
  const double r = 0.01, gap = 1e-5;
  scene.particle_sets.push_back(spheres({scene::Sphere{Vec3(-r - gap, 0, 0), r, Vec3(10, 0, 0)},
                                         scene::Sphere{Vec3(r + gap, 0, 0), r, Vec3(-10, 0, 0)}}));
  DemModel model(scene);
  const Impact result = impact(model, 40.3e-6 / 4000, 20.0);
  expect_relative("D1 test 1 peak force (N)", result.peak_force, 10.70e3, 0.01);
  expect_relative("D1 test 1 largest overlap (m)", result.largest_overlap, 0.274e-3, 0.01);
  expect_relative("D1 test 1 contact time (s)", result.contact_time, 40.3e-6, 0.01);
  expect_relative("D1 test 1 restitution", result.restitution, 1.0, 0.01);
}

TEST(DemLawsD1, HertzImpactOfAnAluminiumSphereOnARigidWall) {
  // Chung & Ooi 2011 test 2: R 0.1 m, 0.2 m/s, E 70 GPa, nu 0.33, rho 2700, rigid wall.
  scene::Scene scene = undamped_hertz_scene(2700, 70e9, 0.33);
  scene.particle_sets.push_back(spheres({scene::Sphere{Vec3(0, 0, 0.1 + 1e-6), 0.1, Vec3(0, 0, -0.2)}}));
  DemModel model(scene);
  Wall wall;
  wall.youngs_modulus = std::numeric_limits<double>::infinity();
  model.add_wall(wall);
  const Impact result = impact(model, 0.726e-3 / 4000, 0.2);
  expect_relative("D1 test 2 peak force (N)", result.peak_force, 11.47e3, 0.01);
  expect_relative("D1 test 2 largest overlap (m)", result.largest_overlap, 49.3e-6, 0.01);
  expect_relative("D1 test 2 contact time (s)", result.contact_time, 0.726e-3, 0.01);
}

TEST(DemLawsWalls, AWallAddedDuringARunStopsASphereNearOrFarFromIt) {
  // Each sphere checks the walls listed near it at the last neighbour-list build. A sphere falls towards
  // z = 0, where the floor is added during the run (with a far wall beside it); undamped Hertz, so it must
  // come back at its speed. Far: from 0.5 m (40 skins) at 2 m/s, the floor added after 0.05 s. Near: from
  // 1 mm at 1 cm/s, the floor added after 0.01 s, before the sphere has moved enough to rebuild the list.
  // A wall missed by the list lets the sphere through.
  struct Case {
    const char* name;
    double gap, speed, added_at, duration;
  };
  for (const Case& c : {Case{"far", 0.5, 2.0, 0.05, 0.5}, Case{"near", 1e-3, 0.01, 0.01, 0.5}}) {
    scene::Scene scene = undamped_hertz_scene(2700, 70e6, 0.33);
    const double r = 0.1;
    scene.particle_sets.push_back(spheres({scene::Sphere{Vec3(0, 0, c.gap + r), r, Vec3(0, 0, -c.speed)}}));
    DemModel model(scene);
    const double dt = 5e-6;
    double dt_previous = 0, lowest = 1.0;
    for (double t = 0; t < c.duration; t += dt) {
      if (std::abs(t - c.added_at) < 0.5 * dt) {
        Wall side;
        side.point = Vec3(-5, 0, 0);
        side.normal = Vec3::UnitX();
        model.add_wall(side);
        model.add_wall(Wall{});
      }
      step(model, dt_previous, dt);
      lowest = std::min(lowest, model.positions()[0].z());
    }
    std::cout << c.name << ": lowest centre " << lowest << " m (expected above " << 0.9 * r << ")\n";
    expect_relative(std::string(c.name) + " rebound speed (m/s)", model.velocities()[0].z(), c.speed, 0.01);
    EXPECT_GT(lowest, 0.9 * r) << c.name;
  }
}

TEST(DemLawsKernel, PairForcesEqualThePhysicsFunctions) {
  // An oblique, spinning contact over a few steps: DemModel's pair force equals the library law's.
  for (const bool hertz : {false, true}) {
    scene::Scene scene = material_scene(2500, 1e8, 0.3);
    scene.dem_contact.model = hertz ? scene::DemLaw::hertz_mindlin : scene::DemLaw::linear;
    scene.dem_contact.restitution = 0.4;
    scene.dem_contact.friction = 0.3;
    scene.dem_contact.rolling_friction = 0;
    scene.dem_contact.normal_stiffness = 1e6;
    const double r = 0.05;
    // b approaches a obliquely (gap 1e-5 m), spinning; the comparison runs while they touch.
    const Vec3 offset = Vec3(0.02, 0.01, 0.0858).normalized() * (1.8 * r + 1e-5);
    scene.particle_sets.push_back(spheres({scene::Sphere{Vec3(0, 0, 0), r, Vec3(0.3, 0.1, 0.5), Vec3(1, 2, 3)},
                                           scene::Sphere{offset, 0.8 * r, Vec3(-0.1, 0, -0.4), Vec3(-2, 0, 1)}}));
    DemModel model(scene);
    physics::TangentialHistory history;
    double dt_previous = 0;
    const double dt = 1e-6;
    double largest_difference = 0, largest_force = 0;
    for (int n = 0; n < 400; ++n) {
      const auto x = model.positions();
      const auto v = model.velocities();
      const auto w = model.angular_velocities();
      const auto radius = model.radii();
      const Vec3 separation = x[0] - x[1];
      const double distance = separation.norm();
      const Vec3 normal = separation / distance;
      const double overlap = radius[0] + radius[1] - distance;
      const Vec3 arm_a = -(radius[0] - 0.5 * overlap) * normal, arm_b = (radius[1] - 0.5 * overlap) * normal;
      const Vec3 relative = (v[0] + w[0].cross(arm_a)) - (v[1] + w[1].cross(arm_b));
      if (!(overlap > 0)) {
        step(model, dt_previous, dt);
        continue;
      }
      const physics::ContactForce expected =
          hertz
              ? physics::hertz_mindlin_force(model.hertz_law(0, 1), overlap, normal, relative, dt_previous, history)
              : physics::spring_dashpot_force(model.contact_law(0, 1), overlap, normal, relative, dt_previous, history);
      model.compute_internal_forces(dt_previous);
      largest_difference = std::max(largest_difference, (model.forces()[0] - expected.force).norm());
      largest_force = std::max(largest_force, expected.force.norm());
      model.integrate(dt_previous, dt);
      dt_previous = dt;
    }
    std::cout << (hertz ? "hertz_mindlin" : "linear") << " kernel vs library: largest difference " << largest_difference
              << " N of forces up to " << largest_force << " N (expected round-off)\n";
    EXPECT_GT(largest_force, 1.0);
    EXPECT_LT(largest_difference, 1e-9 * largest_force);
  }
}

// A sphere launched sliding without spin on the plane z = 0 (linear law, settled at its static overlap).
struct Rolling {
  double sliding_end = 0, sliding_distance = 0, speed_at_end = 0;
  std::vector<std::pair<double, double>> speed;  // (t, v) after sliding
};

Rolling roll(scene::Scene scene, double v0, double duration) {
  const double r = 0.05, density = 2500, stiffness = 1e6;
  const double mass = density * 4.0 / 3.0 * std::numbers::pi * r * r * r;
  scene.run.gravity = Vec3(0, 0, -9.81);
  scene.dem_contact.normal_stiffness = stiffness;
  scene.dem_contact.normal_damping_ratio = 0.7;
  scene.dem_contact.tangential_damping_ratio = 0.4;
  const double resting_overlap = mass * 9.81 / stiffness;
  scene.particle_sets.push_back(spheres({scene::Sphere{Vec3(0, 0, r - resting_overlap), r, Vec3(v0, 0, 0)}}));
  DemModel model(scene);
  model.add_wall(Wall{});
  const double dt = 0.1 * model.stable_dt();
  Rolling result;
  double dt_previous = 0, t = 0, previous_slip = v0;
  const double threshold = 0.005 * v0;
  for (; t < duration; t += dt) {
    step(model, dt_previous, dt);
    const Vec3 v = model.velocities()[0], w = model.angular_velocities()[0];
    const double slip = v.x() - r * w.y();  // contact point velocity
    if (result.sliding_end == 0 && slip < threshold) {
      const double fraction = (previous_slip - threshold) / (previous_slip - slip);
      result.sliding_end = t + fraction * dt;
      result.sliding_distance = model.positions()[0].x();
      result.speed_at_end = v.x();
    }
    if (result.sliding_end > 0) result.speed.emplace_back(t + dt, v.x());
    previous_slip = slip;
  }
  return result;
}

double speed_at(const Rolling& run, double t) {
  for (const auto& [time, v] : run.speed) {
    if (time >= t) return v;
  }
  return run.speed.back().second;
}

TEST(DemLawsD4, SlidingToRolling) {
  const double v0 = 2.0, mu = 0.3, g = 9.81;
  scene::Scene scene = material_scene(2500, 1e8, 0.3);
  scene.dem_contact.friction = mu;
  scene.dem_contact.rolling_friction = 0;
  const Rolling run = roll(scene, v0, 0.3);
  expect_relative("D4 sliding time (s)", run.sliding_end, 2 * v0 / (7 * mu * g), 0.02);
  expect_relative("D4 sliding distance (m)", run.sliding_distance, 12 * v0 * v0 / (49 * mu * g), 0.02);
  expect_relative("D4 speed when rolling starts (m/s)", run.speed_at_end, 5 * v0 / 7, 0.02);
}

TEST(DemLawsD4, ConstantRollingResistanceDecelerates) {
  const double v0 = 2.0, mu = 0.3, mu_r = 0.05, g = 9.81;
  scene::Scene scene = material_scene(2500, 1e8, 0.3);
  scene.dem_contact.friction = mu;
  scene.dem_contact.rolling_friction = mu_r;
  const Rolling run = roll(scene, v0, 1.5);
  const double t1 = run.sliding_end + 0.2, t2 = run.sliding_end + 1.2;
  const double deceleration = (speed_at(run, t1) - speed_at(run, t2)) / (t2 - t1);
  expect_relative("D4 rolling deceleration (m/s^2)", deceleration, 5.0 / 7.0 * mu_r * g, 0.02);
}

TEST(DemLawsD4, ViscousRollingResistanceDecaysExponentially) {
  // Torque eta r F_n (r w) on a rolling sphere: v' = -(5/7) eta g v.
  const double v0 = 2.0, mu = 0.3, eta = 0.05, g = 9.81;
  scene::Scene scene = material_scene(2500, 1e8, 0.3);
  scene.dem_contact.friction = mu;
  scene.dem_contact.rolling = scene::RollingModel::viscous;
  scene.dem_contact.rolling_viscosity = eta;
  const Rolling run = roll(scene, v0, 1.5);
  const double t1 = run.sliding_end + 0.2, t2 = run.sliding_end + 1.2;
  const double rate = std::log(speed_at(run, t1) / speed_at(run, t2)) / (t2 - t1);
  expect_relative("viscous rolling decay rate (1/s)", rate, 5.0 / 7.0 * eta * g, 0.02);
}

TEST(DemLawsScene, PerPairLawsAndTheirCost) {
  scene::Scene scene = material_scene(2500, 1e8, 0.3);
  scene::Material other = scene.materials[0];
  other.name = "n";
  scene.materials.push_back(other);
  scene.dem_contact.pairs.push_back(
      scene::DemPairLaw{"m", "n", {}, scene::DemContactLaw{.model = scene::DemLaw::hertz_mindlin, .friction = 0.2}});
  scene.particle_sets.push_back(spheres({scene::Sphere{Vec3(0, 0, 0), 0.1}}));
  scene::ParticleSet second = spheres({scene::Sphere{Vec3(1, 0, 0), 0.1}});
  second.name = "t";
  second.material = "n";
  scene.particle_sets.push_back(second);
  DemModel model(scene);
  EXPECT_EQ(model.law(0, 1).model, scene::DemLaw::hertz_mindlin);
  EXPECT_EQ(model.law(1, 0).friction, 0.2);
  EXPECT_EQ(model.law(0, 0).model, scene::DemLaw::linear);
  // Hertz pairs bound the step by a fifth of the Rayleigh time.
  const double shear = 1e8 / 2.6, rayleigh = std::numbers::pi * 0.1 * std::sqrt(2500 / shear) / (0.1631 * 0.3 + 0.8766);
  EXPECT_LE(model.stable_dt(), 0.2 * rayleigh * (1 + 1e-12));
}

TEST(DemLawsFill, SizeDistributionsAndPolygonRegions) {
  scene::Scene scene = material_scene(2500, 1e8, 0.3);
  scene::ParticleSet set = fill("graded", Aabb{Vec3(0, 0, 0), Vec3(4, 2, 3)}, 400, 0.1, 0.2, 3);
  set.polygon_xz = {{0.0, 0.0}, {4.0, 0.0}, {4.0, 1.0}, {0.0, 3.0}};
  set.distribution = scene::SizeDistribution::sieve;
  set.sieve = {{0.1, 0.0}, {0.15, 0.5}, {0.2, 1.0}};
  set.sieve_by_mass = false;
  scene.particle_sets.push_back(set);
  DemModel model(scene);
  std::size_t fine = 0, outside = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    const double d = 2 * model.radii()[i];
    EXPECT_GE(d, 0.1);
    EXPECT_LE(d, 0.2);
    fine += d < 0.15 ? 1 : 0;
    outside += set.contains_sphere(model.positions()[i], model.radii()[i]) ? 0 : 1;
  }
  std::cout << "sieve by count: " << fine << " of 400 finer than 0.15 m (expected 200 +- 30); " << outside
            << " outside the polygon (expected 0)\n";
  EXPECT_NEAR(static_cast<double>(fine), 200.0, 30.0);
  EXPECT_EQ(outside, 0U);

  // Normal, clipped.
  set.distribution = scene::SizeDistribution::normal;
  set.mean_diameter = 0.15;
  set.std_diameter = 0.02;
  scene.particle_sets[0] = set;
  DemModel normal(scene);
  double sum = 0;
  for (double r : normal.radii()) sum += 2 * r;
  std::cout << "normal: mean diameter " << sum / 400 << " m expected 0.15 +- 0.004\n";
  EXPECT_NEAR(sum / 400, 0.15, 0.004);
}

TEST(DemLawsFill, SettlingIsBoundedDeterministicAndAtRest) {
  scene::Scene scene = material_scene(2500, 1e7, 0.3);
  scene.run.gravity = Vec3(0, 0, -9.81);
  scene.dem_contact.model = scene::DemLaw::hertz_mindlin;
  scene.dem_contact.restitution = 0.3;
  scene.dem_contact.friction = 0.5;
  scene::ParticleSet set = fill("beads", Aabb{Vec3(0, 0, 0), Vec3(0.1, 0.1, 0.1)}, 300, 0.01, 0.01, 5);
  set.settle_time = 0.3;
  scene.particle_sets.push_back(set);
  auto build = [&](int threads) {
    omp_set_num_threads(threads);
    try {
      return DemModel(scene);
    } catch (const Error& error) {
      ADD_FAILURE() << error.what();
      throw;
    }
  };
  const int saved = omp_get_max_threads();
  const DemModel one = build(1), two = build(2);
  omp_set_num_threads(saved);
  double top = 0;
  for (const auto& x : one.positions()) top = std::max(top, x.z());
  std::cout << "settled: highest centre " << top << " m (placed up to 0.095 m; a 300-sphere pile of 10 mm in a "
            << "0.1 m box is about 0.02 m deep)\n";
  EXPECT_LT(top, 0.05);
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_TRUE(set.contains_sphere(one.positions()[i], 0.5 * one.radii()[i]));
  }
  EXPECT_EQ(std::memcmp(one.positions().data(), two.positions().data(), one.size() * sizeof(Vec3)), 0);
}

TEST(DemStability, DensePileSettlesBoundedAndAtRest) {
  // Reduced variant of the 10 000-sphere, 10 s case in bench/dem_pile.cpp.
  const scene::Scene scene = pile_scene(250, 1.0, 11);
  const PileReport report = settle_pile(scene, 8.0, 1.0);
  std::cout << "pile of 250 boulders, " << report.steps << " steps of " << report.dt
            << " s: largest energy above the initial " << report.largest_energy_rise << " J (initial "
            << report.initial_energy << " J, expected <= 0); escaped " << report.escaped
            << " (expected 0); at the end largest speed " << report.final_largest_speed << " m/s, overlap largest "
            << 100 * report.final_largest_overlap_ratio << " % mean " << 100 * report.final_mean_overlap_ratio
            << " % of the radius (expected < 1 %), " << report.contacts << " contacts\n";
  EXPECT_LE(report.largest_energy_rise, 1e-12 * std::abs(report.initial_energy));
  EXPECT_EQ(report.escaped, 0U);
  EXPECT_LT(report.final_largest_speed, 0.05);
  EXPECT_LT(report.final_largest_overlap_ratio, 0.01);
  EXPECT_GT(report.contacts, 250U);
}

}  // namespace
}  // namespace sabo::dem
