#include "libsabo/solver/driver.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cassert>
#include <chrono>

#include "libsabo/core/error.hpp"
#include "libsabo/core/log.hpp"
#include "libsabo/core/signals.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "libsabo/protocol/solver_link.hpp"
#include "libsabo/protocol/walls_ahead.hpp"
#include "libsabo/scene/loader.hpp"

namespace sabo::solver {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

void Interest::update(const google::protobuf::RepeatedPtrField<sabo::v1::Box>& boxes, bool all) {
  all_ = all;
  boxes_.clear();
  bounds_ = Aabb{};
  for (const auto& box : boxes) {
    boxes_.push_back(Aabb{Vec3(box.min_x(), box.min_y(), box.min_z()), Vec3(box.max_x(), box.max_y(), box.max_z())});
    bounds_.extend(boxes_.back());
  }
}

void Interest::save(io::hdf5::Group& group) const {
  group.set_attribute("interest_all", all_ ? 1 : 0);
  std::vector<double> corners;
  corners.reserve(6 * boxes_.size());
  for (const auto& box : boxes_) {
    for (int c = 0; c < 3; ++c) corners.push_back(box.min[c]);
    for (int c = 0; c < 3; ++c) corners.push_back(box.max[c]);
  }
  io::write_array(group, "interest_boxes", corners);
}

void Interest::load(const io::hdf5::Group& group) {
  all_ = group.int_attribute("interest_all") != 0;
  const auto corners = io::read_array<double>(group, "interest_boxes");
  if (corners.size() % 6 != 0) {
    throw FileError(
        fmt::format("{}: interest_boxes holds {} values, not 6 per box. Fix: restart from a checkpoint "
                    "Sabo wrote",
                    group.file_name(), corners.size()));
  }
  boxes_.clear();
  bounds_ = Aabb{};
  for (std::size_t b = 0; b < corners.size(); b += 6) {
    boxes_.push_back(
        Aabb{Vec3(corners[b], corners[b + 1], corners[b + 2]), Vec3(corners[b + 3], corners[b + 4], corners[b + 5])});
    bounds_.extend(boxes_.back());
  }
}

bool Interest::contains(const Vec3& point) const {
  if (all_) return true;
  if (!bounds_.contains(point)) return false;  // most entities far from every region stop here
  for (const auto& box : boxes_) {
    if (box.contains(point)) return true;
  }
  return false;
}

void set_energies(sabo::v1::StepState& state, const EnergyReport& energies) {
  auto* e = state.mutable_energies();
  e->set_kinetic(energies.kinetic);
  e->set_potential(energies.potential);
  e->set_elastic(energies.elastic);
  e->set_dissipated(energies.dissipated);
  e->set_inflow(energies.inflow);
}

void add_particle_states(const Interest& interest, const ParticleStates& particles, sabo::v1::StepState& state) {
  assert(particles.velocity.size() == particles.position.size());
  assert(particles.angular_velocity.empty() || particles.angular_velocity.size() == particles.position.size());
  assert(particles.active.empty() || particles.active.size() == particles.position.size());
  const bool spins = !particles.angular_velocity.empty();
  auto* index = state.mutable_index();
  auto* x = state.mutable_position();
  auto* v = state.mutable_velocity();
  auto* w = state.mutable_angular_velocity();
  index->Reserve(static_cast<int>(particles.position.size()));
  for (std::size_t i = 0; i < particles.position.size(); ++i) {
    if (!particles.active.empty() && particles.active[i] == 0) continue;
    if (!interest.contains(particles.position[i])) continue;
    index->Add(static_cast<std::uint32_t>(i));
    for (int c = 0; c < 3; ++c) {
      x->Add(particles.position[i][c]);
      v->Add(particles.velocity[i][c]);
      if (spins) w->Add(particles.angular_velocity[i][c]);
    }
  }
}

void take_particle_states(const sabo::v1::StepState& recorded, std::span<Vec3> position, std::span<Vec3> velocity,
                          std::span<Vec3> angular_velocity) {
  const auto count = static_cast<std::size_t>(recorded.index_size());
  const auto take = [&](const google::protobuf::RepeatedField<double>& values, std::span<Vec3> into,
                        const char* field) {
    if (values.empty()) return;
    if (into.empty() || static_cast<std::size_t>(values.size()) != 3 * count) {
      throw ProtocolError(fmt::format("StepForces.taken: {} {} values for {} particles{}", values.size(), field, count,
                                      into.empty() ? " (this solver has no such field)" : ", expected 3 each"));
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::uint32_t i = recorded.index(static_cast<int>(k));
      if (i >= into.size()) {
        throw ProtocolError(fmt::format("StepForces.taken: particle index {} of {} particles", i, into.size()));
      }
      for (int c = 0; c < 3; ++c) into[i][c] = values[static_cast<int>(3 * k) + c];
    }
  };
  take(recorded.position(), position, "position");
  take(recorded.velocity(), velocity, "velocity");
  take(recorded.angular_velocity(), angular_velocity, "angular_velocity");
}

std::optional<SolverOptions> parse_solver_command_line(int argc, char** argv, const std::string& program) {
  SolverOptions options;
  CLI::App app{fmt::format("{}: a Sabo solver process. Normally started by './sabo run SCENE'.", program), program};
  app.add_option("--scene", options.scene, "scene file (TOML)")->required();
  app.add_option("--coupler", options.coupler_endpoint, "coupler endpoint, e.g. ipc:///tmp/run/coupler.sock")
      ->required();
  app.add_option("--out", options.out_dir, "run folder for output files")->capture_default_str();
  app.add_option("--log-level", options.log_level, "trace, debug, info, warn or error")->capture_default_str();
  app.add_option("--resume", options.resume,
                 "start from this checkpoint (RUN_DIR/checkpoints/<role>_<step>.h5) instead of step 0");
  app.add_option("--keys", options.keys,
                 "the run's key set (RUN_DIR/keys, or a copy of coupler.key and this role's .key_secret): over tcp "
                 "this solver's CURVE keys, over ipc the run's token");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& help) {
    app.exit(help);
    return std::nullopt;
  } catch (const CLI::ParseError& error) {
    throw Error(fmt::format("{}: {}. Run '{} --help' for the options.", program, error.what(), program));
  }
  return options;
}

int run_solver(CoupledSolver& solver, const scene::Scene& scene, const SolverOptions& options, Role role) {
  const auto reply_timeout =
      std::chrono::milliseconds(static_cast<long>(1000.0 * std::max(60.0, 6.0 * scene.run.hang_timeout)));
  // A scene that runs tcp in clear (tcp_security = "none") has a coupler that takes no keys.
  const protocol::ClientCredentials credentials =
      options.keys.empty() || scene.run.tcp_in_clear(options.coupler_endpoint)
          ? protocol::ClientCredentials{}
          : protocol::read_client_credentials(options.keys, role_name(role), options.coupler_endpoint);
  protocol::SolverLink link(options.coupler_endpoint, reply_timeout, credentials,
                            protocol::Heartbeat::after(scene.run.heartbeat_timeout));

  sabo::v1::Register registration;
  registration.set_protocol_version(protocol::kProtocolVersion);
  registration.set_role(protocol::to_wire(role));
  registration.set_pid(static_cast<std::uint32_t>(::getpid()));
  solver.describe(registration);
  registration.set_checkpoints(solver.can_checkpoint());
  registration.set_max_substeps(solver.max_substeps());
  registration.set_holds(solver.can_hold());
  registration.set_takes_state(solver.can_take_state());
  registration.set_walls_ahead(solver.takes_walls_ahead());

  const std::string role_text = role_name(role);
  const io::CheckpointStore checkpoints(options.out_dir / "checkpoints", role_text, io::file_digest(options.scene),
                                        scene.run.checkpoints_kept);
  std::uint64_t step = 0;
  double time = 0;
  double dt_previous = 0;
  Interest interest;
  bool resumed = false;
  if (!options.resume.empty()) {
    if (!solver.can_checkpoint()) {
      throw FileError(
          fmt::format("--resume {}: the {} cannot restart from a checkpoint. Fix: start it without --resume",
                      options.resume.string(), role_text));
    }
    const io::hdf5::File file = checkpoints.open_file(options.resume);
    step = io::checkpoint_step(file);
    time = io::checkpoint_time(file);
    dt_previous = file.double_attribute("dt_previous");
    const io::hdf5::Group driver = file.group("driver");
    interest.load(driver);
    solver.load_checkpoint(file.group("solver"));
    resumed = true;
    registration.set_resumed(true);
    registration.set_resume_step(step);
    spdlog::info("resumed from {} at step {}, t = {:.9g} s", options.resume.string(), step, time);
  }
  registration.set_stable_dt(solver.stable_dt());

  sabo::v1::Goodbye goodbye;
  double compute_seconds = 0;
  double checkpoint_seconds = 0;
  std::uint64_t substeps_taken = 0;
  double forces_wait_seconds = 0;  // of the link's wait: for StepForces after their walls came ahead
  int exit_code = 0;
  try {
    const auto& reply = link.register_solver(registration);
    spdlog::info("registered with the coupler at {} (protocol {})", options.coupler_endpoint, reply.protocol_version());
    if (!resumed) interest.update(reply.interest(), reply.interest_all());

    sabo::v1::StepState state, whole;
    double compute_since_last = 0;
    const auto write_checkpoint = [&](std::uint64_t at) {
      const auto checkpoint_start = Clock::now();
      checkpoints.write(at, time, [&](io::hdf5::File& file) {
        file.set_attribute("dt_previous", dt_previous);
        io::hdf5::Group driver = file.create_group("driver");
        interest.save(driver);
        io::hdf5::Group group = file.create_group("solver");
        solver.save_checkpoint(group);
      });
      checkpoint_seconds += seconds_since(checkpoint_start);
    };
    // Hold exchanges still to answer after the last step, and how many there were.
    std::uint32_t holds_left = 0, holds_announced = 0;
    for (;; ++step) {
      auto start = Clock::now();
      state.Clear();
      state.set_step(step);
      state.set_time(time);
      state.set_stable_dt(solver.stable_dt());
      // A hold: a held state, with the energies of the step just taken at the first (the coupler's energy
      // balance takes them there, where every solver's state describes the block's start). The whole state is
      // filled there, once (a fill may report a change once, a new topology), and sent where the solver steps
      // again: nothing moved in between, and the interest regions are those of its step (its pairs wait).
      const bool hold = holds_left > 0;
      if (hold) {
        state.set_held(true);
        if (holds_left == holds_announced) {
          whole.Clear();
          solver.fill_state(interest, whole);
          state.mutable_energies()->CopyFrom(whole.energies());
          state.mutable_part_energies()->CopyFrom(whole.part_energies());
        }
      } else if (holds_announced > 0) {  // the holds are over: `whole` is the state of the step before them
        whole.set_step(step);
        whole.set_time(time);
        whole.set_stable_dt(state.stable_dt());
        state.Swap(&whole);
      } else {
        solver.fill_state(interest, state);
      }
      compute_since_last += seconds_since(start);
      state.set_compute_seconds(compute_since_last);
      state.set_wait_seconds(link.wait_seconds());
      state.set_forces_wait_seconds(forces_wait_seconds);
      link.send_state(state);

      start = Clock::now();
      double overlapped = 0;
      if (!hold) {
        solver.compute_internal_forces(dt_previous);
        overlapped = seconds_since(start);
      }

      const sabo::v1::StepForces* received = &link.receive_forces(step);
      if (received->walls_ahead()) {
        if (!registration.walls_ahead() || hold) {
          throw ProtocolError(fmt::format("StepForces of step {} carries walls ahead{}", step,
                                          hold ? " at a hold" : "; this solver registered walls_ahead = false"));
        }
        if (received->index_size() > 0 || received->node_force_size() > 0 || received->stop() || received->output() ||
            received->checkpoint() || received->holds() > 0 || received->substeps() > 1 || received->has_taken()) {
          throw ProtocolError(fmt::format(
              "the walls-ahead StepForces of step {} carries more than the boundary particles (forces, stop, "
              "output, checkpoint, holds, substeps or taken state come in the step's own StepForces)",
              step));
        }
        const auto walls_start = Clock::now();
        solver.take_walls_ahead(*received);
        overlapped += seconds_since(walls_start);
        const double waited_before = link.wait_seconds();
        received = &link.receive_forces(step);
        forces_wait_seconds += link.wait_seconds() - waited_before;
        if (received->walls_ahead()) {
          throw ProtocolError(fmt::format("two StepForces of step {} carry walls ahead", step));
        }
        if (protocol::has_boundary_particles(*received)) {
          throw ProtocolError(
              fmt::format("StepForces of step {} carries boundary particles, which came ahead of it already", step));
        }
      }
      const sabo::v1::StepForces& forces = *received;

      start = Clock::now();
      if (forces.hold() != hold) {
        throw ProtocolError(
            hold ? fmt::format("StepForces of step {} is not a hold, while the StepForces of step {} announced {} "
                               "hold exchanges",
                               step, step - (holds_announced - holds_left) - 1, holds_announced)
                 : fmt::format("StepForces of step {} is a hold that no StepForces announced", step));
      }
      interest.update(forces.interest(), forces.interest_all());
      if (hold) {
        if (forces.output() || forces.has_taken() || forces.holds() > 0 || forces.index_size() > 0 ||
            forces.node_force_size() > 0 || (forces.checkpoint() && holds_left > 1)) {
          throw ProtocolError(fmt::format(
              "StepForces of step {} is a hold with {}: a hold carries interest regions, stop, and a checkpoint "
              "at the last hold only",
              step,
              forces.output()       ? "output set"
              : forces.has_taken()  ? "recorded state to take"
              : forces.holds() > 0  ? "holds of its own"
              : forces.checkpoint() ? "a checkpoint before the last hold"
                                    : "forces"));
        }
        --holds_left;
        if (forces.stop()) {
          compute_seconds += seconds_since(start);
          ++step;
          break;
        }
        if (forces.checkpoint() && solver.can_checkpoint()) write_checkpoint(step + 1);
        compute_since_last = seconds_since(start);
        compute_seconds += compute_since_last;
        continue;
      }
      solver.apply_coupling_forces(forces);
      if (forces.output()) solver.write_output(step, time);
      if (forces.stop()) {
        compute_seconds += overlapped + seconds_since(start);
        ++step;
        break;
      }
      // Multirate: the further steps of this exchange with the same contact forces held.
      const std::uint32_t substeps = std::max<std::uint32_t>(forces.substeps(), 1);
      if (substeps > registration.max_substeps() && substeps > 1) {
        throw ProtocolError(
            fmt::format("StepForces of step {} asks for {} steps of dt = {:.6g} s; this solver "
                        "registered max_substeps = {}",
                        step, substeps, forces.dt(), registration.max_substeps()));
      }
      if (forces.holds() > 0 && (!registration.holds() || forces.checkpoint())) {
        throw ProtocolError(fmt::format("StepForces of step {} announces {} hold exchanges{}", step, forces.holds(),
                                        forces.checkpoint()
                                            ? " and asks for a checkpoint (a checkpoint comes at the last hold)"
                                            : "; this solver registered holds = false"));
      }
      for (std::uint32_t k = 0; k < substeps; ++k) {
        if (k > 0) {
          solver.compute_internal_forces(dt_previous);
          solver.apply_coupling_forces(forces);
        }
        solver.integrate(dt_previous, forces.dt());
        time += forces.dt();
        dt_previous = forces.dt();
        if (auto instability = solver.check_stability()) {
          const auto file = instability_file(options.out_dir, role);
          solver.write_instability(*instability, file);
          throw InstabilityError(fmt::format(
              "unstable after step {}{} (t = {:.9g} s, dt = {:.6g} s): {}. The entities and their neighbours are in "
              "{} (ParaView; 'culprit' = 1). Fix: a smaller step ([solvers.{}] beta, or what sets the step: the "
              "coupler's log names it), or look for what drives them (a contact stiffness, an initial overlap, a "
              "material)",
              step, substeps > 1 ? fmt::format(" (substep {} of {})", k + 1, substeps) : std::string(), time,
              forces.dt(), instability->detail, file.string(), role_key(role)));
        }
      }
      substeps_taken += substeps;
      holds_left = holds_announced = forces.holds();
      if (forces.has_taken()) {
        if (!registration.takes_state()) {
          throw ProtocolError(
              fmt::format("StepForces of step {} holds recorded state to take; this solver cannot "
                          "take it (it registered takes_state = false)",
                          step));
        }
        solver.take_state(forces.taken());
      }
      if (forces.checkpoint() && solver.can_checkpoint()) write_checkpoint(step + 1);
      compute_since_last = overlapped + seconds_since(start);
      compute_seconds += compute_since_last;
    }
    goodbye.set_reason("completed");
    spdlog::info("completed {} exchanges ({} steps), t = {:.6g} s", step, substeps_taken, time);
  } catch (const StopRequested& stop) {
    spdlog::warn("{}", stop.what());
    goodbye.set_reason(stop.what());
    exit_code = 130;
  } catch (const std::exception& error) {
    spdlog::error("{}", error.what());
    link.send_error(sabo::v1::Error::CODE_SOLVER, fmt::format("{}: {}", role_name(role), error.what()));
    exit_code = 1;
  }
  try {
    solver.finish();
  } catch (const std::exception& error) {
    spdlog::error("while closing the output files: {}", error.what());
    exit_code = exit_code == 0 ? 1 : exit_code;
  }
  goodbye.set_steps(step);
  goodbye.set_compute_seconds(compute_seconds);
  goodbye.set_checkpoint_seconds(checkpoint_seconds);
  goodbye.set_wait_seconds(link.wait_seconds());
  if (exit_code != 1) {
    try {
      goodbye.set_results_json(solver.results());
    } catch (const std::exception& error) {
      spdlog::error("while gathering the results for summary.json: {}", error.what());
    }
    link.send_goodbye(goodbye);
  }
  spdlog::info("compute {:.3f} s, waiting for the coupler {:.3f} s", compute_seconds, link.wait_seconds());
  return exit_code;
}

int solver_main(int argc, char** argv, Role role, const SolverFactory& make) {
  const std::string program = role_name(role);
  std::optional<SolverOptions> options;
  try {
    options = parse_solver_command_line(argc, argv, program);
    if (!options) return 0;
    setup_logging(program, options->log_level);
  } catch (const std::exception& error) {
    fmt::print(stderr, "{}\n", error.what());
    return 2;
  }
  install_stop_handlers();
  try {
    const scene::Scene scene = scene::load_scene(options->scene);
    auto solver = make(scene, *options);
    return run_solver(*solver, scene, *options, role);
  } catch (const SceneError& error) {
    spdlog::error("{}", error.what());
    return 2;
  } catch (const FileError& error) {  // a checkpoint given with --resume that does not fit
    spdlog::error("{}", error.what());
    return 2;
  } catch (const std::exception& error) {
    spdlog::error("{}", error.what());
    return 1;
  }
}

}  // namespace sabo::solver
