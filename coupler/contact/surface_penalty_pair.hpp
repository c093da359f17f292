#pragma once
// Penalty contact of a particle solver's particles (DEM spheres, or SPH
// particles with sph.wall_model = "penalty") against the fem_solver's surface:
// the DEM-FEM pair and the penalty SPH-FEM pair (paper eqs. 3-6, or
// Hertz-Mindlin for spheres), on the contact::SurfaceContact kernel (libsabo/contact).
#include <memory>

#include "coupler/contact/contact_pair.hpp"
#include "coupler/contact/particle_gather.hpp"
#include "libsabo/contact/surface_contact.hpp"

namespace sabo::coupler {

class SurfacePenaltyPair final : public ContactPair {
 public:
  // particles: Role::dem (settings from [contact.dem_fem] and the interactions) or
  // Role::sph ([contact.sph_fem]).
  SurfacePenaltyPair(const scene::Scene& scene, Role particles);

  [[nodiscard]] std::string name() const override;
  [[nodiscard]] std::array<Role, 2> roles() const override { return {particles_, Role::fem}; }
  void start(const Solvers& solvers, Replies& replies) override;
  void compute(const Solvers& solvers, const StepClock& clock) override;
  void scatter(const Solvers& solvers, double dt, Replies& replies) override;
  [[nodiscard]] InterestRequest interest(Role role) const override;
  [[nodiscard]] double stable_dt() const override { return beta_ * contact_->stable_dt(); }
  [[nodiscard]] NewtonBalance newton_balance() const override;
  [[nodiscard]] Energy energy() const override { return {out_.elastic_energy, out_.dissipated_power}; }
  [[nodiscard]] std::optional<std::string> load_source() const override { return source_; }
  [[nodiscard]] std::span<const Vec3> loads() const override { return out_.part_force; }
  void point_loads(std::vector<PointLoad>& out) const override;
  [[nodiscard]] std::size_t contact_count() const override { return out_.contact_count; }
  [[nodiscard]] nlohmann::json effect() const override;
  void save_history(io::hdf5::Group& group) const override;
  void restore_history(const io::hdf5::Group& group) override;

  [[nodiscard]] const contact::SurfaceContact& contact() const { return *contact_; }

 private:
  // Warns (once per run) when a contact overlaps beyond half its face's edge.
  void warn_deep_overlap(double time);

  Role particles_;
  std::string source_;  // forces.csv: "particles" or "fluid"
  std::unique_ptr<contact::SurfaceContact> contact_;
  double beta_ = 1;  // of the particle solver: the contact limits its particles
  ParticleGather gather_;
  contact::ContactOutput out_;
  bool warned_deep_overlap_ = false;
};

}  // namespace sabo::coupler
