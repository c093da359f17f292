// dem_solver: DEM spheres coupled through the Sabo protocol.
//   dem_solver --scene FILE --coupler ENDPOINT [--out DIR]
// The physics is DemModel (dem_model.hpp); this file is the protocol side.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>

#include "dem_solver/dem_model.hpp"
#include "dem_solver/dem_output.hpp"
#include "libsabo/solver/driver.hpp"

namespace sabo::dem {
namespace {

class DemSolver final : public solver::CoupledSolver {
 public:
  DemSolver(const scene::Scene& scene, const solver::SolverOptions& options)
      : model_(scene), output_(options.out_dir, model_), limits_(solver::stability_limits(scene, Role::dem)) {
    spdlog::info("{} spheres in {} sets, stable dt {:.3e} s", model_.size(), scene.particle_sets.size(),
                 model_.stable_dt());
  }

  void describe(sabo::v1::Register& registration) override {
    registration.set_name("dem_solver " SABO_VERSION);
    registration.set_exposes_particles(true);
    registration.set_exposes_angular_velocity(true);
    auto* table = registration.mutable_particles();
    const auto n = model_.size();
    for (std::size_t i = 0; i < n; ++i) table->add_id(i);
    table->mutable_radius()->Assign(model_.radii().begin(), model_.radii().end());
    table->mutable_mass()->Assign(model_.masses().begin(), model_.masses().end());
    table->mutable_material()->Assign(model_.material_index().begin(), model_.material_index().end());
    table->mutable_body()->Assign(model_.body_index().begin(), model_.body_index().end());
  }

  double stable_dt() override { return model_.stable_dt(); }

  void fill_state(const solver::Interest& interest, sabo::v1::StepState& state) override {
    solver::add_particle_states(interest,
                                {.position = model_.positions(),
                                 .velocity = model_.velocities(),
                                 .angular_velocity = model_.angular_velocities()},
                                state);
    const Energies e = model_.energies();
    solver::set_energies(state, {e.kinetic, e.potential, e.elastic, e.dissipated});
  }

  void compute_internal_forces(double dt_previous) override { model_.compute_internal_forces(dt_previous); }

  void apply_coupling_forces(const sabo::v1::StepForces& forces) override {
    model_.add_external_forces({forces.index().data(), static_cast<std::size_t>(forces.index_size())},
                               {forces.force().data(), static_cast<std::size_t>(forces.force_size())},
                               {forces.torque().data(), static_cast<std::size_t>(forces.torque_size())});
  }

  [[nodiscard]] bool can_take_state() const override { return true; }
  void take_state(const sabo::v1::StepState& recorded) override {
    std::vector<Vec3> positions(model_.positions().begin(), model_.positions().end());
    solver::take_particle_states(recorded, positions, model_.velocities(), model_.angular_velocities());
    if (!recorded.position().empty()) model_.set_positions(positions);  // the neighbour list notices the move
  }

  void write_output(std::uint64_t step, double time) override { output_.write(step, time); }
  void integrate(double dt_previous, double dt) override { model_.integrate(dt_previous, dt); }
  [[nodiscard]] std::optional<solver::Instability> check_stability() const override {
    auto found = solver::check_motion(model_.positions(), model_.velocities(), {}, limits_.max_speed, "sphere");
    if (found) return found;
    // A spin that is not finite shows in the position only a step later.
    return solver::check_motion(model_.positions(), model_.angular_velocities(), {},
                                std::numeric_limits<double>::infinity(), "sphere (angular velocity)");
  }
  void write_instability(const solver::Instability& instability, const std::filesystem::path& file) const override {
    const auto radii = model_.radii();
    const double largest = radii.empty() ? 0.0 : *std::max_element(radii.begin(), radii.end());
    // Neighbours: the spheres that can touch a culprit.
    const std::pair<std::string, std::span<const double>> radius{"radius", radii};
    solver::write_instability(file, model_.positions(), model_.velocities(), instability, 4.0 * largest, {&radius, 1});
  }
  [[nodiscard]] std::uint32_t max_substeps() const override { return solver::kMaxSubsteps; }
  [[nodiscard]] bool can_checkpoint() const override { return true; }
  void save_checkpoint(io::hdf5::Group& group) const override {
    io::hdf5::Group model = group.create_group("model");
    model_.save_state(model);
    output_.save(group);
  }
  void load_checkpoint(const io::hdf5::Group& group) override {
    model_.load_state(group.group("model"));
    output_.load(group);
  }
  void finish() override { output_.close(); }

 private:
  DemModel model_;
  DemOutput output_;
  solver::StabilityLimits limits_;
};

}  // namespace
}  // namespace sabo::dem

int main(int argc, char** argv) {
  return sabo::solver::solver_main(argc, argv, sabo::Role::dem,
                                   [](const sabo::scene::Scene& scene, const sabo::solver::SolverOptions& options) {
                                     return std::make_unique<sabo::dem::DemSolver>(scene, options);
                                   });
}
