#pragma once
// The SPH-DEM pair with model = "penalty": paper eqs. 1-2, the node-to-node
// penalty between a fluid particle i (contact radius h_i, its particle table's
// radius: dx/2 for Sabo's sph_solver) and a sphere j of radius r_j. Overlap
// delta = h_i + r_j - d > 0, n the unit vector from the sphere's centre to the
// particle; force on the particle
//   F = (K delta - eta v_rel.n) n  (+ a tangential spring k_t = K capped at mu |F_n| when friction > 0),
// v_rel the particle's velocity minus that of the sphere's surface point
// (v_j + w_j x r_j n), eta = 2 zeta sqrt(K m*) with m* the reduced mass; the
// sphere takes -F at r_j n (a torque from the tangential part only). K is the
// pair's normal_stiffness or Scene::sph_dem_derived_stiffness of the fluid body.
//
// This law carries no fluid pressure: a sphere feels the fluid only where
// particles touch it, so a sphere at rest in a tank sinks until enough
// particles are compressed under it, and buoyancy and drag are not the fluid's
// (docs/physics.md, "SPH-DEM").
//
// Stable step: 0.2 pi sqrt(m* / K) over the pairs within h_i + r_j + h_i
// (a particle is limited one contact radius before it touches), times the
// smaller beta of the two solvers.
//
// Deterministic: the fluid particles are processed in parallel, each on its
// own (its contacts in the order of the spheres' state index); the spheres'
// reactions are summed afterwards in particle order.
#include <vector>

#include "coupler/contact/contact_pair.hpp"
#include "libsabo/physics/cell_list.hpp"
#include "libsabo/physics/contact_law.hpp"

namespace sabo::coupler {

class SphDemPenaltyPair final : public ContactPair {
 public:
  explicit SphDemPenaltyPair(const scene::Scene& scene);

  [[nodiscard]] std::string name() const override { return "sph_dem"; }
  [[nodiscard]] std::array<Role, 2> roles() const override { return {Role::sph, Role::dem}; }
  void start(const Solvers& solvers, Replies& replies) override;
  void compute(const Solvers& solvers, const StepClock& clock) override;
  void scatter(const Solvers& solvers, double dt, Replies& replies) override;
  [[nodiscard]] InterestRequest interest(Role role) const override;
  [[nodiscard]] double stable_dt() const override { return stable_dt_; }
  [[nodiscard]] NewtonBalance newton_balance() const override { return balance_; }
  [[nodiscard]] Energy energy() const override { return {elastic_, dissipated_power_}; }
  [[nodiscard]] std::size_t contact_count() const override { return contacts_; }
  [[nodiscard]] nlohmann::json effect() const override;
  void save_history(io::hdf5::Group& group) const override;
  void restore_history(const io::hdf5::Group& group) override;

  // The law of (fluid body, particle set), as computed from the scene.
  struct Law {
    bool enabled = false;
    double stiffness = 0;      // N/m
    double damping_ratio = 0;  // zeta
    double friction = 0;
  };
  [[nodiscard]] const Law& law(std::uint32_t fluid_body, std::uint32_t set) const {
    return laws_[fluid_body * set_count_ + set];
  }

  // A tangential spring carried to the next step: (fluid particle id, sphere id).
  struct Spring {
    std::uint64_t fluid = 0, sphere = 0;
    Vec3 displacement = Vec3::Zero();
  };

 private:
  struct Contact {
    std::uint32_t sphere = 0;   // position in the DEM state
    Vec3 force = Vec3::Zero();  // on the fluid particle, N
    Vec3 lever = Vec3::Zero();  // r_j n: the sphere's contact point from its centre, m
    double elastic = 0, dissipated_power = 0;
    Vec3 tangential = Vec3::Zero();  // spring after this step (friction > 0)
    bool has_spring = false;
  };
  struct ParticleResult {
    std::vector<Contact> contacts;
    double stable_dt = 0;
  };

  std::vector<Law> laws_;  // [fluid body * sets + set]
  std::size_t set_count_ = 0;
  double beta_ = 1;
  double max_sphere_radius_ = 0, max_fluid_radius_ = 0;

  // This step.
  std::vector<ParticleResult> results_;
  std::vector<double> fluid_force_, sphere_force_, sphere_torque_;
  std::vector<Vec3> sphere_centre_;
  physics::CellList grid_;
  NewtonBalance balance_;
  double stable_dt_ = std::numeric_limits<double>::infinity();
  double elastic_ = 0, dissipated_power_ = 0;
  std::size_t contacts_ = 0, max_contacts_ = 0;
  std::vector<Spring> springs_, next_springs_;  // sorted by (fluid, sphere)
};

}  // namespace sabo::coupler
