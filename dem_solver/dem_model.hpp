#pragma once
// The physics of dem_solver: DEM spheres with DEM-DEM contacts (MODEL.md
// "DEM-DEM"), gravity and forces received from the coupler. No protocol here.
//
// Step contract (central difference, DESIGN.md §2). The state at step n is
// positions x_n and half-step velocities v_{n-1/2}, w_{n-1/2} (at step 0 the
// initial v_0, w_0). One step, in this order:
//   compute_internal_forces(dt_{n-1})   contact forces and torques at x_n, using
//                                       v_{n-1/2}; gravity; contact histories
//                                       advanced by v_t * dt_{n-1} (0 at step 0)
//   add_external_forces(...)            coupler forces/torques, any number of calls
//                                       (before or after the internal forces)
//   integrate(dt_{n-1}, dt_n)           v_{n+1/2} = v_{n-1/2} + dt_avg F/m,
//                                       w_{n+1/2} = w_{n-1/2} + dt_avg T/I (I = 2/5 m r^2),
//                                       x_{n+1} = x_n + dt_n v_{n+1/2},
//                                       dt_avg = (dt_{n-1} + dt_n)/2, or dt_n/2 at step 0;
//                                       then forces and torques are cleared.
// Angular positions are not tracked (spheres). Fixed spheres (set_fixed) take
// part in contacts with infinite mass and never move.
//
// Ids: a sphere's index is its global id, stable for the whole run: particle
// sets in scene order, within a set the listed order (list) or placement order
// (fill: largest first).
//
// Rolling resistance: the constant torque mu_r r_eff F_n of the paper, as the cap
// of an elastic-plastic rolling spring (physics::rolling_spring_torque, Ai et al.
// 2011 "model C", k_r = 2.25 k_n mu_r^2 r_eff^2, dashpot with the tangential
// damping ratio and the pair's reduced moment of inertia). While spheres roll on
// each other the torque is the constant torque against the rotation; at rest
// the spring holds, so a resting pile neither chatters (a bare constant torque
// reverses slow rotations within a step) nor creeps (a constant torque limited
// so as not to reverse them cannot hold a sphere against a driving torque).
//
// Determinism: contacts are found on a cell list and computed once per pair
// (pairs ordered by ids); each sphere sums its own contacts in pair order; all
// reductions are serial. Same input, same bits, for any number of threads.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/physics/cell_list.hpp"
#include "libsabo/physics/contact_law.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::dem {

struct Energies {
  double kinetic = 0;     // J, translational + rotational, at step n: 1/2 m v_{n-1/2}.v_{n+1/2} (+ rotation)
  double potential = 0;   // J, gravitational, -m g.x_n (zero at x = 0; fixed spheres left out)
  double elastic = 0;     // J, springs of the DEM-DEM contacts at x_n
  double dissipated = 0;  // J, accumulated through step n by dashpots, sliding and rolling resistance
                          //    (impulse of their forces times the mean relative velocity over the step,
                          //    plus the spring energy released by slip and by contacts that open)
  [[nodiscard]] double total() const { return kinetic + potential + elastic; }
};

// One DEM-DEM contact's springs, for checkpoints. a < b are sphere ids.
struct ContactRecord {
  std::uint32_t a = 0, b = 0;
  Vec3 tangential_displacement = Vec3::Zero();  // m
  Vec3 rolling_torque = Vec3::Zero();           // N m, on a
};

class DemModel {
 public:
  // Builds every particle set of the scene (fills regions with the set's seed).
  // Throws SceneError if a fill set does not fit or two spheres overlap (by more than 1e-6 of
  // their radii's sum, the round-off of touching spheres written in decimal).
  explicit DemModel(const scene::Scene& scene);

  [[nodiscard]] std::size_t size() const { return radius_.size(); }

  // Structure-of-arrays state, indexed by sphere id.
  [[nodiscard]] std::span<const Vec3> positions() const { return position_; }       // m, x_n
  [[nodiscard]] std::span<const Vec3> velocities() const { return velocity_; }      // m/s, v_{n-1/2}
  [[nodiscard]] std::span<const Vec3> angular_velocities() const { return spin_; }  // rad/s, w_{n-1/2}
  [[nodiscard]] std::span<Vec3> positions() { return position_; }                   // for restarts
  [[nodiscard]] std::span<Vec3> velocities() { return velocity_; }
  [[nodiscard]] std::span<Vec3> angular_velocities() { return spin_; }
  [[nodiscard]] std::span<const double> radii() const { return radius_; }                    // m
  [[nodiscard]] std::span<const double> masses() const { return mass_; }                     // kg
  [[nodiscard]] std::span<const std::uint32_t> material_index() const { return material_; }  // into Scene::materials
  [[nodiscard]] std::span<const std::uint32_t> body_index() const { return body_; }  // into Scene::particle_sets
  [[nodiscard]] const std::vector<std::string>& body_names() const { return body_names_; }
  // Force (N) and torque (N m) accumulated since the last integrate(); fixed spheres get no
  // gravity (their force is the load on them).
  [[nodiscard]] std::span<const Vec3> forces() const { return force_; }
  [[nodiscard]] std::span<const Vec3> torques() const { return torque_; }

  // A fixed sphere keeps its position, has zero velocity and infinite mass in contacts.
  void set_fixed(std::uint32_t id, bool fixed);
  [[nodiscard]] bool is_fixed(std::uint32_t id) const { return fixed_[id] != 0; }

  // See the step contract above.
  void compute_internal_forces(double dt_previous);
  // force and torque: 3 doubles (x, y, z) per listed id; torque may be empty (no torques).
  // Forces on fixed spheres are ignored. Throws ProtocolError on a size mismatch or an unknown id.
  void add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force,
                           std::span<const double> torque);
  void integrate(double dt_previous, double dt);

  // Paper eq. 7's DEM term without beta: 0.2 pi sqrt(m_min / k_max), s; m_min the
  // lightest free sphere, k_max the stiffest pair the sphere sizes allow, in which
  // the tangential spring counts as 3.5 k_t (its contact point also turns the spheres) and
  // the rolling spring as 5.625 mu_r^2 k_n (the largest k_r / I relative to k_n / m).
  // Infinity when no sphere is free.
  [[nodiscard]] double stable_dt() const;

  // Energies at the step of the last integrate() (before any: the initial state).
  [[nodiscard]] Energies energies() const { return energies_; }

  // Box around all spheres (centres inflated by their radii); empty when there are none.
  [[nodiscard]] Aabb bounds() const;

  // DEM-DEM contacts found by the last compute_internal_forces().
  [[nodiscard]] std::size_t contact_count() const { return pair_a_.size(); }
  // Contact histories for checkpoints, ordered by (a, b); restore before the
  // next compute_internal_forces(), together with positions and velocities.
  [[nodiscard]] std::vector<ContactRecord> contact_histories() const;
  void restore(std::span<const ContactRecord> contacts, double dissipated_energy);

  // The contact laws of a pair (stiffness from the scene, damping from the ratios).
  [[nodiscard]] physics::SpringDashpot contact_law(std::uint32_t a, std::uint32_t b) const;
  [[nodiscard]] physics::RollingSpring rolling_law(std::uint32_t a, std::uint32_t b) const;

 private:
  void find_contacts();
  void compute_pair_forces(double dt_previous);
  void build_adjacency();
  [[nodiscard]] double normal_stiffness(std::uint32_t a, std::uint32_t b) const;
  [[nodiscard]] double inverse_inertia(std::uint32_t id) const;

  scene::DemContact settings_;
  Vec3 gravity_;
  std::vector<std::string> body_names_;
  std::vector<double> material_bulk_modulus_;  // Pa, per material

  // Per sphere.
  std::vector<Vec3> position_, velocity_, spin_, force_, torque_;
  std::vector<double> radius_, mass_;
  std::vector<std::uint32_t> material_, body_;
  std::vector<std::uint8_t> fixed_;
  double largest_radius_ = 0;

  // Per contact pair (a < b), ordered by (a, b).
  physics::CellList cells_;
  std::vector<std::uint32_t> contact_count_, contact_offset_;  // per sphere: pairs where it is a
  std::vector<std::uint32_t> pair_a_, pair_b_;
  struct PairHistory {
    physics::TangentialHistory tangential;
    physics::RollingHistory rolling;
  };
  std::vector<PairHistory> pair_history_;
  std::vector<std::uint64_t> previous_key_;  // the pairs of the last force evaluation, sorted
  std::vector<PairHistory> previous_history_;
  std::vector<Vec3> pair_force_;                     // on a, N
  std::vector<Vec3> pair_torque_a_, pair_torque_b_;  // N m: contact force and rolling resistance
  std::vector<Vec3> pair_relative_spin_;             // w_a - w_b at step n (w_{n-1/2}), rad/s
  std::vector<Vec3> pair_relative_velocity_;         // of the contact points, a minus b, m/s
  std::vector<Vec3> pair_arm_a_, pair_arm_b_;        // centre to contact point, m
  std::vector<Vec3> pair_dissipative_force_;         // on a, N
  std::vector<Vec3> pair_dissipative_torque_;        // on a, N m (rolling)
  std::vector<double> pair_elastic_, pair_dissipated_power_, pair_slip_release_;  // J, W, J
  // Per sphere, the pairs it belongs to (as a or b), in pair order.
  std::vector<std::uint32_t> adjacency_start_, adjacency_pair_;

  // Below this many spheres the loops run serially: a parallel region costs more than the work.
  static constexpr std::size_t kParallelThreshold = 256;
  bool parallel_ = false;

  // Step bookkeeping.
  bool forces_ready_ = false;
  double step_elastic_ = 0, step_slip_release_ = 0;
  double step_released_energy_ = 0;  // J, springs of the contacts that opened
  std::vector<double> sphere_kinetic_, sphere_potential_;
  Energies energies_;
};

}  // namespace sabo::dem
