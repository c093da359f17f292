// sph_solver: weakly compressible SPH coupled through the Sabo protocol.
//   sph_solver --scene FILE --coupler ENDPOINT [--out DIR]
// The physics is SphModel (sph_model.hpp); this file is the protocol side.
//
// Walls (docs/protocol.md): with penalty walls the coupler's force per particle is
// added like the DEM solver's, and the SPH forces are computed while the coupler
// works. With boundary particles (structure walls, or boulders with
// [contact.sph_dem] model = "boundary_particles") the wall particles at x_n arrive
// ahead of the forces of step n, in a StepForces of their own (walls ahead: the
// coupler computes its other pairs meanwhile), or inside the StepForces of step n
// (a replay, a restart's catch-up), so the SPH forces of step n are computed once
// they are there (take_walls_ahead, apply_coupling_forces), and the force on each wall particle goes back
// in the next StepState.boundary_force, in the order received. With
// sph.lagged_boundary_particles the SPH forces of step n are computed while the
// coupler works, with the wall particles of step n - 1 moved ahead one step
// (walls_ahead()), and their forces go back with boundary_step = n - 1 in the
// StepState of step n + 1; only step 0, with no wall particles yet, waits.
//
// Ranks (docs/architecture.md, "The slurry on several processes"): started by mpirun with R > 1
// ranks, rank 0 is the coupler's correspondent (SphSolver, as alone) and the others follow it
// (follow()): rank 0 broadcasts each call it makes of the shared model (RankCommand) before
// making it, so that every rank steps the model with it, and after each step collects the whole
// state (SphModel::collect_state()), which the coupler's states, the output and the checks read.
// The coupler and the protocol do not change.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cassert>
#include <cmath>
#include <optional>
#include <utility>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "libsabo/scene/loader.hpp"
#include "libsabo/solver/driver.hpp"
#include "sph_solver/energy_audit.hpp"
#include "sph_solver/fronts.hpp"
#include "sph_solver/gauges.hpp"
#include "sph_solver/inflow_recorder.hpp"
#include "sph_solver/parallel/mpi_ranks.hpp"
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

// What rank 0 tells the other ranks before each call of the shared model: the command, then its
// arguments, all as doubles (ids and counts are exact in one).
enum class RankCommand { compute = 1, walls, forces, integrate, collect, share_loaded_state, sample, take, stop };

std::vector<double> pack_walls(const physics::BoundaryParticles& walls) {
  std::vector<double> out{double(RankCommand::walls), double(walls.size()), walls.velocity.empty() ? 0.0 : 1.0,
                          walls.acceleration.empty() ? 0.0 : 1.0, walls.free_slip.empty() ? 0.0 : 1.0};
  const auto vectors = [&](const std::vector<Vec3>& values) {
    for (const Vec3& v : values) out.insert(out.end(), {v.x(), v.y(), v.z()});
  };
  vectors(walls.position);
  vectors(walls.velocity);
  vectors(walls.normal);
  vectors(walls.acceleration);
  out.insert(out.end(), walls.volume.begin(), walls.volume.end());
  out.insert(out.end(), walls.free_slip.begin(), walls.free_slip.end());
  return out;
}

// The wall particles of the StepForces of step n - 1 at step n, dt = t_n - t_{n-1} later: each moved by the
// leapfrog's displacement dt (v + dt a) of its half-step velocity v, and its velocity by dt a (walls at rest,
// sent without velocities, stay). Second order in dt, like the fluid's own step.
physics::BoundaryParticles walls_ahead(const physics::BoundaryParticles& walls, double dt) {
  physics::BoundaryParticles ahead = walls;
  if (walls.velocity.empty()) return ahead;
  for (std::size_t k = 0; k < walls.size(); ++k) {
    const Vec3 acceleration = walls.acceleration_of(k);
    ahead.position[k] += dt * (walls.velocity[k] + dt * acceleration);
    ahead.velocity[k] += dt * acceleration;
  }
  return ahead;
}

// Whether `in` is a whole pack_walls() list: its size is what its header says (a checkpoint keeps one, and a
// checkpoint is user input).
bool well_formed_walls(const std::vector<double>& in) {
  if (in.size() < 5 || !(in[1] >= 0) || in[1] != std::floor(in[1])) return false;
  const auto n = static_cast<std::size_t>(in[1]);
  const std::size_t vectors = 2 + (in[2] != 0 ? 1 : 0) + (in[3] != 0 ? 1 : 0);
  return in.size() == 5 + n * (3 * vectors + 1 + (in[4] != 0 ? 1 : 0));
}

physics::BoundaryParticles unpack_walls(const std::vector<double>& in) {
  assert(well_formed_walls(in));
  const auto n = static_cast<std::size_t>(in[1]);
  std::size_t at = 5;
  const auto vectors = [&](bool present) {
    std::vector<Vec3> values;
    if (!present) return values;
    for (std::size_t k = 0; k < n; ++k, at += 3) values.emplace_back(in[at], in[at + 1], in[at + 2]);
    return values;
  };
  physics::BoundaryParticles walls;
  walls.position = vectors(true);
  walls.velocity = vectors(in[2] != 0);
  walls.normal = vectors(true);
  walls.acceleration = vectors(in[3] != 0);
  walls.volume.assign(in.begin() + static_cast<std::ptrdiff_t>(at), in.begin() + static_cast<std::ptrdiff_t>(at + n));
  at += n;
  if (in[4] != 0) {
    for (std::size_t k = 0; k < n; ++k) walls.free_slip.push_back(static_cast<std::uint8_t>(in[at + k]));
  }
  return walls;
}

// Replay's recorded state to take (StepForces.taken): index, then each field's count and values.
std::vector<double> pack_taken(const sabo::v1::StepState& recorded) {
  std::vector<double> out{double(RankCommand::take), double(recorded.index_size())};
  out.insert(out.end(), recorded.index().begin(), recorded.index().end());
  for (const auto* field : {&recorded.position(), &recorded.velocity()}) {
    out.push_back(double(field->size()));
    out.insert(out.end(), field->begin(), field->end());
  }
  return out;
}

sabo::v1::StepState unpack_taken(const std::vector<double>& in) {
  sabo::v1::StepState recorded;
  std::size_t at = 1;
  const auto count = static_cast<std::size_t>(in.at(at++));
  for (std::size_t k = 0; k < count; ++k) recorded.add_index(static_cast<std::uint32_t>(in.at(at++)));
  for (auto* field : {recorded.mutable_position(), recorded.mutable_velocity()}) {
    const auto size = static_cast<std::size_t>(in.at(at++));
    for (std::size_t k = 0; k < size; ++k) field->Add(in.at(at++));
  }
  return recorded;
}

// Rank 0's side of the commands (a no-op without ranks).
class RankLeader {
 public:
  explicit RankLeader(std::shared_ptr<parallel::Ranks> ranks) : ranks_(std::move(ranks)) {}
  [[nodiscard]] bool active() const { return ranks_ != nullptr; }
  void send(std::vector<double> command) {
    if (ranks_) ranks_->broadcast(command, 0);
  }
  void send(RankCommand command, std::initializer_list<double> arguments = {}) {
    if (!ranks_) return;
    std::vector<double> out{double(command)};
    out.insert(out.end(), arguments);
    send(std::move(out));
  }
  void stop() {
    if (ranks_ && !stopped_) send(RankCommand::stop);
    stopped_ = true;
  }

 private:
  std::shared_ptr<parallel::Ranks> ranks_;
  bool stopped_ = false;
};

class SphSolver final : public solver::CoupledSolver {
 public:
  SphSolver(const scene::Scene& scene, const solver::SolverOptions& options,
            std::shared_ptr<parallel::Ranks> ranks = nullptr)
      : model_(scene, ranks),
        leader_(ranks),
        audit_(model_),
        output_(options.out_dir, model_),
        gauges_(options.out_dir, scene),
        fronts_(options.out_dir, scene),
        inflow_history_(options.out_dir, scene, model_),
        boundary_walls_(scene.sph_receives_boundary_particles()),
        lagged_walls_(boundary_walls_ && scene.sph.lagged_boundary_particles),
        limits_(solver::stability_limits(scene, Role::sph)) {
    if (leader_.active()) {
      // Gauges and fronts sample the fluid on the grid, which each rank holds for its slab.
      model_.set_remote_sampler([this](const Vec3& point, bool kernel_sum_only) {
        leader_.send(RankCommand::sample, {kernel_sum_only ? 1.0 : 0.0, point.x(), point.y(), point.z()});
        return model_.sample_on_ranks(point, kernel_sum_only);
      });
      spdlog::info(
          "the SPH model runs on {} ranks (slabs of the grid along its longest axis); this rank, 0, talks "
          "to the coupler",
          ranks->size());
    }
    for (const scene::Material& material : scene.materials) rest_density_.push_back(material.density);
    scene_max_speed_ = scene.run.max_speed.has_value();
    spdlog::info("{} SPH particles in {} fluid bodies, h = {:.4g} m, c = {:.4g} m/s, stable dt {:.3e} s, walls: {}",
                 model_.size(), scene.fluids.size(), model_.kernel().h, scene.sph.sound_speed, model_.stable_dt(),
                 boundary_walls_ ? (lagged_walls_ ? "boundary particles, lagged (the fluid's forces computed while "
                                                    "the coupler works, with the wall particles of the step before "
                                                    "moved ahead one step)"
                                                  : "boundary particles")
                                 : "penalty");
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
      // Lagged: forces on the wall particles of step n - 2 (the protocol's default, absent, is n - 1).
      if (lagged_walls_ && state.step() == answered_walls_step_ + 2) state.set_boundary_step(answered_walls_step_);
    }
    const Energies e = model_.energies();
    // Dissipated: the energy the fluid lost beyond the work done on it (energy_audit.hpp), its
    // viscosity and the walls' work held back among it.
    solver::set_energies(state, {e.kinetic, e.potential, e.elastic, audit_.dissipated(), e.inflow});
  }

  void compute_internal_forces(double dt_previous) override {
    dt_previous_ = dt_previous;
    if (!boundary_walls_) {
      leader_.send(RankCommand::compute, {dt_previous});
      model_.compute_internal_forces(dt_previous);
    } else if (lagged_walls_ && last_walls_) {
      compute_with_walls(walls_ahead(last_walls_->walls, last_walls_->dt), last_walls_->step);
    }
  }

  // The lagged fluid computes with the walls of the step before, so walls ahead would gain it nothing.
  [[nodiscard]] bool takes_walls_ahead() const override { return boundary_walls_ && !lagged_walls_; }
  void take_walls_ahead(const sabo::v1::StepForces& walls) override {
    assert(takes_walls_ahead() && "the driver hands walls ahead only to a solver that registered them");
    compute_with_walls(walls_of(walls), walls.step());
    walls_taken_ = true;
  }

  void apply_coupling_forces(const sabo::v1::StepForces& forces) override {
    if (walls_taken_) {
      walls_taken_ = false;  // the driver refuses a StepForces that brings them again
    } else if (boundary_walls_) {
      physics::BoundaryParticles walls = walls_of(forces);
      if (!lagged_walls_) {
        compute_with_walls(std::move(walls), forces.step());
      } else {
        // Without wall particles of a step before (step 0, a checkpoint of step 0) nothing was computed ahead.
        if (!last_walls_) compute_with_walls(walls, forces.step());
        last_walls_ = LastWalls{std::move(walls), forces.step(), forces.dt()};
      }
    }
    const std::span<const std::uint32_t> index{forces.index().data(), static_cast<std::size_t>(forces.index_size())};
    const std::span<const double> force{forces.force().data(), static_cast<std::size_t>(forces.force_size())};
    if (leader_.active()) {
      std::vector<double> command{double(RankCommand::forces), double(index.size())};
      command.insert(command.end(), index.begin(), index.end());
      command.insert(command.end(), force.begin(), force.end());
      leader_.send(std::move(command));
    }
    model_.add_external_forces(index, force);
    audit_.before_integrate(model_, index, force);
    gauges_.sample(model_, model_.time());
    fronts_.sample(model_, model_.time());
    inflow_history_.sample(model_, model_.time());
  }

  // On ranks every rank takes the recorded values into its arrays: an owner steps its particles from them, and
  // rank 0's collected copy (what the next state sends) holds them too.
  [[nodiscard]] bool can_take_state() const override { return true; }
  void take_state(const sabo::v1::StepState& recorded) override {
    solver::take_particle_states(recorded, model_.positions(), model_.velocities());  // checks it before the ranks
    if (leader_.active()) leader_.send(pack_taken(recorded));
  }

  void write_output(std::uint64_t step, double time) override {
    output_.write(step, time);
    report_losses("since the last output");
  }

  void integrate(double dt_previous, double dt) override {
    leader_.send(RankCommand::integrate, {dt_previous, dt});
    model_.integrate(dt_previous, dt);
    leader_.send(RankCommand::collect);
    model_.collect_state();  // alone: nothing to do
    audit_.after_integrate(model_, dt_previous, dt);
    if (lost_reported_ == 0 && model_.lost_count() > 0) {
      // The first loss at once; later ones summed up at each output time (a flow leaving through an open end
      // loses particles at most steps).
      const scene::SphSettings& sph = model_.settings();
      const bool coarse_walls =
          sph.wall_model == scene::SphSettings::WallModel::boundary_particles && sph.wall_spacing_ratio == 1.0;
      spdlog::warn(
          "{} SPH particles left the domain and were taken out at t = {:.6g} s; further losses are "
          "reported at each output time{}",
          model_.lost_count(), model_.time(),
          coarse_walls ? ". If they went through a wall rather than out of an open end: fluid sliding along wall "
                         "particles at a tenth of the sound speed falls through them when they sit at dx; set "
                         "sph.wall_spacing_ratio = 0.5 (docs/physics.md, \"Walls\")"
                       : "");
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
  // On ranks rank 0 writes the state it collects after every step, and shares what it loads.
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
    group.set_attribute("answered_walls_step", static_cast<std::int64_t>(answered_walls_step_));
    if (last_walls_) {
      // Lagged: the next step computes with these, moved ahead; kept as the ranks receive them.
      io::hdf5::Group last = group.create_group("last_walls");
      io::write_array(last, "walls", pack_walls(last_walls_->walls));
      last.set_attribute("step", static_cast<std::int64_t>(last_walls_->step));
      last.set_attribute("dt", last_walls_->dt);
    }
  }
  void load_checkpoint(const io::hdf5::Group& group) override {
    model_.load_state(group.group("model"));
    leader_.send(RankCommand::share_loaded_state);
    model_.share_loaded_state();  // alone: nothing to do
    audit_.load(group);
    output_.load(group);
    gauges_.load(group);
    fronts_.load(group);
    inflow_history_.load(group);
    have_boundary_forces_ = group.int_attribute("have_boundary_forces") != 0;
    answered_walls_step_ = group.has_attribute("answered_walls_step")  // written since lagged walls exist
                               ? static_cast<std::uint64_t>(group.int_attribute("answered_walls_step"))
                               : 0;
    last_walls_.reset();
    if (lagged_walls_ && group.exists("last_walls")) {
      const io::hdf5::Group last = group.group("last_walls");
      const auto packed = io::read_array<double>(last, "walls");
      if (!well_formed_walls(packed)) {
        throw FileError(
            fmt::format("{}: {}/walls is not a whole list of wall particles ({} values). Fix: restart "
                        "from another checkpoint of this run",
                        last.file_name(), last.path(), packed.size()));
      }
      last_walls_ = LastWalls{unpack_walls(packed), static_cast<std::uint64_t>(last.int_attribute("step")),
                              last.double_attribute("dt")};
    }
  }
  [[nodiscard]] std::string results() const override {
    nlohmann::json results = nlohmann::json::object();
    if (!fronts_.empty()) results["fronts"] = fronts_.results();
    if (!model_.inflows().empty()) results["inflows"] = inflow_results();
    return results.empty() ? std::string() : results.dump();
  }
  void finish() override {
    leader_.stop();
    report_losses("since the last output, to the end");
  }

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

  // The wall particles a StepForces carries; ProtocolError when its arrays do not fit their count.
  static physics::BoundaryParticles walls_of(const sabo::v1::StepForces& forces) {
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
    return walls;
  }

  // Sets the wall particles of step `walls_step` (moved ahead or not) and computes the fluid's forces with them.
  void compute_with_walls(physics::BoundaryParticles walls, std::uint64_t walls_step) {
    if (leader_.active()) leader_.send(pack_walls(walls));
    leader_.send(RankCommand::compute, {dt_previous_});
    model_.set_boundary(std::move(walls));
    model_.compute_internal_forces(dt_previous_);
    have_boundary_forces_ = true;
    answered_walls_step_ = walls_step;
  }

  void report_losses(const char* when) {
    if (model_.lost_count() == lost_reported_) return;
    spdlog::warn("{} more SPH particles left the domain and were taken out {} ({} in all)",
                 model_.lost_count() - lost_reported_, when, model_.lost_count());
    lost_reported_ = model_.lost_count();
  }

  SphModel model_;
  RankLeader leader_;
  EnergyAudit audit_;
  SphOutput output_;
  GaugeRecorder gauges_;
  FrontRecorder fronts_;
  InflowRecorder inflow_history_;
  bool boundary_walls_;
  bool lagged_walls_;  // sph.lagged_boundary_particles, with boundary particles
  bool have_boundary_forces_ = false;
  bool walls_taken_ = false;               // this step's walls came ahead of its forces and were computed with
  std::uint64_t answered_walls_step_ = 0;  // the step of the wall particles model_.boundary_forces() answers
  // Lagged: the wall particles of the last StepForces, its step and its dt (s), for the next step's forces.
  struct LastWalls {
    physics::BoundaryParticles walls;
    std::uint64_t step = 0;
    double dt = 0;
  };
  std::optional<LastWalls> last_walls_;
  double dt_previous_ = 0;
  solver::StabilityLimits limits_;
  bool scene_max_speed_ = false;
  std::vector<double> rest_density_;  // kg/m^3, by scene material index
  std::size_t lost_reported_ = 0;     // particles taken out that the log has named
};

}  // namespace
}  // namespace sabo::sph

namespace sabo::sph {
namespace {

// The other ranks: the same scene's model, stepped as rank 0 says, until it says stop.
int follow(int argc, char** argv, const std::shared_ptr<parallel::Ranks>& ranks) {
  const std::optional<solver::SolverOptions> options = solver::parse_solver_command_line(argc, argv, "sph_solver");
  if (!options) return 0;
  const scene::Scene scene = scene::load_scene(options->scene);
  SphModel model(scene, ranks);
  for (;;) {
    std::vector<double> command;
    ranks->broadcast(command, 0);
    switch (static_cast<RankCommand>(static_cast<int>(command.at(0)))) {
      case RankCommand::compute: model.compute_internal_forces(command.at(1)); break;
      case RankCommand::walls: model.set_boundary(unpack_walls(command)); break;
      case RankCommand::forces: {
        const auto count = static_cast<std::size_t>(command.at(1));
        std::vector<std::uint32_t> index(count);
        for (std::size_t k = 0; k < count; ++k) index[k] = static_cast<std::uint32_t>(command[2 + k]);
        model.add_external_forces(index, std::span<const double>(command).subspan(2 + count));
        break;
      }
      case RankCommand::integrate: model.integrate(command.at(1), command.at(2)); break;
      case RankCommand::collect: model.collect_state(); break;
      case RankCommand::share_loaded_state: model.share_loaded_state(); break;
      case RankCommand::sample:
        (void)model.sample_on_ranks(Vec3(command.at(2), command.at(3), command.at(4)), command.at(1) != 0.0);
        break;
      case RankCommand::take:
        solver::take_particle_states(unpack_taken(command), model.positions(), model.velocities());
        break;
      case RankCommand::stop: return 0;
    }
  }
}

}  // namespace
}  // namespace sabo::sph

int main(int argc, char** argv) {
  using namespace sabo;
  const auto make = [](std::shared_ptr<sph::parallel::Ranks> ranks) {
    return [ranks](const scene::Scene& scene, const solver::SolverOptions& options) {
      return std::make_unique<sph::SphSolver>(scene, options, ranks);
    };
  };
  if (!sph::parallel::launched_by_mpi()) return solver::solver_main(argc, argv, Role::sph, make(nullptr));
  std::optional<sph::parallel::MpiSession> mpi;
  std::shared_ptr<sph::parallel::MpiRanks> ranks;
  try {
    mpi.emplace(argc, argv);
    ranks = std::make_shared<sph::parallel::MpiRanks>();
  } catch (const std::exception& error) {
    fmt::print(stderr, "{}\n", error.what());
    return 1;
  }
  if (ranks->size() == 1) return solver::solver_main(argc, argv, Role::sph, make(nullptr));
  int status = 0;
  if (ranks->rank() == 0) {
    status = solver::solver_main(argc, argv, Role::sph, make(ranks));
  } else {
    try {
      status = sph::follow(argc, argv, ranks);
    } catch (const std::exception& error) {
      fmt::print(stderr, "sph_solver rank {}: {}\n", ranks->rank(), error.what());
      status = 1;
    }
  }
  // A rank that failed may have left the others inside a collective call: end them all.
  if (status != 0 && status != 130) mpi->abort(status);
  return status;
}
