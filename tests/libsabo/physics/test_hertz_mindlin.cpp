// Hertz-Mindlin (no-slip) contact law: benchmark D1 (Chung & Ooi 2011, tests 1 and 2) with an
// explicit integration of the normal impact, restitution with damping, and the tangential
// stick / slip behaviour against hand-computed values.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>

#include "libsabo/core/error.hpp"
#include "libsabo/physics/hertz_mindlin.hpp"
#include "tests/support/measure.hpp"

namespace sabo::physics {
namespace {

constexpr double kTight = 1e-12;
constexpr double kBenchmarkTolerance = 0.01;  // docs/benchmarks.md D1: 1%
constexpr double kInfinity = std::numeric_limits<double>::infinity();

using sabo::testing::expect_relative;

double sphere_mass(double density, double radius) {
  return density * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
}

// Undamped Hertz impact at relative approach speed v (Johnson 1985, sec. 11.4).
struct HertzImpact {
  double max_overlap;   // m
  double peak_force;    // N
  double contact_time;  // s
};

HertzImpact analytic_hertz_impact(const HertzMindlin& law, double approach_speed) {
  const double e_star = law.effective_modulus;
  const double sqrt_r = std::sqrt(law.effective_radius);
  const double max_overlap =
      std::pow(15.0 * law.effective_mass * approach_speed * approach_speed / (16.0 * e_star * sqrt_r), 0.4);
  // t_c = 2 (delta_max / v) * integral_0^1 dx / sqrt(1 - x^{5/2}) = 2 (delta_max / v) * 2/5 B(2/5, 1/2).
  const double integral = 0.4 * std::tgamma(0.4) * std::tgamma(0.5) / std::tgamma(0.9);
  return {max_overlap, 4.0 / 3.0 * e_star * sqrt_r * std::pow(max_overlap, 1.5),
          2.0 * max_overlap / approach_speed * integral};
}

struct MeasuredImpact {
  double max_overlap = 0;   // m
  double peak_force = 0;    // N
  double contact_time = 0;  // s
  double restitution = 0;   // separation speed / approach speed
};

// Head-on impact along x: A moves in -x at speed_a, B (mass_b = infinity: a fixed wall) moves in
// +x at speed_b; they touch at t = 0. Explicit central differences (velocities at half steps,
// the dashpot sees the latest half-step velocity), as in a DEM code.
MeasuredImpact simulate_impact(const HertzMindlin& law, double mass_a, double mass_b, double speed_a, double speed_b,
                               double dt) {
  const Vec3 n = Vec3::UnitX();  // from B to A
  double position_a = 0, position_b = 0;
  double velocity_a = -speed_a, velocity_b = speed_b;
  TangentialHistory history;
  MeasuredImpact measured;
  double previous_overlap = 0;
  for (long step = 0;; ++step) {
    const double overlap = position_b - position_a;
    if (step > 0 && overlap <= 0) {
      measured.contact_time = dt * (static_cast<double>(step - 1) + previous_overlap / (previous_overlap - overlap));
      break;
    }
    EXPECT_LT(step, 1'000'000) << "the bodies never separated";
    if (step >= 1'000'000) break;
    const Vec3 relative_velocity(velocity_a - velocity_b, 0, 0);
    const ContactForce contact = hertz_mindlin_force(law, overlap, n, relative_velocity, dt, history);
    measured.max_overlap = std::max(measured.max_overlap, overlap);
    measured.peak_force = std::max(measured.peak_force, contact.normal_force);
    velocity_a += contact.force.x() / mass_a * dt;
    if (std::isfinite(mass_b)) velocity_b -= contact.force.x() / mass_b * dt;
    position_a += velocity_a * dt;
    position_b += velocity_b * dt;
    previous_overlap = overlap;
  }
  measured.restitution = (velocity_a - velocity_b) / (speed_a + speed_b);
  return measured;
}

void check_impact(const HertzMindlin& law, double mass_a, double mass_b, double speed_a, double speed_b,
                  const HertzImpact& benchmark) {
  const HertzImpact analytic = analytic_hertz_impact(law, speed_a + speed_b);
  const MeasuredImpact measured =
      simulate_impact(law, mass_a, mass_b, speed_a, speed_b, analytic.contact_time / 2000.0);
  std::cout << "analytic Hertz: max overlap " << analytic.max_overlap << " m, peak force " << analytic.peak_force
            << " N, contact time " << analytic.contact_time << " s\n";
  expect_relative("max overlap vs benchmark, m", measured.max_overlap, benchmark.max_overlap, kBenchmarkTolerance);
  expect_relative("peak force vs benchmark, N", measured.peak_force, benchmark.peak_force, kBenchmarkTolerance);
  expect_relative("contact time vs benchmark, s", measured.contact_time, benchmark.contact_time, kBenchmarkTolerance);
  expect_relative("restitution (e = 1)", measured.restitution, 1.0, kBenchmarkTolerance);
  // The integration itself must reproduce the closed form much more closely than the benchmark.
  expect_relative("max overlap vs analytic, m", measured.max_overlap, analytic.max_overlap, 1e-3);
  expect_relative("peak force vs analytic, N", measured.peak_force, analytic.peak_force, 1e-3);
  expect_relative("contact time vs analytic, s", measured.contact_time, analytic.contact_time, 1e-3);
}

const HertzBody kGlass{48e9, 0.2, 0.01, sphere_mass(2800, 0.01)};
const HertzBody kAluminium{70e9, 0.33, 0.1, sphere_mass(2700, 0.1)};

TEST(HertzMindlin, EffectiveParametersOfTwoGlassSpheres) {
  const HertzMindlin law = hertz_mindlin_parameters(kGlass, kGlass, 1.0, 0.3);
  // E* = 48e9 / (2 * 0.96); G* = 48e9 / (2 * 2 * 1.8 * 1.2); R* = R/2; m* = m/2.
  expect_relative("E*, Pa", law.effective_modulus, 25e9, kTight);
  expect_relative("G*, Pa", law.effective_shear_modulus, 48e9 / 8.64, kTight);
  expect_relative("R*, m", law.effective_radius, 0.005, kTight);
  expect_relative("m*, kg", law.effective_mass, 0.5 * 2800 * 4.0 / 3.0 * std::numbers::pi * 1e-6, kTight);
}

TEST(HertzMindlin, EffectiveParametersOfSphereOnRigidWall) {
  const HertzMindlin law = hertz_mindlin_wall_parameters(kAluminium, kInfinity, 0.3, 0.5, 0.3);
  expect_relative("E*, Pa", law.effective_modulus, 70e9 / (1 - 0.33 * 0.33), kTight);
  expect_relative("G*, Pa", law.effective_shear_modulus, 70e9 / (2 * 1.67 * 1.33), kTight);
  expect_relative("R*, m", law.effective_radius, 0.1, kTight);
  expect_relative("m*, kg", law.effective_mass, kAluminium.mass, kTight);
}

TEST(HertzMindlin, RejectsNonPhysicalParameters) {
  EXPECT_THROW(hertz_mindlin_parameters(kGlass, kGlass, 0.0, 0.3), Error);
  EXPECT_THROW(hertz_mindlin_parameters(kGlass, kGlass, 1.2, 0.3), Error);
  EXPECT_THROW(hertz_mindlin_parameters(kGlass, kGlass, 0.5, -0.1), Error);
  EXPECT_THROW(hertz_mindlin_parameters(HertzBody{48e9, 0.6, 0.01, 1.0}, kGlass, 0.5, 0.3), Error);
  EXPECT_THROW(hertz_mindlin_wall_parameters(HertzBody{48e9, 0.2, 0.0, 1.0}, kInfinity, 0.3, 0.5, 0.3), Error);
  EXPECT_THROW(
      hertz_mindlin_parameters(HertzBody{kInfinity, 0.2, 0.01, 1.0}, HertzBody{kInfinity, 0.2, 0.01, 1.0}, 0.5, 0.3),
      Error);
}

TEST(HertzMindlin, D1Test1TwoGlassSpheres) {
  const HertzMindlin law = hertz_mindlin_parameters(kGlass, kGlass, 1.0, 0.0);
  check_impact(law, kGlass.mass, kGlass.mass, 10.0, 10.0, HertzImpact{0.274e-3, 10.70e3, 40.3e-6});
}

TEST(HertzMindlin, D1Test2AluminiumSphereOnRigidWall) {
  const HertzMindlin law = hertz_mindlin_wall_parameters(kAluminium, kInfinity, 0.3, 1.0, 0.0);
  check_impact(law, kAluminium.mass, kInfinity, 0.2, 0.0, HertzImpact{49.3e-6, 11.47e3, 0.726e-3});
}

TEST(HertzMindlin, RestitutionWithDampingOnWall) {
  for (const double e : {0.5, 0.9}) {
    const HertzMindlin law = hertz_mindlin_wall_parameters(kAluminium, kInfinity, 0.3, e, 0.0);
    const double dt = analytic_hertz_impact(law, 0.2).contact_time / 2000.0;
    const MeasuredImpact measured = simulate_impact(law, kAluminium.mass, kInfinity, 0.2, 0.0, dt);
    std::cout << "e = " << e << ": ";
    expect_relative("rebound / impact speed", measured.restitution, e, kBenchmarkTolerance);
  }
}

TEST(HertzMindlin, NormalForceEnergyAndStableStep) {
  const HertzMindlin law = hertz_mindlin_parameters(kGlass, kGlass, 1.0, 0.3);
  TangentialHistory history;
  const double overlap = 1e-4;
  const ContactForce c = hertz_mindlin_force(law, overlap, Vec3::UnitZ(), Vec3::Zero(), 1e-7, history);
  // 4/3 * 25e9 * sqrt(0.005 * 1e-4^3) N; 2/5 of force * overlap J.
  const double force = 4.0 / 3.0 * 25e9 * std::sqrt(0.005 * 1e-12);
  expect_relative("normal force, N", c.normal_force, force, kTight);
  expect_relative("force z, N", c.force.z(), force, kTight);
  expect_relative("elastic energy, J", c.elastic_energy, 0.4 * force * overlap, kTight);
  // S_n = 2 * 25e9 * sqrt(0.005 * 1e-4); dt = 0.2 pi sqrt(m*/S_n).
  const double stiffness = 2.0 * 25e9 * std::sqrt(0.005 * 1e-4);
  expect_relative("stable dt, s", hertz_contact_stable_dt(law, overlap),
                  0.2 * std::numbers::pi * std::sqrt(law.effective_mass / stiffness), kTight);
  EXPECT_FALSE(c.sliding);
}

TEST(HertzMindlin, NormalDampingOpposesApproach) {
  const HertzMindlin law = hertz_mindlin_parameters(kGlass, kGlass, 0.5, 0.3);
  TangentialHistory history;
  const double overlap = 1e-4;
  const ContactForce c = hertz_mindlin_force(law, overlap, Vec3::UnitZ(), Vec3(0, 0, -2), 1e-7, history);
  const double log_e = std::log(0.5);
  const double beta = log_e / std::sqrt(log_e * log_e + std::numbers::pi * std::numbers::pi);
  const double stiffness = 2.0 * 25e9 * std::sqrt(0.005 * 1e-4);
  const double damping = -2.0 * std::sqrt(5.0 / 6.0) * beta * std::sqrt(stiffness * law.effective_mass);
  expect_relative("normal force, N", c.normal_force, 2.0 / 3.0 * stiffness * overlap + 2.0 * damping, kTight);
  expect_relative("dissipative force z, N", c.dissipative_force.z(), 2.0 * damping, kTight);
}

TEST(HertzMindlin, TangentialStickIsMindlinSpring) {
  const HertzMindlin law = hertz_mindlin_parameters(kGlass, kGlass, 1.0, 0.5);
  TangentialHistory history;
  const double overlap = 1e-4, dt = 1e-7;
  const Vec3 velocity(0.01, -0.02, 0);  // m/s, tangential
  ContactForce c;
  for (int step = 0; step < 100; ++step) c = hertz_mindlin_force(law, overlap, Vec3::UnitZ(), velocity, dt, history);
  // S_t = 8 G* sqrt(R* delta), G* = 48e9 / 8.64; displacement = v * 100 dt.
  const double stiffness = 8.0 * 48e9 / 8.64 * std::sqrt(0.005 * 1e-4);
  const Vec3 expected = -stiffness * velocity * (100 * dt);
  std::cout << "stick tangential force: measured (" << c.force.head<2>().transpose() << ") expected ("
            << expected.head<2>().transpose() << ")\n";
  EXPECT_LE((c.force - c.normal_force * Vec3::UnitZ() - expected).norm(), kTight * expected.norm());
  EXPECT_FALSE(c.sliding);
  EXPECT_LT(expected.norm(), 0.5 * c.normal_force);  // really below the Coulomb limit
  expect_relative("elastic energy, J", c.elastic_energy,
                  0.4 * c.normal_force * overlap + 0.5 * stiffness * (velocity * 100 * dt).squaredNorm(), kTight);
}

TEST(HertzMindlin, TangentialSlipIsCappedAtCoulomb) {
  const double mu = 0.3;
  const HertzMindlin law = hertz_mindlin_parameters(kGlass, kGlass, 1.0, mu);
  TangentialHistory history;
  const double overlap = 1e-4, dt = 1e-7;
  const Vec3 velocity(1.0, 0, 0);  // m/s: 100 um in 1000 steps, 4x past the limit
  ContactForce c;
  for (int step = 0; step < 1000; ++step) c = hertz_mindlin_force(law, overlap, Vec3::UnitZ(), velocity, dt, history);
  const double stiffness = 8.0 * 48e9 / 8.64 * std::sqrt(0.005 * 1e-4);
  EXPECT_TRUE(c.sliding);
  expect_relative("sliding force x, N", c.force.x(), -mu * c.normal_force, kTight);
  expect_relative("spring length (shortened), m", history.displacement.norm(), mu * c.normal_force / stiffness, kTight);
  // Losing contact clears the spring.
  c = hertz_mindlin_force(law, -1e-6, Vec3::UnitZ(), velocity, dt, history);
  EXPECT_EQ(c.force, Vec3::Zero());
  EXPECT_EQ(history.displacement, Vec3::Zero());
}

}  // namespace
}  // namespace sabo::physics
