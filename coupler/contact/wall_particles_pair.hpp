#pragma once
// The SPH-FEM pair with sph.wall_model = "boundary_particles": the fem_solver's
// surface sampled as wall particles (BoundaryWalls) that the sph_solver
// includes in its sums (Adami, Hu & Adams 2012); the force the fluid put on
// them comes back in a later StepState and is spread onto the surface's nodes.
#include "coupler/contact/boundary_walls.hpp"
#include "coupler/contact/contact_pair.hpp"

namespace sabo::coupler {

class WallParticlesPair final : public ContactPair {
 public:
  explicit WallParticlesPair(const scene::Scene& scene);

  [[nodiscard]] std::string name() const override { return "sph_fem"; }
  [[nodiscard]] std::array<Role, 2> roles() const override { return {Role::sph, Role::fem}; }
  void start(const Solvers& solvers, Replies& replies) override;
  void check_state(const SolverView& solver) const override;
  void compute(const Solvers& solvers, const StepClock& clock) override;
  void scatter(const Solvers& solvers, double dt, Replies& replies) override;
  [[nodiscard]] InterestRequest interest(Role role) const override;
  [[nodiscard]] bool every_exchange() const override { return true; }
  [[nodiscard]] const physics::BoundaryParticles* boundary_particles() const override { return &walls_.selected(); }
  [[nodiscard]] NewtonBalance newton_balance() const override;
  // Not on a deformable structure: there the walls' acceleration enters their pressure (the fluid's added
  // mass), and that force held over several of the structure's steps feeds its vibration (C1 in
  // bench/RESULTS.md: the energy grew eightfold at two of its steps per exchange).
  [[nodiscard]] const Holding& holding() const override { return holding_; }
  [[nodiscard]] std::optional<std::string> load_source() const override { return "fluid"; }
  [[nodiscard]] std::span<const Vec3> loads() const override { return part_force_; }
  void want_point_loads() override { want_point_loads_ = true; }
  void point_loads(std::vector<PointLoad>& out) const override {
    out.insert(out.end(), point_loads_.begin(), point_loads_.end());
  }
  [[nodiscard]] nlohmann::json effect() const override;
  void save_history(io::hdf5::Group& group) const override;
  void restore_history(const io::hdf5::Group& group) override;

  [[nodiscard]] const BoundaryWalls& walls() const { return walls_; }

 private:
  BoundaryWalls walls_;
  Holding holding_;  // not allowed when a structure among the walls is deformable
  const BoundaryChannel* channel_ = nullptr;
  std::size_t slot_ = 0;
  std::span<const double> returned_;  // this step: the fluid's force on the walls of an earlier step
  bool want_point_loads_ = false;
  std::vector<PointLoad> point_loads_;  // of returned_, when wanted
  std::vector<double> node_force_;      // N, 3 per node, from returned_
  std::vector<Vec3> part_force_;        // N per part
  std::size_t max_sent_ = 0;            // most wall particles sent in one step
};

}  // namespace sabo::coupler
