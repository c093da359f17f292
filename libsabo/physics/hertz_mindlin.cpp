#include "libsabo/physics/hertz_mindlin.hpp"

#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "libsabo/core/error.hpp"
#include "libsabo/physics/stable_step.hpp"

namespace sabo::physics {
namespace {

// 2 sqrt(5/6): the restitution-damping prefactor of the Hertz-Mindlin DEM form.
const double kDampingPrefactor = 2.0 * std::sqrt(5.0 / 6.0);

void require(bool ok, const char* key, double value, const char* fix) {
  if (ok) return;
  throw Error("Hertz-Mindlin contact: " + std::string(key) + " = " + std::to_string(value) +
              " is not physical. Fix: " + fix);
}

void check_body(const HertzBody& body, const char* which) {
  const std::string prefix = std::string(which) + ".";
  require(body.youngs_modulus > 0, (prefix + "youngs_modulus").c_str(), body.youngs_modulus,
          "give a positive Young's modulus in Pa");
  require(body.poisson_ratio > -1 && body.poisson_ratio <= 0.5, (prefix + "poisson_ratio").c_str(), body.poisson_ratio,
          "give a Poisson ratio in (-1, 0.5]");
  require(body.radius > 0 && std::isfinite(body.radius), (prefix + "radius").c_str(), body.radius,
          "give a positive, finite radius in m");
  require(body.mass > 0 && std::isfinite(body.mass), (prefix + "mass").c_str(), body.mass,
          "give a positive, finite mass in kg");
}

void check_coefficients(double restitution, double friction) {
  require(restitution > 0 && restitution <= 1, "restitution", restitution,
          "give a coefficient of restitution in (0, 1]");
  require(friction >= 0 && std::isfinite(friction), "friction", friction, "give a finite friction coefficient >= 0");
}

// (1 - nu^2) / E; 0 for a rigid body (E = +infinity).
double normal_compliance(double youngs_modulus, double poisson_ratio) {
  return (1.0 - poisson_ratio * poisson_ratio) / youngs_modulus;
}

// 2 (2 - nu)(1 + nu) / E = (2 - nu) / G; 0 for a rigid body.
double shear_compliance(double youngs_modulus, double poisson_ratio) {
  return 2.0 * (2.0 - poisson_ratio) * (1.0 + poisson_ratio) / youngs_modulus;
}

}  // namespace

double hertz_effective_modulus(double youngs_a, double poisson_a, double youngs_b, double poisson_b) {
  return 1.0 / (normal_compliance(youngs_a, poisson_a) + normal_compliance(youngs_b, poisson_b));
}

double mindlin_effective_shear_modulus(double youngs_a, double poisson_a, double youngs_b, double poisson_b) {
  return 1.0 / (shear_compliance(youngs_a, poisson_a) + shear_compliance(youngs_b, poisson_b));
}

HertzMindlin hertz_mindlin_parameters(const HertzBody& a, const HertzBody& b, double restitution, double friction) {
  check_body(a, "body A");
  check_body(b, "body B");
  check_coefficients(restitution, friction);
  const double modulus = hertz_effective_modulus(a.youngs_modulus, a.poisson_ratio, b.youngs_modulus, b.poisson_ratio);
  // Two rigid bodies: no compliance, E* = +infinity.
  require(std::isfinite(modulus), "youngs_modulus (both)", a.youngs_modulus,
          "at most one body of a contact can be rigid");
  return HertzMindlin{
      modulus,
      a.radius * b.radius / (a.radius + b.radius),
      a.mass * b.mass / (a.mass + b.mass),
      mindlin_effective_shear_modulus(a.youngs_modulus, a.poisson_ratio, b.youngs_modulus, b.poisson_ratio),
      restitution,
      friction};
}

HertzMindlin hertz_mindlin_wall_parameters(const HertzBody& sphere, double wall_youngs_modulus,
                                           double wall_poisson_ratio, double restitution, double friction) {
  check_body(sphere, "sphere");
  require(wall_youngs_modulus > 0, "wall.youngs_modulus", wall_youngs_modulus,
          "give a positive Young's modulus in Pa (or infinity for a rigid wall)");
  require(wall_poisson_ratio > -1 && wall_poisson_ratio <= 0.5, "wall.poisson_ratio", wall_poisson_ratio,
          "give a Poisson ratio in (-1, 0.5]");
  check_coefficients(restitution, friction);
  return HertzMindlin{
      hertz_effective_modulus(sphere.youngs_modulus, sphere.poisson_ratio, wall_youngs_modulus, wall_poisson_ratio),
      sphere.radius,
      sphere.mass,
      mindlin_effective_shear_modulus(sphere.youngs_modulus, sphere.poisson_ratio, wall_youngs_modulus,
                                      wall_poisson_ratio),
      restitution,
      friction};
}

double restitution_damping_ratio(double restitution) {
  assert(restitution > 0 && restitution <= 1);
  const double log_e = std::log(restitution);
  return log_e / std::sqrt(log_e * log_e + std::numbers::pi * std::numbers::pi);
}

double hertz_damping_factor(double restitution) {
  return -kDampingPrefactor * restitution_damping_ratio(restitution);
}

double hertz_normal_stiffness(const HertzMindlin& law, double overlap) {
  return overlap > 0 ? 2.0 * law.effective_modulus * std::sqrt(law.effective_radius * overlap) : 0.0;
}

double mindlin_tangential_stiffness(const HertzMindlin& law, double overlap) {
  return overlap > 0 ? 8.0 * law.effective_shear_modulus * std::sqrt(law.effective_radius * overlap) : 0.0;
}

double hertz_contact_stable_dt(const HertzMindlin& law, double overlap) {
  if (!(overlap > 0)) return std::numeric_limits<double>::infinity();
  return spring_stable_dt(law.effective_mass, hertz_normal_stiffness(law, overlap));
}

ContactForce hertz_mindlin_force(const HertzMindlin& law, double overlap, const Vec3& n, const Vec3& relative_velocity,
                                 double dt_previous, TangentialHistory& history) {
  ContactForce result;
  if (!(overlap > 0)) {
    history.displacement.setZero();
    return result;
  }
  const double normal_speed = relative_velocity.dot(n);  // < 0 while approaching
  const Vec3 tangential_velocity = relative_velocity - normal_speed * n;
  const double normal_stiffness = hertz_normal_stiffness(law, overlap);
  const double tangential_stiffness = mindlin_tangential_stiffness(law, overlap);
  const double damping_factor = hertz_damping_factor(law.restitution);
  const double normal_damping = damping_factor * std::sqrt(normal_stiffness * law.effective_mass);
  const double tangential_damping = damping_factor * std::sqrt(tangential_stiffness * law.effective_mass);

  // 4/3 E* sqrt(R*) delta^{3/2} = 2/3 S_n delta.
  const double elastic_normal_force = (2.0 / 3.0) * normal_stiffness * overlap;
  result.normal_force = elastic_normal_force - normal_damping * normal_speed;

  const TangentialForce tangential =
      tangential_spring_force(tangential_stiffness, tangential_damping, law.friction, result.normal_force, n,
                              tangential_velocity, dt_previous, history);
  result.sliding = tangential.sliding;
  result.slip_spring_release = tangential.slip_spring_release;
  result.dissipative_force = -normal_damping * normal_speed * n + tangential.dissipative;

  result.force = result.normal_force * n + tangential.force;
  // 2/5 * 4/3 E* sqrt(R*) delta^{5/2} = 2/5 * elastic normal force * delta.
  result.elastic_energy =
      0.4 * elastic_normal_force * overlap + 0.5 * tangential_stiffness * history.displacement.squaredNorm();
  return result;
}

}  // namespace sabo::physics
