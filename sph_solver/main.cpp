// sph_solver: weakly compressible SPH coupled through the Sabo protocol.
//   sph_solver --scene FILE --coupler ENDPOINT [--out DIR]
// The physics is SphModel (sph_model.hpp); this file is the protocol side.
//
// Walls (docs/protocol.md): with penalty walls the coupler's force per particle is
// added like the DEM solver's, and the SPH forces are computed while the coupler
// works. With boundary particles (structure walls, or boulders with
// [contact.sph_dem] model = "boundary_particles") the wall particles at x_n arrive
// in the StepForces of step n, so the SPH forces of step n are computed once they
// are there (apply_coupling_forces), and the force on each wall particle goes back
// in the next StepState.boundary_force, in the order received.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <utility>

#include "libsabo/core/error.hpp"
#include "libsabo/solver/driver.hpp"
#include "sph_solver/energy_audit.hpp"
#include "sph_solver/fronts.hpp"
#include "sph_solver/gauges.hpp"
#include "sph_solver/inflow_recorder.hpp"
#include "sph_solver/sph_model.hpp"
#include "sph_solver/sph_output.hpp"

namespace sabo::sph {
namespace {

std::vector<Vec3> unpack_vectors(const google::protobuf::RepeatedField<double>& values, std::size_t count,
                                 const char* field) {
  if (static_cast<std::size_t>(values.size()) != 3 * count) {
    throw ProtocolError(fmt::format("StepForces.{} has {} values for {} boundary particles; 3 per particle expected",
                                    field, values.size(), count));
  }
  std::vector<Vec3> out(count);
  for (std::size_t k = 0; k < count; ++k) {
    out[k] =
        Vec3(values[static_cast<int>(3 * k)], values[static_cast<int>(3 * k + 1)], values[static_cast<int>(3 * k + 2)]);
  }
  return out;
}

class SphSolver final : public solver::CoupledSolver {
 public:
  SphSolver(const scene::Scene& scene, const solver::SolverOptions& options)
      : model_(scene),
        audit_(model_),
        output_(options.out_dir, model_),
        gauges_(options.out_dir, scene),
        fronts_(options.out_dir, scene),
        inflow_history_(options.out_dir, scene, model_),
        boundary_walls_(scene.sph_receives_boundary_particles()),
        limits_(solver::stability_limits(scene, Role::sph)) {
    for (const scene::Material& material : scene.materials) rest_density_.push_back(material.density);
    scene_max_speed_ = scene.run.max_speed.has_value();
    spdlog::info("{} SPH particles in {} fluid bodies, h = {:.4g} m, c = {:.4g} m/s, stable dt {:.3e} s, walls: {}",
                 model_.size(), scene.fluids.size(), model_.kernel().h, scene.sph.sound_speed, model_.stable_dt(),
                 boundary_walls_ ? "boundary particles" : "penalty");
    for (const InflowState& inflow : model_.inflows()) {
      spdlog::info(
          "inflow '{}': a section of {} x {} particles ({:.4g} m^2), a buffer of {} layers, {} particles for the "
          "{:.6g} m^3 of its hydrograph up to t = {:.6g} s (peak {:.6g} m^3/s, {:.4g} m/s)",
          inflow.name, inflow.lattice.across, inflow.lattice.up, inflow.lattice.area, inflow.lattice.buffer_layers,
          inflow.lattice.particles(), inflow.section.volume(0.0, scene.run.end_time), scene.run.end_time,
          inflow.section.peak_discharge(), inflow.section.peak_discharge() / inflow.lattice.area);
    }
    for (const scene::FluidBody& body : scene.fluids) {
      if (body.settle_time > 0) {
        spdlog::info("fluid body '{}' settles until t = {:.4g} s: its velocities are damped, then set to zero",
                     body.name, body.settle_time);
      }
    }
  }

  void describe(sabo::v1::Register& registration) override {
    registration.set_name("sph_solver " SABO_VERSION);
    registration.set_exposes_particles(true);
    auto* table = registration.mutable_particles();
    const auto n = model_.size();
    const double contact_radius = 0.5 * model_.settings().particle_spacing;  // docs/protocol.md
    for (std::size_t i = 0; i < n; ++i) {
      table->add_id(i);
      table->add_radius(contact_radius);
    }
    table->mutable_mass()->Assign(model_.masses().begin(), model_.masses().end());
    table->mutable_material()->Assign(model_.material_index().begin(), model_.material_index().end());
    table->mutable_body()->Assign(model_.body_index().begin(), model_.body_index().end());
  }

  double stable_dt() override { return model_.stable_dt(); }

  void fill_state(const solver::Interest& interest, sabo::v1::StepState& state) override {
    solver::add_particle_states(
        interest, {.position = model_.positions(), .velocity = model_.velocities(), .active = model_.active()}, state);
    if (boundary_walls_ && have_boundary_forces_) {
      auto* f = state.mutable_boundary_force();
      for (const Vec3& force : model_.boundary_forces()) {
        for (int c = 0; c < 3; ++c) f->Add(force[c]);
      }
    }
    const Energies e = model_.energies();
    // Dissipated: the energy the fluid lost beyond the work done on it (energy_audit.hpp), its
    // viscosity and the walls' work held back among it.
    solver::set_energies(state, {e.kinetic, e.potential, e.elastic, audit_.dissipated(), e.inflow});
  }

  void compute_internal_forces(double dt_previous) override {
    dt_previous_ = dt_previous;
    if (!boundary_walls_) model_.compute_internal_forces(dt_previous);
  }

  void apply_coupling_forces(const sabo::v1::StepForces& forces) override {
    if (boundary_walls_) {
      const auto count = static_cast<std::size_t>(forces.boundary_volume_size());
      physics::BoundaryParticles walls;
      walls.position = unpack_vectors(forces.boundary_position(), count, "boundary_position");
      // Empty: every wall particle at rest (BoundaryParticles keeps them empty then).
      if (!forces.boundary_velocity().empty()) {
        walls.velocity = unpack_vectors(forces.boundary_velocity(), count, "boundary_velocity");
      }
      walls.normal = unpack_vectors(forces.boundary_normal(), count, "boundary_normal");
      if (!forces.boundary_acceleration().empty()) {
        walls.acceleration = unpack_vectors(forces.boundary_acceleration(), count, "boundary_acceleration");
      }
      walls.volume.assign(forces.boundary_volume().begin(), forces.boundary_volume().end());
      walls.free_slip.assign(forces.boundary_free_slip().begin(), forces.boundary_free_slip().end());
      model_.set_boundary(std::move(walls));
      model_.compute_internal_forces(dt_previous_);
      have_boundary_forces_ = true;
    }
    const std::span<const std::uint32_t> index{forces.index().data(), static_cast<std::size_t>(forces.index_size())};
    const std::span<const double> force{forces.force().data(), static_cast<std::size_t>(forces.force_size())};
    model_.add_external_forces(index, force);
    audit_.before_integrate(model_, index, force);
    gauges_.sample(model_, model_.time());
    fronts_.sample(model_, model_.time());
    inflow_history_.sample(model_, model_.time());
  }

  [[nodiscard]] bool can_take_state() const override { return true; }
  void take_state(const sabo::v1::StepState& recorded) override {
    solver::take_particle_states(recorded, model_.positions(), model_.velocities());
  }

  void write_output(std::uint64_t step, double time) override {
    output_.write(step, time);
    report_losses("since the last output");
  }

  void integrate(double dt_previous, double dt) override {
    model_.integrate(dt_previous, dt);
    audit_.after_integrate(model_, dt_previous, dt);
    if (lost_reported_ == 0 && model_.lost_count() > 0) {
      // The first loss at once; later ones summed up at each output time (a flow leaving through an open end
      // loses particles at most steps).
      spdlog::warn(
          "{} SPH particles left the domain and were taken out at t = {:.6g} s; further losses are "
          "reported at each output time",
          model_.lost_count(), model_.time());
      lost_reported_ = model_.lost_count();
    }
  }

  [[nodiscard]] std::optional<solver::Instability> check_stability() const override {
    auto found =
        solver::check_motion(model_.positions(), model_.velocities(), model_.active(), limits_.max_speed, "particle");
    if (found && found->what == "too fast" && !scene_max_speed_) {
      found->detail += fmt::format(
          " (here the sound speed sph.sound_speed: the weakly compressible model needs the "
          "flow well below it; raise it, or set run.max_speed)");
    }
    if (found) return found;
    return solver::check_density(model_.densities(), model_.material_index(), rest_density_, model_.active(), limits_);
  }
  void write_instability(const solver::Instability& instability, const std::filesystem::path& file) const override {
    const std::pair<std::string, std::span<const double>> arrays[] = {{"density", model_.densities()},
                                                                      {"pressure", model_.pressures()}};
    solver::write_instability(file, model_.positions(), model_.velocities(), instability, 2.0 * model_.kernel().h,
                              arrays);
  }

  // Walls arrive as boundary particles at x_n and the fluid's force on them goes back for that one
  // step: held over several steps, neither would be exact, so such a run is lock-step for the fluid.
  [[nodiscard]] std::uint32_t max_substeps() const override { return boundary_walls_ ? 1 : solver::kMaxSubsteps; }
  [[nodiscard]] bool can_checkpoint() const override { return true; }
  void save_checkpoint(io::hdf5::Group& group) const override {
    io::hdf5::Group model = group.create_group("model");
    model_.save_state(model);
    audit_.save(group);
    output_.save(group);
    gauges_.save(group);
    fronts_.save(group);
    inflow_history_.save(group);
    group.set_attribute("have_boundary_forces", have_boundary_forces_ ? 1 : 0);
  }
  void load_checkpoint(const io::hdf5::Group& group) override {
    model_.load_state(group.group("model"));
    audit_.load(group);
    output_.load(group);
    gauges_.load(group);
    fronts_.load(group);
    inflow_history_.load(group);
    have_boundary_forces_ = group.int_attribute("have_boundary_forces") != 0;
  }
  [[nodiscard]] std::string results() const override {
    nlohmann::json results = nlohmann::json::object();
    if (!fronts_.empty()) results["fronts"] = fronts_.results();
    if (!model_.inflows().empty()) results["inflows"] = inflow_results();
    return results.empty() ? std::string() : results.dump();
  }
  void finish() override { report_losses("since the last output, to the end"); }

 private:
  // Per inflow: the hydrograph's volume up to the model's time against the volume and mass released.
  [[nodiscard]] nlohmann::json inflow_results() const {
    nlohmann::json list = nlohmann::json::array();
    for (const InflowState& inflow : model_.inflows()) {
      const double target = inflow.section.volume(0.0, model_.time());
      double mass = 0;
      for (std::size_t layer = 0; layer < inflow.released; ++layer) {
        for (std::size_t p = 0; p < inflow.lattice.per_layer(); ++p) mass += model_.masses()[inflow.id(layer, p)];
      }
      list.push_back({{"name", inflow.name},
                      {"time", model_.time()},
                      {"hydrograph_volume", target},
                      {"released_volume", inflow.released_volume()},
                      {"relative_error", target > 0 ? inflow.released_volume() / target - 1.0 : 0.0},
                      {"layer_volume", inflow.lattice.area * inflow.spacing},
                      {"released_mass", mass},
                      {"released_particles", inflow.released * inflow.lattice.per_layer()},
                      {"buffer_ended", inflow.ended}});
    }
    return list;
  }

  void report_losses(const char* when) {
    if (model_.lost_count() == lost_reported_) return;
    spdlog::warn("{} more SPH particles left the domain and were taken out {} ({} in all)",
                 model_.lost_count() - lost_reported_, when, model_.lost_count());
    lost_reported_ = model_.lost_count();
  }

  SphModel model_;
  EnergyAudit audit_;
  SphOutput output_;
  GaugeRecorder gauges_;
  FrontRecorder fronts_;
  InflowRecorder inflow_history_;
  bool boundary_walls_;
  bool have_boundary_forces_ = false;
  double dt_previous_ = 0;
  solver::StabilityLimits limits_;
  bool scene_max_speed_ = false;
  std::vector<double> rest_density_;  // kg/m^3, by scene material index
  std::size_t lost_reported_ = 0;     // particles taken out that the log has named
};

}  // namespace
}  // namespace sabo::sph

int main(int argc, char** argv) {
  return sabo::solver::solver_main(argc, argv, sabo::Role::sph,
                                   [](const sabo::scene::Scene& scene, const sabo::solver::SolverOptions& options) {
                                     return std::make_unique<sabo::sph::SphSolver>(scene, options);
                                   });
}
