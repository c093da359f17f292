// DemModel: D2 restitution and contact time, free fall, resting contacts,
// rolling resistance, energy, and determinism across thread counts.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <iostream>
#include <numbers>

#include "dem_solver/dem_model.hpp"
#include "dem_test_scene.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/physics/contact_law.hpp"

namespace sabo::dem {
namespace {

using testing::fill_set;
using testing::list_set;
using testing::rock_scene;

constexpr double kRadius = 0.05;     // m
constexpr double kDensity = 2500.0;  // kg/m^3
const double kMass = kDensity * 4.0 / 3.0 * std::numbers::pi * kRadius * kRadius * kRadius;

// One central-difference step in the order main.cpp runs it.
void step(DemModel& model, double& dt_previous, double dt) {
  model.compute_internal_forces(dt_previous);
  model.integrate(dt_previous, dt);
  dt_previous = dt;
}

scene::Scene contact_scene(double stiffness, double normal_damping_ratio, Vec3 gravity) {
  scene::Scene scene = rock_scene(kDensity);
  scene.run.gravity = gravity;
  scene.dem_contact.normal_stiffness = stiffness;
  scene.dem_contact.normal_damping_ratio = normal_damping_ratio;
  return scene;
}

struct Collision {
  double restitution = 0;
  double contact_time = 0;                                      // s
  double largest_energy_rise = 0;                               // J, over one step
  double initial_energy = 0, final_energy = 0, dissipated = 0;  // J
};

// Head-on collision of two equal spheres (or of one with a fixed sphere) at a
// closing speed of 1 m/s, steps_per_contact steps per expected contact time.
Collision collide(double zeta, int steps_per_contact, bool fixed_partner) {
  const double stiffness = 1e5;  // N/m
  scene::Scene scene = contact_scene(stiffness, zeta, Vec3::Zero());
  const double gap = 1e-3;  // m, between the surfaces at t = 0
  const Vec3 va = fixed_partner ? Vec3(1, 0, 0) : Vec3(0.5, 0, 0);
  scene.particle_sets.push_back(list_set(
      "pair", {scene::Sphere{Vec3(-kRadius - gap / 2, 0, 0), kRadius, va},
               scene::Sphere{Vec3(kRadius + gap / 2, 0, 0), kRadius, fixed_partner ? Vec3::Zero() : Vec3(-va)}}));
  DemModel model(scene);
  if (fixed_partner) model.set_fixed(1, true);
  const double effective_mass = fixed_partner ? kMass : kMass / 2;
  const double omega = std::sqrt(stiffness / effective_mass);
  const double expected_time = std::numbers::pi / (omega * std::sqrt(1 - zeta * zeta));
  const double dt = expected_time / steps_per_contact;

  Collision result;
  result.initial_energy = model.energies().total();
  double previous_energy = result.initial_energy;
  double previous_gap = gap, t = 0, dt_previous = 0, start = -1, end = -1;
  for (int n = 0; n < 4 * steps_per_contact && end < 0; ++n) {
    step(model, dt_previous, dt);
    t += dt;
    const double energy = model.energies().total();
    result.largest_energy_rise = std::max(result.largest_energy_rise, energy - previous_energy);
    previous_energy = energy;
    // Positions move linearly within a step: the crossings interpolate exactly.
    const double now_gap = (model.positions()[1] - model.positions()[0]).norm() - 2 * kRadius;
    if (start < 0 && previous_gap >= 0 && now_gap < 0) start = t - dt * now_gap / (now_gap - previous_gap);
    if (start >= 0 && previous_gap < 0 && now_gap >= 0) end = t - dt * now_gap / (now_gap - previous_gap);
    previous_gap = now_gap;
  }
  EXPECT_GE(end, 0) << "the spheres did not separate";
  step(model, dt_previous, dt);  // no contact any more: final velocities
  result.restitution = (model.velocities()[1] - model.velocities()[0]).x() / 1.0;
  result.contact_time = end - start;
  result.final_energy = model.energies().total();
  result.dissipated = model.energies().dissipated;
  return result;
}

TEST(DemModelD2, RestitutionAndContactTimeOfTheSpringDashpot) {
  for (double zeta : {0.1, 0.3, 0.7}) {
    const double e_ref = std::exp(-std::numbers::pi * zeta / std::sqrt(1 - zeta * zeta));
    const double omega = std::sqrt(1e5 / (kMass / 2));
    const double t_ref = std::numbers::pi / (omega * std::sqrt(1 - zeta * zeta));
    std::cout << "zeta " << zeta << ": expected e " << e_ref << ", contact time " << t_ref << " s\n";
    // The dashpot sees v_{n-1/2}, half a step late: the restitution converges at first order.
    for (int steps : {25, 100, 400, 1600, 6400}) {
      const Collision c = collide(zeta, steps, false);
      std::cout << "  " << steps << " steps/contact: restitution measured " << c.restitution << " (error "
                << 100 * (c.restitution / e_ref - 1) << "%), contact time measured " << c.contact_time << " (error "
                << 100 * (c.contact_time / t_ref - 1) << "%)\n";
      if (steps == 6400) {
        EXPECT_NEAR(c.restitution, e_ref, 0.005 * e_ref);
        EXPECT_NEAR(c.contact_time, t_ref, 0.01 * t_ref);
      }
    }
  }
}

TEST(DemModelD2, ImpactOnAFixedSphere) {
  const double zeta = 0.3;
  const double e_ref = std::exp(-std::numbers::pi * zeta / std::sqrt(1 - zeta * zeta));
  const double t_ref = std::numbers::pi / (std::sqrt(1e5 / kMass) * std::sqrt(1 - zeta * zeta));
  const Collision c = collide(zeta, 6400, true);
  std::cout << "fixed partner: restitution measured " << c.restitution << " expected " << e_ref
            << "; contact time measured " << c.contact_time << " expected " << t_ref << "\n";
  EXPECT_NEAR(c.restitution, e_ref, 0.005 * e_ref);
  EXPECT_NEAR(c.contact_time, t_ref, 0.01 * t_ref);
}

TEST(DemModelEnergy, NeverIncreasesInADampedCollision) {
  for (double zeta : {0.1, 0.7}) {
    const int steps = 200;
    const Collision c = collide(zeta, steps, false);
    const double dissipated_ref = c.initial_energy * (1 - c.restitution * c.restitution);
    // Within a contact the discrete energy 1/2 m v_{n-1/2}.v_{n+1/2} + 1/2 k delta_n^2 only
    // decreases; the force switching on and off mid-step can add at most 1/2 k (v dt)^2.
    const double onset_bound = 0.5 * 1e5 * std::pow(1.0 * c.contact_time / steps, 2);
    std::cout << "zeta " << zeta << ": largest rise over one step " << c.largest_energy_rise
              << " J (expected <= " << onset_bound << " J, the contact switching mid-step); dissipated measured "
              << c.dissipated << " J expected " << dissipated_ref << " J\n";
    EXPECT_LE(c.largest_energy_rise, onset_bound);
    EXPECT_NEAR(c.dissipated, dissipated_ref, 0.02 * c.initial_energy);
  }
}

TEST(DemModelEnergy, ObliqueImpactWithFrictionAndSpin) {
  // Off-centre impact on a fixed sphere: normal and tangential springs, sliding, rotation.
  scene::Scene scene = contact_scene(1e5, 0.3, Vec3::Zero());
  scene.dem_contact.friction = 0.3;
  scene.dem_contact.rolling_friction = 0.1;
  scene.particle_sets.push_back(list_set(
      "pair", {scene::Sphere{Vec3(-0.11, 0.04, 0), kRadius, Vec3(1, 0, 0)}, scene::Sphere{Vec3(0, 0, 0), kRadius}}));
  DemModel model(scene);
  model.set_fixed(1, true);
  const double e0 = model.energies().total();
  const double dt = 0.05 * model.stable_dt();
  double dt_previous = 0, previous = e0, largest_rise = 0;
  bool spun = false;
  for (int n = 0; n < 3000; ++n) {
    step(model, dt_previous, dt);
    const double energy = model.energies().total();
    largest_rise = std::max(largest_rise, energy - previous);
    previous = energy;
    spun = spun || model.angular_velocities()[0].norm() > 1.0;
  }
  const Energies end = model.energies();
  std::cout << "oblique impact: largest rise over one step " << largest_rise << " J (expected <= " << 1e-6 * e0
            << "), final " << end.total() << " J + dissipated " << end.dissipated
            << " J = " << end.total() + end.dissipated << " J, expected " << e0 << " J\n";
  EXPECT_TRUE(spun);
  EXPECT_EQ(model.contact_count(), 0U);
  EXPECT_LT(end.total(), e0);
  EXPECT_LE(largest_rise, 1e-6 * e0);
  EXPECT_NEAR(end.total() + end.dissipated, e0, 0.02 * e0);
}

TEST(DemModelMotion, FreeFallIsExactForConstantGravityWithVaryingSteps) {
  scene::Scene scene = rock_scene();
  const Vec3 x0(1, 2, 10), v0(1, -0.5, 2), w0(3, 0, -1), g = scene.run.gravity;
  scene.particle_sets.push_back(list_set("stone", {scene::Sphere{x0, 0.1, v0, w0}}));
  DemModel model(scene);
  double t = 0, dt_previous = 0, largest_error = 0;
  for (int n = 0; n < 1000; ++n) {
    const double dt = 1e-3 * (1 + 0.5 * (n % 3));
    step(model, dt_previous, dt);
    t += dt;
    const Vec3 exact = x0 + v0 * t + 0.5 * g * t * t;
    largest_error = std::max(largest_error, (model.positions()[0] - exact).norm());
  }
  std::cout << "free fall after " << t << " s: largest position error " << largest_error
            << " m (expected round-off, < 1e-11 m); spin measured " << model.angular_velocities()[0].transpose()
            << " expected " << w0.transpose() << "\n";
  EXPECT_LT(largest_error, 1e-11);
  EXPECT_EQ(model.angular_velocities()[0], w0);
  // v_{n+1/2} = v0 + g (t_n + dt_n / 2): last half-step velocity.
  const Vec3 v_half = v0 + g * (t - 0.5 * dt_previous);
  EXPECT_LT((model.velocities()[0] - v_half).norm(), 1e-12);
}

TEST(DemModelMotion, AnEmptySceneSteps) {
  DemModel model(rock_scene());
  double dt_previous = 0;
  step(model, dt_previous, 1e-3);
  step(model, dt_previous, 1e-3);
  EXPECT_EQ(model.size(), 0U);
  EXPECT_EQ(model.contact_count(), 0U);
  EXPECT_TRUE(std::isinf(model.stable_dt()));
  EXPECT_TRUE(model.bounds().empty());
  EXPECT_EQ(model.energies().total(), 0.0);
}

TEST(DemModelMotion, StableStepFollowsThePaperFormula) {
  scene::Scene scene = rock_scene(3000);
  // LS-DYNA style stiffness from the bulk modulus: K r1 K r2 / (K r1 + K r2) for the two largest.
  scene.particle_sets.push_back(list_set(
      "boulders",
      {scene::Sphere{Vec3(0, 0, 0), 0.5}, scene::Sphere{Vec3(3, 0, 0), 1.0}, scene::Sphere{Vec3(6, 0, 0), 0.8}}));
  const DemModel model(scene);
  const double bulk = scene.materials[0].bulk_modulus();
  const double k = 0.01 * (bulk * 1.0) * (bulk * 0.8) / (bulk * 1.0 + bulk * 0.8);
  const double m_min = 3000 * 4.0 / 3.0 * std::numbers::pi * 0.125;
  const double expected = 0.2 * std::numbers::pi * std::sqrt(m_min / k);
  std::cout << "stable dt: measured " << model.stable_dt() << " s expected " << expected << " s\n";
  EXPECT_NEAR(model.stable_dt(), expected, 1e-12 * expected);
  EXPECT_NEAR(model.contact_law(0, 1).normal_stiffness, 0.01 * bulk * 0.5 * bulk / (bulk * 1.5), 1e-6);
}

// Three fixed spheres in a touching triangle and a free sphere dropped into their pocket.
struct PocketResult {
  double overlap = 0, expected_overlap = 0, speed = 0, spin = 0, drift = 0;
  Vec3 load = Vec3::Zero();
};

PocketResult settle_in_pocket(double friction, double rolling_friction) {
  const double stiffness = 1e5;
  scene::Scene scene = contact_scene(stiffness, 0.7, Vec3(0, 0, -9.81));
  scene.dem_contact.friction = friction;
  scene.dem_contact.rolling_friction = rolling_friction;
  const double offset = 2 * kRadius / std::sqrt(3.0);  // horizontal distance of the bed spheres from the axis
  std::vector<scene::Sphere> bed;
  for (int k = 0; k < 3; ++k) {
    const double angle = std::numbers::pi / 2 + 2 * std::numbers::pi * k / 3;
    bed.push_back(scene::Sphere{Vec3(offset * std::cos(angle), offset * std::sin(angle), 0), kRadius});
  }
  const double touching_height = std::sqrt(4 * kRadius * kRadius - offset * offset);
  scene.particle_sets.push_back(list_set("bed", bed));
  scene.particle_sets.push_back(list_set("stone", {scene::Sphere{Vec3(0, 0, touching_height + 0.01), kRadius}}));
  DemModel model(scene);
  for (std::uint32_t k = 0; k < 3; ++k) model.set_fixed(k, true);

  const double dt = 0.2 * model.stable_dt();
  double dt_previous = 0;
  for (int n = 0; n < static_cast<int>(0.5 / dt); ++n) step(model, dt_previous, dt);
  model.compute_internal_forces(dt_previous);

  PocketResult result;
  // Without friction: 3 k delta cos(theta) = m g with cos(theta) = z / (2r - delta).
  auto vertical = [&](double delta) {
    const double d = 2 * kRadius - delta;
    return 3 * stiffness * delta * std::sqrt(d * d - offset * offset) / d - kMass * 9.81;
  };
  double lo = 0, hi = 1e-3;
  for (int i = 0; i < 200; ++i) (vertical(0.5 * (lo + hi)) > 0 ? hi : lo) = 0.5 * (lo + hi);
  result.expected_overlap = 0.5 * (lo + hi);
  result.overlap = 2 * kRadius - (model.positions()[3] - model.positions()[0]).norm();
  for (std::uint32_t k = 0; k < 3; ++k) result.load += model.forces()[k];
  result.speed = model.velocities()[3].norm();
  result.spin = model.angular_velocities()[3].norm();
  result.drift = model.positions()[3].head<2>().norm();
  std::cout << "pocket, friction " << friction << ", rolling friction " << rolling_friction << ": overlap measured "
            << result.overlap << " m (frictionless expected " << result.expected_overlap << " m); load on the bed "
            << result.load.transpose() << " N expected (0 0 " << -kMass * 9.81 << "); speed " << result.speed
            << " m/s, spin " << result.spin << " rad/s; horizontal drift " << result.drift << " m\n";
  return result;
}

TEST(DemModelRest, SphereSettlesInThePocketOfThreeFixedSpheres) {
  for (double friction : {0.0, 1.0}) {
    const PocketResult r = settle_in_pocket(friction, 0.1);
    // With friction the tangential springs hold part of the load (statically indeterminate).
    if (friction == 0) {
      EXPECT_NEAR(r.overlap, r.expected_overlap, 1e-6 * r.expected_overlap);
    }
    EXPECT_NEAR(r.load.z(), -kMass * 9.81, 1e-6 * kMass * 9.81);
    EXPECT_LT(r.load.head<2>().norm(), 1e-9);
    EXPECT_LT(r.speed, 1e-9);
    EXPECT_LT(r.spin, 1e-9);
    EXPECT_LT(r.drift, 1e-9);
  }
}

TEST(DemModelRest, RollingResistanceStopsASpinAtConstantTorqueAndHolds) {
  // A sphere resting on a fixed one, spinning about the contact normal: only the rolling
  // resistance acts, at its cap a constant deceleration mu_r r_eff m g / I.
  // w0 large enough for the spin to stop after many times the rotation that loads the rolling
  // spring to its cap (overlap / (2.25 mu_r r_eff) = 0.023 rad here).
  const double stiffness = 1e5, mu_r = 0.1, w0 = 5.0;
  scene::Scene scene = contact_scene(stiffness, 0.7, Vec3(0, 0, -9.81));
  scene.dem_contact.rolling_friction = mu_r;
  scene.particle_sets.push_back(
      list_set("stack", {scene::Sphere{Vec3::Zero(), kRadius}, scene::Sphere{Vec3(0, 0, 2 * kRadius), kRadius}}));
  DemModel model(scene);
  model.set_fixed(0, true);
  const double dt = 0.1 * model.stable_dt();
  double t = 0, dt_previous = 0;
  for (int n = 0; n < static_cast<int>(0.2 / dt); ++n) step(model, dt_previous, dt);  // settle
  model.angular_velocities()[1] = Vec3(0, 0, w0);

  const double inertia = 0.4 * kMass * kRadius * kRadius;
  const double cap = mu_r * (kRadius / 2) * kMass * 9.81;
  const double deceleration = cap / inertia;
  const physics::RollingSpring law = model.rolling_law(0, 1);
  // The spring, loaded to the cap when the spin stops, unwinds: at most cap / sqrt(k_r I) back.
  const double rebound_bound = cap / std::sqrt(law.stiffness * inertia);
  double stop_time = -1, lowest = w0, spin_at_half = 0;
  const double half_time = 0.5 * w0 / deceleration;
  for (int n = 0; n < static_cast<int>(1.5 / dt); ++n) {  // stops at 0.2 s
    const bool crosses_half = t < half_time && t + dt >= half_time;
    const double before = model.angular_velocities()[1].z();
    step(model, dt_previous, dt);
    t += dt;
    const double w = model.angular_velocities()[1].z();
    if (crosses_half) spin_at_half = w + deceleration * (t - half_time);  // back to half_time at the expected slope
    lowest = std::min(lowest, w);
    if (stop_time < 0 && before > 0 && w <= 0) stop_time = t - dt * w / (w - before);
  }
  std::cout << "spin at " << half_time << " s: measured " << spin_at_half << " rad/s expected " << w0 / 2
            << "; stopped at " << stop_time << " s expected " << w0 / deceleration << " s (dt " << dt
            << " s); largest reverse spin " << -lowest << " rad/s (elastic bound " << rebound_bound << "); after 1.5 s "
            << model.angular_velocities()[1].norm() << " rad/s (expected < 1e-6)\n";
  EXPECT_NEAR(spin_at_half, w0 / 2, 0.005 * w0);
  EXPECT_NEAR(stop_time, w0 / deceleration, 0.005 * w0 / deceleration);
  EXPECT_LT(-lowest, rebound_bound);
  EXPECT_LT(model.angular_velocities()[1].norm(), 1e-6);  // the rolling spring's damped rocking dies out
}

// A bowl of fixed spheres (lower hemisphere, Fibonacci lattice) and stones poured into it.
// The lattice spacing (about 0.044 m at both sizes) leaves no hole a stone could pass.
scene::Scene bowl_scene(bool large, std::size_t stones) {
  scene::Scene scene = contact_scene(2e4, 0.7, Vec3(0, 0, -9.81));
  scene.dem_contact.tangential_damping_ratio = 0.4;
  scene.dem_contact.friction = 0.5;
  scene.dem_contact.rolling_friction = 0.1;
  const double bowl_radius = large ? 0.4 : 0.25, bed_radius = 0.021;
  const int lattice = large ? 800 : 320;
  std::vector<scene::Sphere> bed;
  for (int k = 0; k < lattice; ++k) {
    const double s = k + 0.5, z = 1 - 2 * s / lattice, phi = std::numbers::pi * (1 + std::sqrt(5.0)) * s;
    if (z >= 0) continue;
    const double r = std::sqrt(1 - z * z);
    bed.push_back(scene::Sphere{bowl_radius * Vec3(r * std::cos(phi), r * std::sin(phi), z), bed_radius});
  }
  scene.particle_sets.push_back(list_set("bowl", bed));
  const double half = large ? 0.2 : 0.12;
  scene.particle_sets.push_back(
      fill_set("stones", Aabb{Vec3(-half, -half, -half), Vec3(half, half, 0.25)}, stones, 0.06, 0.08, 3));
  return scene;
}

void fix_bowl(DemModel& model) {
  for (std::uint32_t i = 0; i < model.size(); ++i) {
    if (model.body_index()[i] == 0) model.set_fixed(i, true);
  }
}

TEST(DemModelRest, PileSettlesInABowl) {
  DemModel model(bowl_scene(false, 30));
  fix_bowl(model);
  // beta 0.25: with zeta_n 0.7 and up to 7 contacts per stone, beta 0.5 is unstable (the
  // explicit dashpots overshoot: a period-2 oscillation that sliding keeps bounded).
  const double dt = 0.25 * model.stable_dt();
  const double e0 = model.energies().total();
  double dt_previous = 0, previous = e0, largest_rise = 0, weight = 0;
  for (std::uint32_t i = 0; i < model.size(); ++i) weight += model.is_fixed(i) ? 0 : model.masses()[i] * 9.81;
  const int steps = static_cast<int>(3.0 / dt);
  const double impact_speed = std::sqrt(2 * 9.81 * 0.5);  // the highest stones fall about 0.5 m
  const double onset_bound = 0.5 * 2e4 * std::pow(impact_speed * dt, 2);
  for (int n = 0; n < steps; ++n) {
    step(model, dt_previous, dt);
    largest_rise = std::max(largest_rise, model.energies().total() - previous);
    previous = model.energies().total();
  }
  model.compute_internal_forces(dt_previous);
  double fastest = 0, farthest = 0, highest = -1;
  Vec3 load = Vec3::Zero();
  for (std::uint32_t i = 0; i < model.size(); ++i) {
    if (model.is_fixed(i)) {
      load += model.forces()[i];
      continue;
    }
    fastest = std::max(fastest, model.velocities()[i].norm());
    farthest = std::max(farthest, model.positions()[i].norm());
    highest = std::max(highest, model.positions()[i].z());
  }
  const Energies end = model.energies();
  std::cout << "bowl, " << steps << " steps of " << dt << " s, " << model.contact_count() << " contacts: fastest stone "
            << fastest << " m/s (expected 0), farthest centre " << farthest << " m (bowl 0.25 m), highest centre "
            << highest << " m (rim 0), load on the bowl " << load.transpose() << " N expected (0 0 " << -weight
            << "); energy " << end.total() << " + dissipated " << end.dissipated << " = "
            << end.total() + end.dissipated << " J vs initial " << e0 << " J; largest rise " << largest_rise
            << " J (bound for contacts switching mid-step " << onset_bound << " J)\n";
  EXPECT_LT(fastest, 1e-9);
  EXPECT_LT(farthest, 0.25);  // nothing fell through the bowl
  EXPECT_LT(highest, 0.0);    // nothing left above the rim
  EXPECT_NEAR(load.z(), -weight, 1e-6 * weight);
  EXPECT_LT(load.head<2>().norm(), 1e-6 * weight);
  EXPECT_LE(largest_rise, onset_bound);
  EXPECT_NEAR(end.total() + end.dissipated, e0, 0.01 * (e0 - end.total()));
}

TEST(DemModelDeterminism, SameBitsWithOneAndTwoThreads) {
  // Large bowl (above the size where the loops go parallel), stones placed low in it so that
  // contacts, sliding and rolling all happen within a few hundred steps.
  scene::Scene scene = bowl_scene(true, 0);
  scene.particle_sets.back() =
      fill_set("stones", Aabb{Vec3(-0.12, -0.12, -0.39), Vec3(0.12, 0.12, -0.2)}, 25, 0.05, 0.06, 4);
  auto run = [&scene](int threads) {
    omp_set_num_threads(threads);
    DemModel model(scene);
    fix_bowl(model);
    const double dt = 0.25 * model.stable_dt();
    double dt_previous = 0;
    for (int n = 0; n < 300; ++n) step(model, dt_previous, dt);
    return model;
  };
  const int saved = omp_get_max_threads();
  const DemModel one = run(1), two = run(2);
  omp_set_num_threads(saved);
  const std::size_t bytes = one.size() * sizeof(Vec3);
  std::cout << "threads 1/2: " << one.size() << " spheres, " << one.contact_count() << " contacts, energy "
            << one.energies().total() << " / " << two.energies().total() << " J, dissipated "
            << one.energies().dissipated << " / " << two.energies().dissipated << " J (expected bitwise equal)\n";
  ASSERT_GE(one.size(), 256U);
  EXPECT_GT(one.contact_count(), 25U);
  EXPECT_EQ(std::memcmp(one.positions().data(), two.positions().data(), bytes), 0);
  EXPECT_EQ(std::memcmp(one.velocities().data(), two.velocities().data(), bytes), 0);
  EXPECT_EQ(std::memcmp(one.angular_velocities().data(), two.angular_velocities().data(), bytes), 0);
  EXPECT_EQ(one.energies().total(), two.energies().total());
  EXPECT_EQ(one.energies().dissipated, two.energies().dissipated);
}

TEST(DemModelIo, ExternalForcesAndCheckpointedHistories) {
  scene::Scene scene = contact_scene(1e5, 0.3, Vec3::Zero());
  scene.particle_sets.push_back(list_set("one", {scene::Sphere{Vec3::Zero(), kRadius}}));
  DemModel model(scene);
  const std::vector<std::uint32_t> ids{0};
  const std::vector<double> force{kMass, 0, 0}, torque{0, 0, 0.4 * kMass * kRadius * kRadius};
  model.compute_internal_forces(0);
  model.add_external_forces(ids, force, torque);
  model.integrate(0, 0.01);  // first half step: dt/2 * a = 0.005
  std::cout << "external force: velocity measured " << model.velocities()[0].x() << " expected 0.005; spin "
            << model.angular_velocities()[0].z() << " expected 0.005\n";
  EXPECT_NEAR(model.velocities()[0].x(), 0.005, 1e-15);
  EXPECT_NEAR(model.angular_velocities()[0].z(), 0.005, 1e-15);
  EXPECT_THROW(model.add_external_forces(ids, std::vector<double>{1, 2}, {}), ModelInputError);
  EXPECT_THROW(model.add_external_forces(std::vector<std::uint32_t>{7}, force, {}), ModelInputError);

  // Histories survive a checkpoint: a model restored from them continues with the same bits.
  scene::Scene pile = bowl_scene(false, 30);
  DemModel a(pile), b(pile);
  fix_bowl(a);
  fix_bowl(b);
  const double dt = 0.25 * a.stable_dt();
  double dt_previous = 0;
  for (int n = 0; n < 300; ++n) step(a, dt_previous, dt);
  b.set_positions(a.positions());
  std::copy(a.velocities().begin(), a.velocities().end(), b.velocities().begin());
  std::copy(a.angular_velocities().begin(), a.angular_velocities().end(), b.angular_velocities().begin());
  const auto histories = a.contact_histories();
  b.restore(histories, a.energies().dissipated);
  double dt_b = dt_previous;
  for (int n = 0; n < 100; ++n) {
    step(a, dt_previous, dt);
    step(b, dt_b, dt);
  }
  std::cout << "restart: " << histories.size() << " histories restored\n";
  EXPECT_GT(histories.size(), 10U);
  EXPECT_EQ(std::memcmp(a.positions().data(), b.positions().data(), a.size() * sizeof(Vec3)), 0);
  EXPECT_EQ(a.energies().dissipated, b.energies().dissipated);
}

// Issue 17, item 3: `fixed = true` on a particle set fixes its spheres from the start, exactly as set_fixed()
// does (same bits), and they stay where they are under gravity and the load of a sphere resting on them.
TEST(DemModelRest, FixedSetOfTheSceneIsHeldFromTheStart) {
  scene::Scene scene = contact_scene(1e5, 0.7, Vec3(0, 0, -9.81));
  scene.dem_contact.friction = 1.0;
  const double offset = 2 * kRadius / std::sqrt(3.0);
  std::vector<scene::Sphere> bed;
  for (int k = 0; k < 3; ++k) {
    const double angle = std::numbers::pi / 2 + 2 * std::numbers::pi * k / 3;
    bed.push_back(scene::Sphere{Vec3(offset * std::cos(angle), offset * std::sin(angle), 0), kRadius});
  }
  const double touching_height = std::sqrt(4 * kRadius * kRadius - offset * offset);
  scene.particle_sets.push_back(list_set("bed", bed));
  scene.particle_sets.push_back(list_set("stone", {scene::Sphere{Vec3(0, 0, touching_height + 0.01), kRadius}}));
  DemModel by_hand(scene);
  for (std::uint32_t k = 0; k < 3; ++k) by_hand.set_fixed(k, true);
  scene.particle_sets[0].fixed = true;
  DemModel by_scene(scene);
  for (std::uint32_t k = 0; k < 4; ++k) EXPECT_EQ(by_scene.is_fixed(k), k < 3);
  const double dt = 0.2 * by_hand.stable_dt();
  EXPECT_EQ(by_scene.stable_dt(), by_hand.stable_dt());
  double dt_previous = 0, dt_previous_scene = 0;
  for (int n = 0; n < static_cast<int>(0.3 / dt); ++n) {
    step(by_hand, dt_previous, dt);
    step(by_scene, dt_previous_scene, dt);
  }
  for (std::uint32_t k = 0; k < 4; ++k) ASSERT_EQ(by_scene.positions()[k], by_hand.positions()[k]) << k;
  EXPECT_EQ(by_scene.energies().total(), by_hand.energies().total());
  for (std::uint32_t k = 0; k < 3; ++k) EXPECT_EQ(by_scene.positions()[k], bed[k].center);
  std::cout << "the stone rests at z = " << by_scene.positions()[3].z() << " m on the fixed bed (touching at "
            << touching_height << " m)\n";
  EXPECT_NEAR(by_scene.positions()[3].z(), touching_height, 0.01 * kRadius);
}

}  // namespace
}  // namespace sabo::dem
