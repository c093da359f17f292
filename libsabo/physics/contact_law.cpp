#include "libsabo/physics/contact_law.hpp"

#include <algorithm>
#include <cmath>

namespace sabo::physics {

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

}  // namespace sabo::physics
