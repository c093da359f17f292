// Spring-dashpot contact law and rolling resistance against hand-computed values.
#include <gtest/gtest.h>

#include <iostream>

#include "libsabo/physics/contact_law.hpp"
#include "tests/support/measure.hpp"

namespace sabo::physics {
namespace {

constexpr double kTight = 1e-12;

using sabo::testing::expect_scaled;
using sabo::testing::expect_vec_scaled;

TEST(ContactLaw, DampingCoefficientIsTwoZetaSqrtKm) {
  // 2 * 0.5 * sqrt(100 * 4) = 20 N s/m
  expect_scaled("c", damping_coefficient(100.0, 4.0, 0.5), 20.0, kTight);
}

TEST(ContactLaw, NormalSpringAndDashpot) {
  const SpringDashpot law{1000.0, 10.0, 0.0, 0.0, 0.5};
  TangentialHistory history;
  // Approaching at 2 m/s with 10 mm overlap: F = 1000 * 0.01 + 10 * 2 = 30 N.
  ContactForce c = spring_dashpot_force(law, 0.01, Vec3::UnitZ(), Vec3(0, 0, -2), 1e-3, history);
  expect_vec_scaled("approaching force", c.force, Vec3(0, 0, 30), kTight);
  expect_scaled("approaching normal force", c.normal_force, 30.0, kTight);
  expect_scaled("elastic energy", c.elastic_energy, 0.5 * 1000 * 0.01 * 0.01, kTight);
  expect_vec_scaled("dissipative force", c.dissipative_force, Vec3(0, 0, 20), kTight);
  EXPECT_FALSE(c.sliding);
  // Separating at 3 m/s with 1 mm overlap: F = 1 - 30 = -29 N, not clamped at zero.
  c = spring_dashpot_force(law, 0.001, Vec3::UnitZ(), Vec3(0, 0, 3), 1e-3, history);
  expect_vec_scaled("separating force (unclamped)", c.force, Vec3(0, 0, -29), kTight);
  // The law follows the given normal, not the z axis.
  const Vec3 n = Vec3(1, 2, 2) / 3.0;
  c = spring_dashpot_force(law, 0.01, n, -2.0 * n, 1e-3, history);
  expect_vec_scaled("oblique normal force", c.force, 30.0 * n, kTight);
}

TEST(ContactLaw, TangentialSpringSticks) {
  // k_n 1000, k_t 500, c_t 5, mu 0.5: F_n = 10 N, Coulomb limit 5 N.
  const SpringDashpot law{1000.0, 0.0, 500.0, 5.0, 0.5};
  TangentialHistory history;
  // v_t = 0.1 m/s over 10 ms: spring 1 mm; F_t = -500 * 0.001 - 5 * 0.1 = -1 N.
  const ContactForce c = spring_dashpot_force(law, 0.01, Vec3::UnitZ(), Vec3(0.1, 0, 0), 0.01, history);
  expect_vec_scaled("stick force", c.force, Vec3(-1.0, 0, 10.0), kTight);
  expect_vec_scaled("spring", history.displacement, Vec3(0.001, 0, 0), kTight);
  expect_scaled("elastic energy", c.elastic_energy, 0.05 + 0.5 * 500 * 1e-6, kTight);
  expect_vec_scaled("dissipative force (stick: dashpot)", c.dissipative_force, Vec3(-0.5, 0, 0), kTight);
  EXPECT_FALSE(c.sliding);
}

TEST(ContactLaw, TangentialSlipCapsAtCoulombAndResetsSpring) {
  const SpringDashpot law{1000.0, 0.0, 500.0, 5.0, 0.5};
  TangentialHistory history{Vec3(0.005, 0, 0)};
  // Spring 5 mm + 1 m/s * 10 ms = 15 mm; trial F_t = -7.5 - 5 = -12.5 N > 5 N: slides at 5 N.
  const ContactForce c = spring_dashpot_force(law, 0.01, Vec3::UnitZ(), Vec3(1.0, 0, 0), 0.01, history);
  EXPECT_TRUE(c.sliding);
  expect_vec_scaled("slip force", c.force, Vec3(-5.0, 0, 10.0), kTight);
  // Reset: k_t |d| = mu F_n -> |d| = 10 mm along the slip.
  expect_vec_scaled("reset spring", history.displacement, Vec3(0.01, 0, 0), kTight);
  expect_vec_scaled("dissipative force (slip: Coulomb)", c.dissipative_force, Vec3(-5.0, 0, 0), kTight);
  // Spring 5 mm before, 10 mm after: it stored 1/2 * 500 * (1e-4 - 2.5e-5) more.
  expect_scaled("slip spring release", c.slip_spring_release, -0.5 * 500 * (1e-4 - 2.5e-5), kTight);
  expect_scaled("elastic energy", c.elastic_energy, 0.05 + 0.5 * 500 * 1e-4, kTight);
}

TEST(ContactLaw, SlipCausedByTheDashpotKeepsTheSpring) {
  const SpringDashpot law{1000.0, 0.0, 500.0, 5.0, 0.5};
  TangentialHistory history;
  // Spring 0 + 2 m/s * 1 ms = 2 mm (1 N); dashpot 5 * 2 = 10 N; trial -11 N > 5 N: slides at 5 N,
  // the spring is not stretched to 10 mm (that would store 25 mJ no work paid for).
  const ContactForce c = spring_dashpot_force(law, 0.01, Vec3::UnitZ(), Vec3(2.0, 0, 0), 0.001, history);
  EXPECT_TRUE(c.sliding);
  expect_vec_scaled("slip force", c.force, Vec3(-5.0, 0, 10.0), kTight);
  expect_vec_scaled("kept spring", history.displacement, Vec3(0.002, 0, 0), kTight);
  expect_vec_scaled("dissipative force (slip: Coulomb)", c.dissipative_force, Vec3(-5.0, 0, 0), kTight);
}

TEST(ContactLaw, NoFrictionWhenTheDashpotPullsTogether) {
  const SpringDashpot law{1000.0, 10.0, 500.0, 0.0, 0.5};
  TangentialHistory history{Vec3(0.002, 0, 0)};
  // F_n = 1 - 30 = -29 N: no Coulomb force, spring reset to zero.
  const ContactForce c = spring_dashpot_force(law, 0.001, Vec3::UnitZ(), Vec3(1, 0, 3), 0.01, history);
  EXPECT_TRUE(c.sliding);
  expect_vec_scaled("force", c.force, Vec3(0, 0, -29), kTight);
  expect_vec_scaled("spring", history.displacement, Vec3::Zero(), kTight);
  expect_scaled("slip spring release (all of it)", c.slip_spring_release, 0.5 * 500 * 0.002 * 0.002, kTight);
}

TEST(ContactLaw, HistoryIsRotatedOntoTheTangentPlaneWithItsLength) {
  const SpringDashpot law{1000.0, 0.0, 500.0, 0.0, 0.5};
  // |d| = 5 mm, partly along the new normal z: becomes 5 mm along x.
  TangentialHistory history{Vec3(0.003, 0, 0.004)};
  const ContactForce c = spring_dashpot_force(law, 0.01, Vec3::UnitZ(), Vec3::Zero(), 0.01, history);
  expect_vec_scaled("rotated spring", history.displacement, Vec3(0.005, 0, 0), kTight);
  expect_vec_scaled("force", c.force, Vec3(-2.5, 0, 10.0), kTight);
  // A spring exactly along the new normal has no tangent direction left: dropped.
  TangentialHistory along_normal{Vec3(0, 0, 0.004)};
  spring_dashpot_force(law, 0.01, Vec3::UnitZ(), Vec3::Zero(), 0.01, along_normal);
  expect_vec_scaled("spring along the normal", along_normal.displacement, Vec3::Zero(), kTight);
}

TEST(ContactLaw, RollingResistanceIsAConstantTorqueAgainstTheRelativeSpin) {
  // mu_r 0.1, r_eff 0.5 m, F_n 100 N: 5 N m against w = (0, 2, 0).
  expect_vec_scaled("torque", rolling_resistance_torque(0.1, 0.5, 100.0, Vec3(0, 2, 0)), Vec3(0, -5, 0), kTight);
  expect_vec_scaled("torque, 100x faster spin", rolling_resistance_torque(0.1, 0.5, 100.0, Vec3(0, 200, 0)),
                    Vec3(0, -5, 0), kTight);
  expect_vec_scaled("torque at rest", rolling_resistance_torque(0.1, 0.5, 100.0, Vec3::Zero()), Vec3::Zero(), kTight);
  expect_vec_scaled("torque under tension", rolling_resistance_torque(0.1, 0.5, -100.0, Vec3(0, 2, 0)), Vec3::Zero(),
                    kTight);
}

TEST(ContactLaw, RollingSpringHoldsThenRollsAtTheConstantTorque) {
  // k_r = 2.25 * 1000 * 0.1^2 * 0.5^2 = 5.625 N m/rad
  expect_scaled("k_r", rolling_stiffness(1000.0, 0.1, 0.5), 5.625, kTight);
  const RollingSpring law{5.625, 0.5, 0.1, 0.5};  // cap at F_n = 100 N: 0.1 * 0.5 * 100 = 5 N m
  RollingHistory history;
  // w_rel (0, 2, 0) over 0.1 s: spring -1.125 N m, dashpot -1 N m, under the cap: holds.
  RollingTorque r = rolling_spring_torque(law, 100.0, Vec3(0, 2, 0), 0.1, history);
  EXPECT_FALSE(r.rolling);
  expect_vec_scaled("holding torque", r.torque, Vec3(0, -2.125, 0), kTight);
  expect_vec_scaled("spring", history.torque, Vec3(0, -1.125, 0), kTight);
  expect_scaled("elastic energy", r.elastic_energy, 1.125 * 1.125 / (2 * 5.625), kTight);
  expect_vec_scaled("dissipative torque (dashpot)", r.dissipative_torque, Vec3(0, -1, 0), kTight);
  // Another 0.5 s: spring -1.125 - 5.625 = -6.75 N m > 5: rolls at the cap, spring shortened to 5.
  r = rolling_spring_torque(law, 100.0, Vec3(0, 2, 0), 0.5, history);
  EXPECT_TRUE(r.rolling);
  expect_vec_scaled("rolling torque (constant torque)", r.torque,
                    rolling_resistance_torque(0.1, 0.5, 100.0, Vec3(0, 2, 0)), kTight);
  expect_vec_scaled("spring at the cap", history.torque, Vec3(0, -5, 0), kTight);
  expect_scaled("slip spring release", r.slip_spring_release, (1.125 * 1.125 - 25.0) / (2 * 5.625), kTight);
  // The rotation stops: the spring holds the torque, no reversal of the load direction.
  r = rolling_spring_torque(law, 100.0, Vec3::Zero(), 0.1, history);
  EXPECT_FALSE(r.rolling);
  expect_vec_scaled("torque at rest", r.torque, Vec3(0, -5, 0), kTight);
  // Tension: no rolling resistance, the spring is released.
  r = rolling_spring_torque(law, -1.0, Vec3::Zero(), 0.1, history);
  expect_vec_scaled("torque under tension", r.torque, Vec3::Zero(), kTight);
  expect_scaled("released", r.slip_spring_release, 25.0 / (2 * 5.625), kTight);
}

}  // namespace
}  // namespace sabo::physics
