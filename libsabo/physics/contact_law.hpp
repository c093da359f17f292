#pragma once
// Contact laws shared by dem_solver (DEM-DEM) and the coupler (DEM-FEM):
// linear spring-dashpot with a tangential spring and a Coulomb limit, and a
// constant-torque rolling resistance (docs/model.md "DEM-DEM", paper eqs. 1-5).
// The parts a solver evaluates per contact per step (the tangential and the rolling
// spring, the dashpot coefficient) are inline: the DEM kernel calls them in its
// innermost loop.
#include <algorithm>
#include <cassert>
#include <cmath>

#include "libsabo/core/types.hpp"

namespace sabo::physics {

// One contact's parameters.
struct SpringDashpot {
  double normal_stiffness;      // k_n, N/m
  double normal_damping;        // c_n, N s/m
  double tangential_stiffness;  // k_t, N/m
  double tangential_damping;    // c_t, N s/m
  double friction;              // Coulomb mu, >= 0
};

// c = 2 zeta sqrt(k m_eff): critical-damping fraction zeta -> dashpot coefficient, N s/m.
[[nodiscard]] inline double damping_coefficient(double stiffness, double effective_mass, double damping_ratio) {
  assert(stiffness >= 0 && effective_mass >= 0 && damping_ratio >= 0);
  return 2.0 * damping_ratio * std::sqrt(stiffness * effective_mass);
}

// Accumulated tangential spring elongation of one contact, m.
struct TangentialHistory {
  Vec3 displacement = Vec3::Zero();
};

struct ContactForce {
  Vec3 force = Vec3::Zero();  // on body A, N (B receives -force)
  double normal_force = 0;    // signed normal component along n, N (positive = repulsive)
  double elastic_energy = 0;  // J stored in normal + tangential springs
  bool sliding = false;
  // Energy bookkeeping (not needed to apply the force). dissipative_force, N: the part of
  // `force` that dissipates: the dashpots, or when sliding the normal dashpot plus the whole
  // (Coulomb) tangential force; the power it takes from the bodies is
  // -dissipative_force . relative_velocity. slip_spring_release, J: when sliding, the
  // tangential spring's energy at the start of this call minus at its end (signed; > 0 when
  // the spring relaxes, e.g. all of it when the contact goes tensile). Energy dissipated over a
  // step of length dt: -dissipative_force . v dt + slip_spring_release.
  Vec3 dissipative_force = Vec3::Zero();
  double slip_spring_release = 0;
};

// Linear spring-dashpot with tangential spring and Coulomb limit (paper eqs. 1-5).
// n: unit normal pointing from B to A; overlap > 0 in contact; relative_velocity: velocity of
// A's contact point minus B's; dt_previous: the step that moved the bodies from the previous
// positions to the current ones (the history is incremented by v_t * dt_previous, after being
// rotated onto the current tangent plane with its length kept). The normal force is NOT
// clamped at zero (the D2 restitution formula is the unclamped oscillator's). On sliding
// (|trial tangential force| > Coulomb force) the force is capped at the Coulomb force along the
// trial force, and a spring longer than the limit is reset so that k_t * |displacement| equals
// the Coulomb force (docs/model.md, SPH–FEM: "slipping shortens the spring"); a shorter spring (the dashpot pushed the
// contact over the limit) is kept as it is: the reset never stores energy.
// The Coulomb limit is mu * max(normal_force, 0): a contact that its dashpot pulls together
// (normal_force < 0, at the end of an unclamped damped impact) carries no friction.
ContactForce spring_dashpot_force(const SpringDashpot& law, double overlap, const Vec3& n,
                                  const Vec3& relative_velocity, double dt_previous, TangentialHistory& history);

// The tangential part of a contact law, shared by spring_dashpot_force, hertz_mindlin_force and the
// DEM kernel: the spring displacement `history` is rotated onto the tangent plane of n (length kept)
// and extended by tangential_velocity * dt_previous; the trial force -stiffness d - damping v_t is
// capped at friction * max(normal_force, 0) as spring_dashpot_force describes (the spring is
// shortened to the limit, never lengthened). `history` is updated.
struct TangentialForce {
  Vec3 force = Vec3::Zero();        // on A, N
  Vec3 dissipative = Vec3::Zero();  // N: -damping v_t, or the capped force when sliding
  bool sliding = false;
  double slip_spring_release = 0;  // J, as in ContactForce
};
inline TangentialForce tangential_spring_force(double stiffness, double damping, double friction, double normal_force,
                                               const Vec3& n, const Vec3& tangential_velocity, double dt_previous,
                                               Vec3& history) {
  TangentialForce result;
  Vec3 displacement = history;
  // Carry the spring over from the previous tangent plane: drop its normal part, keep its length.
  const double length_squared = displacement.squaredNorm();
  if (length_squared > 0) {
    displacement -= displacement.dot(n) * n;
    const double projected_squared = displacement.squaredNorm();
    displacement =
        projected_squared > 0 ? Vec3(displacement * std::sqrt(length_squared / projected_squared)) : Vec3::Zero();
  }
  const double stored_energy = 0.5 * stiffness * displacement.squaredNorm();
  displacement += tangential_velocity * dt_previous;
  result.force = -stiffness * displacement - damping * tangential_velocity;
  const double coulomb_force = friction * std::max(normal_force, 0.0);
  const double trial_squared = result.force.squaredNorm();
  if (trial_squared > coulomb_force * coulomb_force) {
    result.sliding = true;
    result.force *= coulomb_force / std::sqrt(trial_squared);
    // Shorten the spring to the Coulomb force; never lengthen it (when the dashpot alone pushes
    // the contact over the limit, stretching the spring would store energy that no work paid for).
    const double spring_force = stiffness * displacement.norm();
    if (spring_force > coulomb_force) displacement *= coulomb_force / spring_force;
    result.slip_spring_release = stored_energy - 0.5 * stiffness * displacement.squaredNorm();
    result.dissipative = result.force;
  } else {
    result.dissipative = -damping * tangential_velocity;
  }
  history = displacement;
  return result;
}
inline TangentialForce tangential_spring_force(double stiffness, double damping, double friction, double normal_force,
                                               const Vec3& n, const Vec3& tangential_velocity, double dt_previous,
                                               TangentialHistory& history) {
  return tangential_spring_force(stiffness, damping, friction, normal_force, n, tangential_velocity, dt_previous,
                                 history.displacement);
}

// Constant-torque rolling resistance: torque on A = -mu_r * r_eff * |F_n| * w_rel/|w_rel|
// (zero if w_rel ~ 0). relative_angular_velocity = w_A - w_B, rad/s; B receives -torque.
// |F_n| is the compressive part max(normal_force, 0), as for the Coulomb limit. The torque
// is constant, so an explicit step can reverse a slow relative rotation (chatter) and cannot
// hold a sphere still under a smaller driving torque; rolling_spring_torque has neither issue.
Vec3 rolling_resistance_torque(double rolling_friction, double effective_radius, double normal_force,
                               const Vec3& relative_angular_velocity);

// Elastic-plastic rolling resistance (Ai, Chen, Rotter & Ooi 2011, "model C"): a rolling
// spring whose torque is capped at the constant torque mu_r * r_eff * max(F_n, 0). While a
// relative rotation goes on, the spring stays at the cap: the torque is then the constant
// torque of rolling_resistance_torque, against the accumulated rotation. Near rest the spring
// holds (like the tangential spring under the Coulomb limit), so a sphere at rest neither
// chatters nor creeps under a driving torque below the cap. It resists the whole relative
// rotation w_A - w_B (rolling and twisting), as the constant-torque law does.
struct RollingSpring {
  double stiffness;         // k_r, N m/rad (see rolling_stiffness)
  double damping;           // c_r, N m s/rad: dashpot acting while the spring holds
  double friction;          // mu_r, dimensionless, >= 0
  double effective_radius;  // r_eff = r_A r_B / (r_A + r_B), m
};

// k_r = 2.25 k_n mu_r^2 r_eff^2 (Iwashita & Oda 1998, as used by Ai et al. 2011): the spring
// reaches the cap after a relative rotation of overlap / (2.25 mu_r r_eff) rad.
[[nodiscard]] inline double rolling_stiffness(double normal_stiffness, double rolling_friction,
                                              double effective_radius) {
  return 2.25 * normal_stiffness * rolling_friction * rolling_friction * effective_radius * effective_radius;
}

// Accumulated rolling spring torque of one contact, on A, N m.
struct RollingHistory {
  Vec3 torque = Vec3::Zero();
};

struct RollingTorque {
  Vec3 torque = Vec3::Zero();  // on A, N m (B receives -torque)
  double elastic_energy = 0;   // J: |spring torque|^2 / (2 k_r)
  bool rolling = false;        // the torque is at the cap
  // Energy bookkeeping, as in ContactForce: the dashpot, or when rolling the whole torque;
  // power -dissipative_torque . w_rel; spring energy released by the cap, J.
  Vec3 dissipative_torque = Vec3::Zero();
  double slip_spring_release = 0;
};

// The spring `spring_torque` is incremented by -k_r * w_rel * dt_previous, the dashpot adds
// -c_r * w_rel; when the sum exceeds the cap it is scaled to the cap and a spring beyond the cap is
// shortened to it (never lengthened). k_r = 0 (no rolling friction) clears the spring.
inline RollingTorque rolling_spring_torque(const RollingSpring& law, double normal_force,
                                           const Vec3& relative_angular_velocity, double dt_previous,
                                           Vec3& spring_torque) {
  RollingTorque result;
  if (!(law.stiffness > 0)) {
    spring_torque.setZero();
    return result;
  }
  const double cap = law.friction * law.effective_radius * std::max(normal_force, 0.0);
  const double stored_energy = 0.5 * spring_torque.squaredNorm() / law.stiffness;
  Vec3 spring = spring_torque - (law.stiffness * dt_previous) * relative_angular_velocity;
  const Vec3 dashpot = -law.damping * relative_angular_velocity;
  Vec3 torque = spring + dashpot;
  const double magnitude = torque.norm();
  if (magnitude > cap) {
    result.rolling = true;
    torque = magnitude > 0 ? Vec3(torque * (cap / magnitude)) : Vec3::Zero();
    const double spring_magnitude = spring.norm();
    if (spring_magnitude > cap) spring *= cap / spring_magnitude;
    result.dissipative_torque = torque;
    result.slip_spring_release = stored_energy - 0.5 * spring.squaredNorm() / law.stiffness;
  } else {
    result.dissipative_torque = dashpot;
  }
  spring_torque = spring;
  result.torque = torque;
  result.elastic_energy = 0.5 * spring.squaredNorm() / law.stiffness;
  return result;
}
inline RollingTorque rolling_spring_torque(const RollingSpring& law, double normal_force,
                                           const Vec3& relative_angular_velocity, double dt_previous,
                                           RollingHistory& history) {
  return rolling_spring_torque(law, normal_force, relative_angular_velocity, dt_previous, history.torque);
}

}  // namespace sabo::physics
