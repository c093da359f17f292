// sabo_replay: replay recorded interface traffic (traffic.h5) against one process and compare what it sends
// with the recording, field by field (docs/traffic.md, "Replay"). `./sabo replay RUN_DIR ROLE` starts it
// with the process to check; it can also be run by hand:
//   sabo_replay scene  --traffic FILE                   the recorded scene's text on stdout
//   sabo_replay solver --traffic FILE --role ROLE --endpoint E [--tolerance FIELD=RTOL[:ATOL]]... [--json FILE]
//                      [--take FIELD...]
//       plays the coupler for one solver: the solver registers at E, gets the recorded StepForces of every
//       step in order, and each StepState it sends is compared with the recorded one; --take also sends the
//       recorded values of those state fields (StepForces.taken), which the solver puts in place of its own
//   sabo_replay coupler --traffic FILE --endpoint E [--tolerance ...] [--json FILE] [--resume CHECKPOINT]
//       plays every solver for a coupler bound at E: the recorded registrations and StepStates go in, each
//       StepForces that comes back is compared with the recorded one (from the checkpoint's step with --resume,
//       the coupler started from that checkpoint)
// Exit status: 0 everything matches, 1 a divergence (the first is printed, then a table per field), 2 bad
// input (a recording that lacks what replay needs, a command line error), 3 the process failed or went silent.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <fstream>
#include <iostream>
#include <set>

#include "libsabo/core/error.hpp"
#include "libsabo/core/signals.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "libsabo/io/traffic.hpp"
#include "libsabo/protocol/message_compare.hpp"
#include "libsabo/protocol/socket.hpp"
#include "libsabo/protocol/walls_ahead.hpp"

namespace {

using namespace sabo;
using Clock = std::chrono::steady_clock;
constexpr int kMatches = 0, kDiverges = 1, kBadInput = 2, kProcessFailed = 3;

std::map<std::string, protocol::Tolerance> parse_tolerances(const std::vector<std::string>& specs) {
  std::map<std::string, protocol::Tolerance> out;
  std::set<std::string> known(protocol::compared_state_fields().begin(), protocol::compared_state_fields().end());
  known.insert(protocol::compared_forces_fields().begin(), protocol::compared_forces_fields().end());
  for (const std::string& spec : specs) {
    const auto equals = spec.find('=');
    const std::string field = spec.substr(0, equals);
    if (equals == std::string::npos || !known.count(field)) {
      throw Error(fmt::format("--tolerance {}: expected FIELD=RTOL or FIELD=RTOL:ATOL with FIELD one of {}", spec,
                              fmt::join(known, ", ")));
    }
    const std::string values = spec.substr(equals + 1);
    const auto colon = values.find(':');
    try {
      protocol::Tolerance t;
      t.rtol = std::stod(values.substr(0, colon));
      if (colon != std::string::npos) t.atol = std::stod(values.substr(colon + 1));
      if (!(t.rtol >= 0) || !(t.atol >= 0)) throw std::invalid_argument("negative");
      out[field] = t;
    } catch (const std::exception&) {
      throw Error(fmt::format("--tolerance {}: the tolerances must be numbers >= 0, e.g. position=1e-12:1e-15", spec));
    }
  }
  return out;
}

// The recorded steps of a role, checked to be every step from 0 without a gap.
std::vector<std::uint64_t> contiguous_steps(const io::TrafficReader& traffic, const std::string& role) {
  const auto states = traffic.steps(role), forces = traffic.force_steps(role);
  if (states.empty()) throw FileError(fmt::format("the recording holds no state of {}", role));
  for (std::size_t k = 0; k < states.size(); ++k) {
    if (states[k] != k || k >= forces.size() || forces[k] != k) {
      throw FileError(fmt::format(
          "the recording of {} is not every step from 0 (a gap at step {}): replay needs them all. Fix: record "
          "the run again with [recording] every = 1 and no first_step",
          role, k));
    }
  }
  return states;
}

// Replay drives a process with recorded messages: those must hold every field that drives it.
void require_fields(const io::TrafficReader& traffic, const std::vector<std::string>& needed, const char* why) {
  const auto fields = traffic.recorded_fields();
  std::vector<std::string> missing;
  for (const auto& name : needed) {
    if (std::find(fields.begin(), fields.end(), name) == fields.end()) missing.push_back(name);
  }
  if (!missing.empty()) {
    throw FileError(
        fmt::format("the recording lacks the field(s) {} that {}. Fix: record the run again with "
                    "[recording] fields = [] (all)",
                    fmt::join(missing, ", "), why));
  }
}

// The StepState fields this solver sends that the recording left out (its [recording] fields), by the names
// the comparison uses.
std::set<std::string> unrecorded_state_fields(const io::TrafficReader& traffic, const sabo::v1::Register& solver) {
  const auto recorded = traffic.recorded_fields();
  const auto has = [&](const char* name) {
    return std::find(recorded.begin(), recorded.end(), name) != recorded.end();
  };
  std::vector<std::string> sent{"energies"};
  if (solver.exposes_particles()) sent.insert(sent.end(), {"position", "velocity"});
  if (solver.exposes_angular_velocity()) sent.push_back("angular_velocity");
  if (solver.exposes_surface()) sent.insert(sent.end(), {"node_position", "node_velocity"});
  if (sabo::protocol::from_wire(solver.role()) == sabo::Role::sph) sent.push_back("boundary_force");
  std::set<std::string> out;
  for (const auto& name : sent) {
    if (!has(name.c_str())) out.insert(name);
  }
  if (out.count("boundary_force")) out.insert("boundary_step");
  if (!has("position") && !has("velocity") && !has("angular_velocity")) out.insert("index");
  return out;
}

void finish_report(const protocol::MessageComparison& comparison, const std::string& json_file,
                   const std::string& process, const std::string& failure) {
  std::cout << comparison.report();
  if (!failure.empty()) std::cout << process << ": " << failure << "\n";
  if (!json_file.empty()) {
    nlohmann::json j = comparison.json();
    j["process"] = process;
    j["failure"] = failure;
    std::ofstream(json_file) << j.dump(2) << "\n";
  }
}

// Plays the coupler for one solver.
// The steps up to `until` (a window's last step), or all; FileError when the recording has none of them.
std::vector<std::uint64_t> up_to(std::vector<std::uint64_t> steps, std::optional<std::uint64_t> until) {
  if (!until) return steps;
  if (steps.empty() || *until < steps.front()) {
    throw FileError(fmt::format("--until {}: the recording's steps start at {}", *until,
                                steps.empty() ? std::string("(none)") : std::to_string(steps.front())));
  }
  steps.erase(std::upper_bound(steps.begin(), steps.end(), *until), steps.end());
  return steps;
}

// The steps (every one from 0, contiguous_steps) from a checkpoint's step on, or all; FileError when the replay
// of `who` ends before it.
std::vector<std::uint64_t> from_step(std::vector<std::uint64_t> steps, std::optional<std::uint64_t> resume_step,
                                     const std::string& who) {
  if (!resume_step) return steps;
  if (*resume_step > steps.back()) {
    throw FileError(
        fmt::format("the checkpoint is of step {}, the replay of {} ends at step {}", *resume_step, who, steps.back()));
  }
  steps.erase(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(*resume_step));
  return steps;
}

// The state fields `--take` can feed to a solver of `role`: what it moves (the rest of a StepState is computed
// from those: energies, stable_dt, boundary forces).
std::vector<std::string> takeable_fields(Role role) {
  switch (role) {
    case Role::dem: return {"position", "velocity", "angular_velocity"};
    case Role::fem: return {"node_position", "node_velocity"};
    default: return {"position", "velocity"};
  }
}

void check_taken_fields(const io::TrafficReader& traffic, Role role, const std::set<std::string>& taken) {
  const auto takeable = takeable_fields(role);
  for (const auto& field : taken) {
    if (std::find(takeable.begin(), takeable.end(), field) == takeable.end()) {
      throw Error(
          fmt::format("--take {}: the {} takes {} (the fields of its state that it moves; the others are "
                      "computed from them)",
                      field, role_name(role), fmt::join(takeable, ", ")));
    }
  }
  require_fields(traffic, {taken.begin(), taken.end()}, "--take feeds to the solver");
}

// The surface node ids of the recorded topology in force at `step`: the registration's, or the last one a
// state up to `step` carried.
std::vector<std::uint64_t> recorded_node_ids(const io::TrafficReader& traffic, const std::string& role,
                                             const sabo::v1::Register& registration, std::uint64_t step) {
  std::vector<std::uint64_t> ids(registration.surface().node_id().begin(), registration.surface().node_id().end());
  for (std::uint64_t s = 0; s <= step; ++s) {
    const sabo::v1::StepState state = traffic.state(role, s);
    if (state.has_topology()) ids.assign(state.topology().node_id().begin(), state.topology().node_id().end());
  }
  return ids;
}

// StepForces.taken for the exchange that leads to the recorded state `next`: its fields named in `taken`.
sabo::v1::StepState taken_state(const sabo::v1::StepState& next, const std::set<std::string>& taken,
                                const std::vector<std::uint64_t>& node_ids) {
  sabo::v1::StepState out;
  out.set_step(next.step());
  out.set_time(next.time());
  const auto has = [&](const char* field) { return taken.count(field) != 0; };
  if (has("position") || has("velocity") || has("angular_velocity")) {
    *out.mutable_index() = next.index();
    if (has("position")) *out.mutable_position() = next.position();
    if (has("velocity")) *out.mutable_velocity() = next.velocity();
    if (has("angular_velocity")) *out.mutable_angular_velocity() = next.angular_velocity();
  }
  const bool nodes_sent = next.node_position_size() > 0;  // empty: unchanged (rigid parts only)
  if (nodes_sent && (has("node_position") || has("node_velocity"))) {
    out.mutable_topology()->mutable_node_id()->Assign(node_ids.begin(), node_ids.end());
    if (has("node_position")) *out.mutable_node_position() = next.node_position();
    if (has("node_velocity")) *out.mutable_node_velocity() = next.node_velocity();
  }
  return out;
}

int replay_solver(const io::TrafficReader& traffic, const std::string& role, const std::string& endpoint,
                  protocol::MessageComparison& comparison, const std::string& json_file, double timeout_s,
                  std::optional<std::uint64_t> resume_step, std::optional<std::uint64_t> until,
                  const std::set<std::string>& taken) {
  auto steps = up_to(contiguous_steps(traffic, role), until);
  // A solver restarted from its checkpoint of step n: the recording from step n on, as a coupler's catch-up.
  steps = from_step(std::move(steps), resume_step, role);
  const std::optional<Role> solver_role = role_from_name(role);
  require_fields(traffic,
                 solver_role == Role::fem   ? std::vector<std::string>{"node_force"}
                 : solver_role == Role::sph ? std::vector<std::string>{"force", "boundary_particles"}
                                            : std::vector<std::string>{"force", "torque"},
                 "drive the solver");
  const sabo::v1::Register recorded_registration = traffic.registration(role);
  comparison.skip(unrecorded_state_fields(traffic, recorded_registration));
  std::vector<std::uint64_t> node_ids;
  if (!taken.empty()) {
    check_taken_fields(traffic, solver_role.value_or(Role::sph), taken);
    comparison.set_taken(taken);
    if (taken.count("node_position") || taken.count("node_velocity")) {
      node_ids = recorded_node_ids(traffic, role, recorded_registration, steps.front());
    }
  }
  zmq::context_t context(1);
  protocol::Socket socket(context, zmq::socket_type::router);
  socket.bind(endpoint);
  std::cerr << "replay: listening on " << socket.endpoint() << " for the " << role << "\n";
  protocol::Inbound inbound;
  const auto wait = [&](sabo::v1::MessageType type, const std::string& what) {
    const auto deadline = Clock::now() + std::chrono::milliseconds(static_cast<long>(1000 * timeout_s));
    while (Clock::now() < deadline) {
      if (stop_requested()) throw StopRequested("replay stopped by a signal");
      if (!socket.receive(inbound, std::chrono::milliseconds(100))) continue;
      if (!inbound.valid()) continue;
      if (inbound.header.type == sabo::v1::MESSAGE_TYPE_ERROR) {
        sabo::v1::Error error;
        inbound.parse(error);
        throw ProtocolError(fmt::format("sent an Error while the replay expected {}: {}", what, error.message()));
      }
      if (inbound.header.type == sabo::v1::MESSAGE_TYPE_GOODBYE && type != sabo::v1::MESSAGE_TYPE_GOODBYE) {
        throw ProtocolError(fmt::format("left (Goodbye) while the replay expected {}", what));
      }
      if (inbound.header.type == type) return;
    }
    throw ProtocolError(fmt::format("did not send {} within {} s", what, timeout_s));
  };
  std::string failure;
  try {
    wait(sabo::v1::MESSAGE_TYPE_REGISTER, "its registration");
    const std::string peer = inbound.peer;
    sabo::v1::Register registration;
    inbound.parse(registration);
    if (registration.role() != recorded_registration.role()) {
      throw ProtocolError(
          fmt::format("registered as role {}, the recording is of {}", static_cast<int>(registration.role()), role));
    }
    if (resume_step && (!registration.resumed() || registration.resume_step() != *resume_step)) {
      throw ProtocolError(fmt::format("registered {}, the replay expected a solver resumed at step {}",
                                      registration.resumed()
                                          ? fmt::format("as resumed at step {}", registration.resume_step())
                                          : std::string("as a fresh start"),
                                      *resume_step));
    }
    if (registration.particles().SerializeAsString() != recorded_registration.particles().SerializeAsString() ||
        registration.surface().SerializeAsString() != recorded_registration.surface().SerializeAsString()) {
      std::cout << "the registration differs from the recorded one (particle table or surface)\n";
    }
    sabo::v1::RegisterReply reply;
    reply.set_accepted(true);
    reply.set_protocol_version(protocol::kProtocolVersion);
    reply.set_interest_all(true);
    if (!taken.empty() && !registration.takes_state()) {
      throw Error(
          fmt::format("--take: the {} cannot take recorded fields (its registration says takes_state = "
                      "false; docs/adding-a-solver.md says what a solver implements for it)",
                      role));
    }
    socket.send(reply, peer);
    sabo::v1::StepState recorded = traffic.state(role, steps.front());
    for (std::size_t k = 0; k < steps.size(); ++k) {
      const std::uint64_t step = steps[k];
      wait(sabo::v1::MESSAGE_TYPE_STEP_STATE, fmt::format("the state of step {}", step));
      sabo::v1::StepState state;
      inbound.parse(state);
      comparison.compare_states(recorded_registration, recorded, state);
      sabo::v1::StepForces forces = traffic.forces(role, step);
      if (step == steps.back()) forces.set_stop(true);  // a recording (or a window) that ends before the run did
      if (k + 1 < steps.size()) {
        sabo::v1::StepState next = traffic.state(role, steps[k + 1]);
        if (!taken.empty()) {
          if (next.has_topology()) node_ids.assign(next.topology().node_id().begin(), next.topology().node_id().end());
          *forces.mutable_taken() = taken_state(next, taken, node_ids);
        }
        recorded = std::move(next);
      }
      socket.send(forces, peer);
    }
    wait(sabo::v1::MESSAGE_TYPE_GOODBYE, "its Goodbye");
  } catch (const ProtocolError& error) {
    failure = error.what();
  }
  finish_report(comparison, json_file, role, failure);
  if (!failure.empty()) return kProcessFailed;
  return comparison.matches() ? kMatches : kDiverges;
}

// Plays every solver for a coupler.
int replay_coupler(const io::TrafficReader& traffic, const std::string& endpoint,
                   protocol::MessageComparison& comparison, const std::string& json_file, double timeout_s,
                   std::optional<std::uint64_t> resume_step, std::optional<std::uint64_t> until,
                   const std::vector<std::string>& played) {
  // The solvers played from the recording: all, or those named (the others run live against the coupler).
  std::vector<std::string> roles = traffic.roles();
  if (!played.empty()) {
    for (const auto& role : played) {
      if (std::find(roles.begin(), roles.end(), role) == roles.end()) {
        throw FileError(
            fmt::format("--play {}: the recording has no such role (it has {})", role, fmt::join(roles, ", ")));
      }
    }
    roles = played;
  }
  require_fields(traffic, io::traffic_field_names(), "the coupler computes from");
  std::vector<std::uint64_t> steps;
  for (const auto& role : roles) {
    const auto s = contiguous_steps(traffic, role);
    steps = steps.empty() ? s : (s.size() < steps.size() ? s : steps);
  }
  steps = up_to(std::move(steps), until);
  // A coupler resumed from its checkpoint of step n: the solvers register resumed there and send from step n.
  steps = from_step(std::move(steps), resume_step, "the coupler");
  zmq::context_t context(1);
  struct Solver {
    std::string role;
    sabo::v1::Register registration;
    std::unique_ptr<protocol::Socket> socket;
  };
  std::vector<Solver> solvers;
  for (const auto& role : roles) {
    Solver s{role, traffic.registration(role), std::make_unique<protocol::Socket>(context, zmq::socket_type::dealer)};
    if (resume_step) {
      s.registration.set_resumed(true);
      s.registration.set_resume_step(*resume_step);
    }
    s.socket->connect(endpoint);
    solvers.push_back(std::move(s));
  }
  protocol::Inbound inbound;
  const auto wait = [&](protocol::Socket& socket, sabo::v1::MessageType type, const std::string& what) {
    const auto deadline = Clock::now() + std::chrono::milliseconds(static_cast<long>(1000 * timeout_s));
    while (Clock::now() < deadline) {
      if (stop_requested()) throw StopRequested("replay stopped by a signal");
      if (!socket.receive(inbound, std::chrono::milliseconds(100)) || !inbound.valid()) continue;
      if (inbound.header.type == sabo::v1::MESSAGE_TYPE_STOP)
        throw ProtocolError(fmt::format("sent Stop while the replay expected {}", what));
      if (inbound.header.type == sabo::v1::MESSAGE_TYPE_ERROR) {
        sabo::v1::Error error;
        inbound.parse(error);
        throw ProtocolError(fmt::format("sent an Error while the replay expected {}: {}", what, error.message()));
      }
      if (inbound.header.type == type) return;
    }
    throw ProtocolError(fmt::format("did not send {} within {} s", what, timeout_s));
  };
  std::string failure;
  try {
    for (auto& s : solvers) {
      s.socket->send(s.registration);
      wait(*s.socket, sabo::v1::MESSAGE_TYPE_REGISTER_REPLY,
           fmt::format("the answer to the registration of {}", s.role));
      sabo::v1::RegisterReply reply;
      inbound.parse(reply);
      if (!reply.accepted())
        throw ProtocolError(fmt::format("refused the recorded registration of {}: {}", s.role, reply.error()));
    }
    bool stopped = false;
    for (const std::uint64_t step : steps) {
      for (auto& s : solvers) s.socket->send(traffic.state(s.role, step));
      for (auto& s : solvers) {
        wait(*s.socket, sabo::v1::MESSAGE_TYPE_STEP_FORCES, fmt::format("the forces of step {} for {}", step, s.role));
        sabo::v1::StepForces forces;
        inbound.parse(forces);
        if (forces.walls_ahead()) {
          // Walls ahead: the step's own StepForces follows; compared as the one StepForces the recording holds.
          sabo::v1::StepForces rest;
          wait(*s.socket, sabo::v1::MESSAGE_TYPE_STEP_FORCES,
               fmt::format("the forces of step {} for {} after its walls", step, s.role));
          inbound.parse(rest);
          if (rest.walls_ahead() || rest.step() != forces.step()) {
            throw ProtocolError(
                fmt::format("sent walls ahead for step {} to {}, then no forces of that step", step, s.role));
          }
          protocol::move_boundary_particles(forces, rest);
          forces = std::move(rest);
        }
        comparison.compare_forces(s.registration, traffic.forces(s.role, step), forces);
        stopped = stopped || forces.stop();
      }
      if (stopped) break;
    }
    sabo::v1::Goodbye goodbye;
    goodbye.set_reason("replay ended");
    for (auto& s : solvers) s.socket->send(goodbye);
  } catch (const ProtocolError& error) {
    failure = error.what();
  }
  finish_report(comparison, json_file, "coupler", failure);
  if (!failure.empty()) return kProcessFailed;
  return comparison.matches() ? kMatches : kDiverges;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("sabo_replay: replay traffic.h5 against one process and compare, field by field", "sabo_replay");
  std::string traffic_file, role, endpoint, json_file;
  std::optional<std::uint64_t> until;
  std::vector<std::string> tolerances;
  double timeout_s = 60;
  auto* scene = app.add_subcommand("scene", "print the recorded scene");
  scene->add_option("--traffic", traffic_file, "traffic.h5 of a run folder")->required();
  auto* solver = app.add_subcommand("solver", "play the coupler for one solver");
  auto* coupler = app.add_subcommand("coupler", "play every solver for a coupler");
  for (auto* sub : {solver, coupler}) {
    sub->add_option("--traffic", traffic_file, "traffic.h5 of a run folder")->required();
    sub->add_option("--endpoint", endpoint, "ZeroMQ endpoint (the solver connects to it; the coupler binds it)")
        ->required();
    sub->add_option("--tolerance", tolerances, "FIELD=RTOL[:ATOL], repeatable (default: exact)");
    sub->add_option("--json", json_file, "also write the report as JSON to this file");
    sub->add_option("--timeout", timeout_s, "seconds to wait for any one message")->capture_default_str();
    sub->add_option("--until", until, "the last step to replay (the end of a --steps window)");
  }
  solver->add_option("--role", role, "sph_solver, dem_solver or fem_solver")->required();
  std::vector<std::string> taken;
  solver->add_option("--take", taken,
                     "state fields fed to the solver from the recording at every step in place of its own "
                     "(position, velocity, angular_velocity; node_position, node_velocity)");
  std::vector<std::string> played;
  coupler->add_option("--play", played,
                      "the roles to play from the recording (default: every one; the others run live)");
  std::string resume_file;
  solver->add_option("--resume", resume_file,
                     "the checkpoint the solver was started from (--resume of the solver): replay from its step");
  coupler->add_option("--resume", resume_file,
                      "the checkpoint the coupler was started from (--resume of the coupler): the played solvers "
                      "register resumed at its step and the replay runs from there");
  app.require_subcommand(1);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& help) {
    return app.exit(help);
  } catch (const CLI::ParseError& error) {
    fmt::print(stderr, "sabo_replay: {}. Run 'sabo_replay --help' for the commands.\n", error.what());
    return kBadInput;
  }
  install_stop_handlers();
  try {
    const io::TrafficReader traffic(traffic_file);
    if (scene->parsed()) {
      std::cout << traffic.scene_text();
      return 0;
    }
    protocol::MessageComparison comparison(parse_tolerances(tolerances));
    std::optional<std::uint64_t> resume_step;
    if (!resume_file.empty()) {
      try {
        resume_step = io::checkpoint_step(io::hdf5::File::open(resume_file));
      } catch (const std::exception& error) {
        fmt::print(stderr, "sabo_replay: --resume {}: not a checkpoint Sabo wrote ({})\n", resume_file, error.what());
        return kBadInput;
      }
    }
    if (solver->parsed()) {
      return replay_solver(traffic, role, endpoint, comparison, json_file, timeout_s, resume_step, until,
                           {taken.begin(), taken.end()});
    }
    return replay_coupler(traffic, endpoint, comparison, json_file, timeout_s, resume_step, until, played);
  } catch (const StopRequested& stop) {
    fmt::print(stderr, "sabo_replay: {}\n", stop.what());
    return 130;
  } catch (const FileError& error) {
    fmt::print(stderr, "sabo_replay: {}: {}\n", traffic_file, error.what());
    return kBadInput;
  } catch (const std::exception& error) {
    fmt::print(stderr, "sabo_replay: {}\n", error.what());
    return kBadInput;
  }
}
