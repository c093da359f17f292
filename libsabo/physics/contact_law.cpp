#include "libsabo/physics/contact_law.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace sabo::physics {

double damping_coefficient(double stiffness, double effective_mass, double damping_ratio) {
  assert(stiffness >= 0 && effective_mass >= 0 && damping_ratio >= 0);
  return 2.0 * damping_ratio * std::sqrt(stiffness * effective_mass);
}

TangentialForce tangential_spring_force(double stiffness, double damping, double friction, double normal_force,
                                        const Vec3& n, const Vec3& tangential_velocity, double dt_previous,
                                        TangentialHistory& history) {
  TangentialForce result;
  // Carry the spring over from the previous tangent plane: drop its normal part, keep its length.
  Vec3 displacement = history.displacement;
  const double length = displacement.norm();
  if (length > 0) {
    displacement -= displacement.dot(n) * n;
    const double projected_length = displacement.norm();
    displacement = projected_length > 0 ? Vec3(displacement * (length / projected_length)) : Vec3::Zero();
  }
  const double stored_energy = 0.5 * stiffness * displacement.squaredNorm();
  displacement += tangential_velocity * dt_previous;

  result.force = -stiffness * displacement - damping * tangential_velocity;
  const double coulomb_force = friction * std::max(normal_force, 0.0);
  const double trial_magnitude = result.force.norm();
  if (trial_magnitude > coulomb_force) {
    result.sliding = true;
    result.force *= coulomb_force / trial_magnitude;
    // Shorten the spring to the Coulomb force; never lengthen it (when the dashpot alone pushes
    // the contact over the limit, stretching the spring would store energy that no work paid for).
    const double spring_force = stiffness * displacement.norm();
    if (spring_force > coulomb_force) displacement *= coulomb_force / spring_force;
    result.slip_spring_release = stored_energy - 0.5 * stiffness * displacement.squaredNorm();
    result.dissipative = result.force;
  } else {
    result.dissipative = -damping * tangential_velocity;
  }
  history.displacement = displacement;
  return result;
}

ContactForce spring_dashpot_force(const SpringDashpot& law, double overlap, const Vec3& n,
                                  const Vec3& relative_velocity, double dt_previous, TangentialHistory& history) {
  ContactForce result;
  const double normal_speed = relative_velocity.dot(n);  // < 0 while approaching
  const Vec3 tangential_velocity = relative_velocity - normal_speed * n;

  result.normal_force = law.normal_stiffness * overlap - law.normal_damping * normal_speed;
  const TangentialForce tangential =
      tangential_spring_force(law.tangential_stiffness, law.tangential_damping, law.friction, result.normal_force, n,
                              tangential_velocity, dt_previous, history);
  result.sliding = tangential.sliding;
  result.slip_spring_release = tangential.slip_spring_release;
  result.dissipative_force = -law.normal_damping * normal_speed * n + tangential.dissipative;
  result.force = result.normal_force * n + tangential.force;
  result.elastic_energy = 0.5 * law.normal_stiffness * overlap * overlap +
                          0.5 * law.tangential_stiffness * history.displacement.squaredNorm();
  return result;
}

Vec3 rolling_resistance_torque(double rolling_friction, double effective_radius, double normal_force,
                               const Vec3& relative_angular_velocity) {
  // Below this relative spin (rad/s) the direction is noise: no torque.
  constexpr double kAtRest = 1e-12;
  const double speed = relative_angular_velocity.norm();
  const double magnitude = rolling_friction * effective_radius * std::max(normal_force, 0.0);
  if (!(speed > kAtRest) || magnitude == 0) return Vec3::Zero();
  return relative_angular_velocity * (-magnitude / speed);
}

double rolling_stiffness(double normal_stiffness, double rolling_friction, double effective_radius) {
  return 2.25 * normal_stiffness * rolling_friction * rolling_friction * effective_radius * effective_radius;
}

RollingTorque rolling_spring_torque(const RollingSpring& law, double normal_force,
                                    const Vec3& relative_angular_velocity, double dt_previous,
                                    RollingHistory& history) {
  RollingTorque result;
  const double cap = law.friction * law.effective_radius * std::max(normal_force, 0.0);
  if (!(law.stiffness > 0)) {
    history.torque.setZero();
    return result;
  }
  const double stored_energy = 0.5 * history.torque.squaredNorm() / law.stiffness;
  Vec3 spring = history.torque - (law.stiffness * dt_previous) * relative_angular_velocity;
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
  history.torque = spring;
  result.torque = torque;
  result.elastic_energy = 0.5 * spring.squaredNorm() / law.stiffness;
  return result;
}

}  // namespace sabo::physics
