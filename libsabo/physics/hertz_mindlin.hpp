#pragma once
// Hertz-Mindlin (no-slip) contact law: Hertz normal spring, Mindlin no-slip tangential spring,
// restitution-based dashpots (the usual DEM form, as in LIGGGHTS / EDEM) and a Coulomb limit.
// Same conventions as spring_dashpot_force in contact_law.hpp (benchmark D1).
#include "libsabo/core/types.hpp"
#include "libsabo/physics/contact_law.hpp"

namespace sabo::physics {

// Effective parameters of one contact pair.
struct HertzMindlin {
  double effective_modulus;        // E*, Pa: 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2
  double effective_radius;         // R*, m: 1/R* = 1/R1 + 1/R2 (a wall: R2 = infinity)
  double effective_mass;           // m*, kg: m1 m2 / (m1 + m2) (a wall: m1)
  double effective_shear_modulus;  // G*, Pa: 1/G* = 2(2-nu1)(1+nu1)/E1 + 2(2-nu2)(1+nu2)/E2
  double restitution;              // e in (0, 1]; 1 = no damping
  double friction;                 // Coulomb mu, >= 0
};

// One body's material and size. youngs_modulus may be +infinity (rigid).
struct HertzBody {
  double youngs_modulus;  // E, Pa
  double poisson_ratio;   // nu, in (-1, 0.5]
  double radius;          // R, m
  double mass;            // m, kg
};

// Effective parameters of a sphere-sphere contact. Throws sabo::Error on a non-physical value
// (E <= 0, nu outside (-1, 0.5], R <= 0, m <= 0, e outside (0, 1], mu < 0).
HertzMindlin hertz_mindlin_parameters(const HertzBody& a, const HertzBody& b, double restitution, double friction);

// Effective parameters of a sphere-wall contact: the wall is flat (R = infinity) and immovable
// (m* = sphere mass); wall_youngs_modulus may be +infinity for a rigid wall.
HertzMindlin hertz_mindlin_wall_parameters(const HertzBody& sphere, double wall_youngs_modulus,
                                           double wall_poisson_ratio, double restitution, double friction);

// E* of two bodies, Pa: 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2 (E = +infinity: rigid, adds nothing).
double hertz_effective_modulus(double youngs_a, double poisson_a, double youngs_b, double poisson_b);

// G* of two bodies, Pa: 1/G* = 2(2-nu1)(1+nu1)/E1 + 2(2-nu2)(1+nu2)/E2 (E = +infinity adds nothing).
double mindlin_effective_shear_modulus(double youngs_a, double poisson_a, double youngs_b, double poisson_b);

// Damping ratio of the restitution: beta = ln(e) / sqrt(ln(e)^2 + pi^2) (<= 0; 0 for e = 1).
double restitution_damping_ratio(double restitution);

// Dashpot factor of the restitution: -2 sqrt(5/6) beta >= 0; a dashpot is factor * sqrt(S m*), N s/m.
double hertz_damping_factor(double restitution);

// Normal contact stiffness S_n = dF_n/d(delta) = 2 E* sqrt(R* delta), N/m.
double hertz_normal_stiffness(const HertzMindlin& law, double overlap);

// Mindlin no-slip tangential stiffness S_t = 8 G* sqrt(R* delta), N/m.
double mindlin_tangential_stiffness(const HertzMindlin& law, double overlap);

// Stable explicit step at a given overlap: 0.2 pi sqrt(m* / S_n(overlap)), s, i.e. a tenth of
// the period of the linear oscillator with the tangent stiffness there. Use the largest overlap
// expected (e.g. the analytic Hertz maximum of the fastest impact): S_n grows with the overlap,
// so this step shrinks with it. Returns +infinity for overlap <= 0.
double hertz_contact_stable_dt(const HertzMindlin& law, double overlap);

// Hertz-Mindlin no-slip force. n: unit normal from B to A; overlap > 0 in contact;
// relative_velocity: A's contact point minus B's; dt_previous: the step that moved the bodies to
// the current positions (the history displacement is rotated onto the current tangent plane with
// its length kept, then incremented by v_t * dt_previous).
//   Normal: F_n = 4/3 E* sqrt(R*) delta^{3/2} - c_n v_n, c_n = -2 sqrt(5/6) beta sqrt(S_n m*) >= 0,
//   not clamped at zero (like spring_dashpot_force).
//   Tangential: F_t = -S_t * displacement - c_t v_t, c_t = -2 sqrt(5/6) beta sqrt(S_t m*); the
//   total displacement is stored, so with a constant overlap the spring force is exactly
//   -S_t * accumulated displacement. Coulomb limit mu * max(F_n, 0): on sliding the force is capped
//   along the trial force and a spring longer than the limit is shortened to S_t |d| = mu F_n.
// elastic_energy = 8/15 E* sqrt(R*) delta^{5/2} + S_t |d|^2 / 2 (the tangential term uses the
// current S_t). dissipative_force and slip_spring_release as in ContactForce.
// overlap <= 0: no contact; zero force and the history is cleared.
ContactForce hertz_mindlin_force(const HertzMindlin& law, double overlap, const Vec3& n, const Vec3& relative_velocity,
                                 double dt_previous, TangentialHistory& history);

}  // namespace sabo::physics
