// [run], [solvers] and [recording]: the schema of the section and its reader.

#include "libsabo/scene/detail/builder.hpp"
#include "libsabo/scene/detail/schema_tables.hpp"

namespace sabo::scene::schema::detail {

void Schema::build_run() {
  run.title = "[run]";
  run.anchor = "run";
  run.description = "Run control: how long, how often to write output, how the processes talk.";
  run.keys = {
      K("end_time", Type::number).required("10.0").unit("s").gt(0).doc("Simulated time at which the run ends."),
      K("output_interval", Type::number)
          .required("0.1")
          .unit("s")
          .gt(0)
          .doc("Simulated time between two output frames (VTK, forces.csv)."),
      K("endpoint", Type::string)
          .def(RunSettings{}.endpoint)
          .allowed("`\"ipc\"`, `\"tcp\"` or `\"tcp://HOST:PORT\"`")
          .doc("Where the coupler listens: `ipc` is a socket in the run folder (a folder only you can enter); "
               "`tcp` is this machine's loopback (127.0.0.1) at a free port; `tcp://HOST:PORT` listens on the "
               "address HOST of this machine, so that solvers on other hosts can join (PORT 1-65535, or `*` for a "
               "free one; `tcp://0.0.0.0:PORT` for every interface). Over tcp every connection is authenticated "
               "and encrypted (`tcp_security`; docs/security.md)."),
      K("tcp_security", Type::string)
          .def(RunSettings{}.tcp_security)
          .doc("`\"curve\"`: over tcp the coupler accepts only processes that hold this run's keys (ZeroMQ CURVE: "
               "authenticated and encrypted; the supervisor makes the keys in `RUN_DIR/keys`). `\"none\"`: no "
               "authentication and no encryption: any process that reaches the port can join the run, read its "
               "state and send forces; said in the log and in summary.json."),
      K("heartbeat_timeout", Type::number)
          .def(RunSettings{}.heartbeat_timeout)
          .unit("s")
          .gt(0)
          .doc("A connection on which nothing is heard this long (ZMTP heartbeats every fifth of it) is closed: a "
               "solver whose host vanished or whose process stopped is declared lost, and the run stops or "
               "restarts it (`restart`)."),
      K("connect_host", Type::string)
          .absent("the endpoint's address (this machine's host name for `0.0.0.0`)")
          .example("\"head-node.cluster\"")
          .doc("The host name or address that solvers started through a `launcher` connect to, when they run on "
               "another host."),
      K("gravity", Type::vec3).def(RunSettings{}.gravity).unit("m/s^2").doc("Gravitational acceleration (z is up)."),
      K("hang_timeout", Type::number)
          .def(RunSettings{}.hang_timeout)
          .unit("s")
          .gt(0)
          .doc("Wall time after which a silent process is declared hung and the run is stopped."),
      K("registration_timeout", Type::number)
          .def(RunSettings{}.registration_timeout)
          .unit("s")
          .gt(0)
          .doc("Wall time the coupler waits for every solver to register before it gives up; give a solver "
               "started by hand (`by_hand`) the time to be started."),
      K("max_dt", Type::number)
          .absent("no limit")
          .example("1e-3")
          .unit("s")
          .gt(0)
          .doc("Upper bound on the coupled time step."),
      K("max_speed", Type::number)
          .absent("the sph_solver's sound speed for fluid particles; 1000 m/s, or ten times the fastest initial "
                  "velocity of the scene when that is more, for spheres and structure nodes")
          .example("200.0")
          .unit("m/s")
          .gt(0)
          .doc("Every solver checks its state after each step (docs/physics.md, \"Instability detection\"): a "
               "particle or node faster than this, or with a position or velocity that is not finite, stops the run "
               "at that step, naming the process, the step, the entities and their values, with those entities and "
               "their neighbours in `RUN_DIR/instability.vtp`."),
      K("multirate", Type::boolean)
          .def(RunSettings{}.multirate)
          .doc("Each solver at its own stable step: the exchange step is that of the slower side of each contact "
               "pair (never above the pair's own stable step), and a solver whose stable step is shorter takes the "
               "fewest steps in it that keep within its own, with the contact forces held, so that momentum is "
               "exchanged exactly "
               "(docs/architecture.md, \"Multirate\"). `false`: every solver at the smallest stable step of all "
               "(paper eq. 7). Off by default: on `debris_flow_dam` it saves 17-26 % of the wall time and moves "
               "the fluid's mean load on the dam by 1.6-9 % (docs/accuracy-cost.md), and the held forces let the "
               "energy rise by up to 2e-3 of its initial value at 8 substeps; turn it on where a structure's or a "
               "boulder's step is far below the fluid's. SPH boundary particles on a deformable structure are "
               "never held (their pair keeps its faster side's step: held, the fluid's added mass fed C1's plate "
               "until it failed)."),
      K("hold_exchanges", Type::boolean)
          .def(RunSettings{}.hold_exchanges)
          .doc("With `multirate`: a solver whose step spans several exchanges steps at the first and holds at the "
               "others (docs/protocol.md, \"Hold exchanges\"), so that the slurry steps at its own step although "
               "boulders or structures set a shorter exchange; each pair is evaluated where both its solvers step. "
               "`false`: every solver steps at every exchange (the exchange is then the finest interval of all)."),
      K("checkpoint_interval", Type::number)
          .absent("a tenth of `end_time`")
          .example("0.5")
          .unit("s")
          .ge(0)
          .doc("Simulated time between two checkpoints: every process writes its whole state at the same step "
               "into `RUN_DIR/checkpoints/<role>_<step>.h5`, from which one process is restarted while the others "
               "wait (docs/restart.md). `0`: no checkpoints."),
      K("checkpoints_kept", Type::integer)
          .def(RunSettings{}.checkpoints_kept)
          .ge(1)
          .doc("How many checkpoints of each process are kept (the newest; older ones are removed)."),
      K("restart", Type::string)
          .def(RunSettings{}.restart ? "auto" : "off")
          .allowed("`\"auto\"` or `\"off\"`")
          .doc("`\"auto\"`: a solver killed by a signal (a crash, kill -9, out of memory) is started again from its "
               "newest "
               "checkpoint while the others wait; the coupler feeds it the StepForces it was sent since then and "
               "checks that it sends the same states to the bit before it rejoins (docs/restart.md). `\"off\"`: "
               "the run stops."),
      K("max_restarts", Type::integer)
          .def(RunSettings{}.max_restarts)
          .ge(0)
          .doc("Restarts allowed per solver process in one run; one more death stops the run."),
      K("restart_journal_limit", Type::number)
          .def(RunSettings{}.restart_journal_limit)
          .unit("GB")
          .gt(0)
          .doc("Disk the coupler's restart journal of one solver may take (`RUN_DIR/checkpoints/<role>.journal`: "
               "the StepForces sent to it since its newest checkpoint, which a restart feeds it again). Past it the "
               "journal is dropped, its file emptied and a warning logged; the solver cannot be restarted until its "
               "next checkpoint. A scene whose solver takes many MB an exchange (wall particles) wants checkpoints "
               "often enough to stay below it."),
  };
}

void Schema::build_solvers() {
  solvers.title = "[solvers]";
  solvers.anchor = "solvers";
  solvers.description =
      "One table per solver role: `[solvers.sph]`, `[solvers.dem]`, `[solvers.fem]`. A role runs only when "
      "the scene's bodies need it (`[[fluids]]` need the sph_solver, `[[particles]]` the dem_solver, "
      "`[[structures]]` the fem_solver). A table for a role that no body needs is an error. A needed role without a "
      "table uses the built executable and `beta = 1.0`.";
  const std::string role_doc = "Settings of this role (see below).";
  solvers.keys = {
      K("sph", Type::table).inside(solver).absent("defaults").doc(role_doc),
      K("dem", Type::table).inside(solver).absent("defaults").doc(role_doc),
      K("fem", Type::table).inside(solver).absent("defaults").doc(role_doc),
  };
  solver.title = "[solvers.ROLE]";
  solver.anchor = "solvers-role";
  solver.description =
      "Settings of one solver process. Any program that speaks the protocol can replace the built solver.";
  solver.keys = {
      K("command", Type::string_list)
          .absent("the built executable (`sph_solver`, `dem_solver`, `fem_solver`)")
          .example("[\"/opt/my_dem/bin/dem\", \"--fast\"]")
          .doc("Program and fixed arguments that replace the built solver; the supervisor appends "
               "`--scene`, `--coupler` and `--out`. The program is an absolute path, a path relative to the "
               "scene file's folder (when it contains a `/`), or a name found on `PATH`."),
      K("launcher", Type::string_list)
          .absent("started on this machine")
          .example("[\"ssh\", \"node2\"]")
          .doc("A command that places this process, put before its command line: `[\"ssh\", \"node2\"]`, "
               "`[\"srun\", \"--het-group=1\"]`, `[\"mpirun\", \"-n\", \"1\"]`. The scene, the run folder and the "
               "built solver must be at the same paths there (a shared file system; docs/cluster.md). Needs a tcp "
               "`endpoint`."),
      K("by_hand", Type::boolean)
          .def(SolverSettings{}.by_hand)
          .doc("`true`: the supervisor does not start this role; you start it yourself, on this host or another, "
               "with `--keys` pointing at a copy of the run's keys (docs/cluster.md, \"By hand\"). The coupler "
               "waits `registration_timeout` for it. Needs a tcp `endpoint` to come from another host."),
      K("beta", Type::number)
          .def(SolverSettings{}.beta)
          .gt(0)
          .le(10)
          .doc("Safety factor on this solver's stable time step (paper eq. 7): the coupled step is "
               "`min(beta_i * stable_dt_i)`. Above 1 the steps are longer than the stable step: a warning says "
               "so, and the run may become unstable (to find where the returns stop in a study; the instability "
               "check stops such a run at the step it goes wrong)."),
  };
}

void Schema::build_recording() {
  recording.title = "[recording]";
  recording.anchor = "recording";
  recording.description = "What the coupler records into `traffic.h5`, the log that replay and restart read.";
  recording.keys = {
      K("enabled", Type::boolean).def(Recording{}.enabled).doc("Record at all."),
      K("fields", Type::string_list)
          .def(Recording{}.fields)
          .choices({"position", "velocity", "angular_velocity", "force", "torque", "node_position", "node_velocity",
                    "node_force", "energies", "boundary_particles", "boundary_force"})
          .doc("Fields to record; empty: all. `boundary_particles`: the SPH wall particles sent to the sph_solver "
               "(position, velocity, normal, acceleration, volume); `boundary_force`: the fluid's forces on them "
               "(with their `boundary_step`)."),
      K("every", Type::integer).def(Recording{}.every).ge(1).doc("Record every N-th step."),
      K("first_step", Type::integer).def(Recording{}.first_step).ge(0).doc("First recorded step."),
      K("last_step", Type::integer)
          .absent("to the end")
          .example("100000")
          .ge(0)
          .doc("Last recorded step, not before `first_step`."),
      K("flush_interval", Type::number)
          .def(Recording{}.flush_interval)
          .unit("s")
          .gt(0)
          .doc("Wall time between flushes to disk (the file stays readable after a crash)."),
  };
}

}  // namespace sabo::scene::schema::detail

namespace sabo::scene::detail {

void Builder::read_run(const toml::table& table) {
  Reader r(diag_, spec("run"), table, "run");
  RunSettings& run = scene_.run;
  if (auto v = r.number("end_time")) run.end_time = *v;
  if (auto v = r.number("output_interval")) run.output_interval = *v;
  if (auto v = r.boolean("multirate")) run.multirate = *v;
  if (auto v = r.boolean("hold_exchanges")) run.hold_exchanges = *v;
  run.endpoint_origin = origin(r.line("endpoint"), r.node("endpoint") != nullptr ? r.key_path("endpoint") : "run");
  if (auto v = r.string("endpoint")) {
    const auto address = valid_endpoint(*v) && v->starts_with("tcp://") ? ipv4_problem(*v) : std::nullopt;
    if (v->starts_with("tcp://*:")) {
      diag_.add(r.line("endpoint"), r.key_path("endpoint"), quote_text(*v),
                "'*' would listen on every interface without saying so",
                fmt::format("write endpoint = \"tcp://0.0.0.0:{}\" to listen on every interface, or \"tcp\" for this "
                            "machine only",
                            v->substr(8)));
    } else if (address) {
      diag_.add(r.line("endpoint"), r.key_path("endpoint"), quote_text(*v), *address,
                "give an address of this machine, e.g. endpoint = \"tcp://127.0.0.1:5555\" (this machine only) or "
                "\"tcp://0.0.0.0:5555\" (every interface)");
    } else if (valid_endpoint(*v)) {
      run.endpoint = *v;
    } else {
      diag_.add(r.line("endpoint"), r.key_path("endpoint"), quote_text(*v),
                "must be \"ipc\", \"tcp\" or \"tcp://HOST:PORT\"",
                "write endpoint = \"ipc\" to run on one machine, or e.g. endpoint = \"tcp://127.0.0.1:5555\"");
    }
  }
  if (auto v = r.string("tcp_security")) run.tcp_security = value_named<RunSettings::TcpSecurity>(*v);
  if (auto v = r.number("heartbeat_timeout")) run.heartbeat_timeout = *v;
  if (auto v = r.string("connect_host")) {
    if (v->empty() || v->find_first_of(" /:\t") != std::string::npos) {
      diag_.add(r.line("connect_host"), r.key_path("connect_host"), quote_text(*v), "not a host name or IPv4 address",
                "write a name or address only, e.g. connect_host = \"node1\"");
    } else {
      run.connect_host = *v;
    }
  }
  if (auto v = r.vec3("gravity")) run.gravity = *v;
  if (auto v = r.number("hang_timeout")) run.hang_timeout = *v;
  if (auto v = r.number("registration_timeout")) run.registration_timeout = *v;
  run.max_dt = r.number("max_dt");
  run.max_speed = r.number("max_speed");
  run.checkpoint_interval = r.number("checkpoint_interval");
  if (auto v = r.integer("checkpoints_kept")) run.checkpoints_kept = static_cast<std::size_t>(*v);
  if (auto v = r.string("restart")) {
    if (*v == "auto" || *v == "off") {
      run.restart = *v == "auto";
    } else {
      diag_.add(r.line("restart"), r.key_path("restart"), quote_text(*v), "must be \"auto\" or \"off\"",
                "write restart = \"auto\" to restart a solver that dies, or restart = \"off\" to stop the run");
    }
  }
  if (auto v = r.integer("max_restarts")) run.max_restarts = static_cast<std::size_t>(*v);
  if (auto v = r.number("restart_journal_limit")) run.restart_journal_limit = *v;
}

void Builder::read_solvers(Reader& root) {
  const toml::table* table = root.table("solvers");
  Reader solvers(diag_, spec("solvers"), table != nullptr ? *table : empty_table(), "solvers");
  struct RoleInfo {
    Role role;
    const char* key;
    bool needed;
    const char* bodies;
  };
  const RoleInfo roles[] = {
      {Role::sph, "sph", has_fluids_, "[[fluids]] or [[inflows]]"},
      {Role::dem, "dem", has_particles_, "[[particles]]"},
      {Role::fem, "fem", has_structures_, "[[structures]]"},
  };
  for (const RoleInfo& info : roles) {
    const toml::table* role_table = solvers.table(info.key);
    const std::string path = std::string("solvers.") + info.key;
    if (!info.needed) {
      if (role_table != nullptr) {
        diag_.add(line_of(*role_table), path, std::nullopt, fmt::format("no bodies need the {}", role_name(info.role)),
                  fmt::format("remove [{}] or add {}", path, info.bodies));
      }
      continue;
    }
    Reader r(diag_, spec("solvers-role"), role_table != nullptr ? *role_table : empty_table(), path);
    SolverSettings solver;
    solver.role = info.role;
    solver.origin = origin(r.line(), path);
    if (auto v = r.number("beta")) solver.beta = *v;
    if (auto command = r.strings("command")) {
      solver.command = *command;
      check_command(r, solver);
    }
    if (auto launcher = r.strings("launcher")) {
      if (launcher->empty() || launcher->front().empty()) {
        diag_.add(r.line("launcher"), r.key_path("launcher"), value_text(*r.node("launcher")),
                  "the launcher names no program",
                  "give the program first, e.g. launcher = [\"ssh\", \"node2\"], or remove 'launcher' to start the "
                  "process here");
      } else if (!scene_.run.endpoint.starts_with("tcp")) {
        diag_.add(r.line("launcher"), r.key_path("launcher"), value_text(*r.node("launcher")),
                  fmt::format("a launched process may run on another host, and run.endpoint = \"{}\" is a socket "
                              "of this machine",
                              scene_.run.endpoint),
                  "set [run] endpoint = \"tcp://0.0.0.0:5555\" (or the address of this machine the other hosts "
                  "reach), or remove 'launcher'");
      } else {
        solver.launcher = *launcher;
      }
    }
    if (auto by_hand = r.boolean("by_hand")) {
      solver.by_hand = *by_hand;
      if (*by_hand && (!solver.launcher.empty() || !solver.command.empty())) {
        const char* other = solver.launcher.empty() ? "command" : "launcher";
        diag_.add(r.line("by_hand"), r.key_path("by_hand"), "true",
                  fmt::format("a role started by hand is not started by the supervisor, so its '{}' would never be "
                              "used",
                              other),
                  fmt::format("remove '{}', or remove by_hand to let the supervisor start the role", other));
      }
    }
    scene_.solvers.push_back(std::move(solver));
  }
}

void Builder::check_command(Reader& r, SolverSettings& solver) {
  const int line = r.line("command");
  const std::string value = value_text(*r.node("command"));
  const std::string fallback = fmt::format("remove 'command' to run the built {}", role_name(solver.role));
  if (solver.command.empty() || solver.command.front().empty()) {
    diag_.add(line, r.key_path("command"), value, "the command names no program",
              "give the program first, e.g. command = [\"/opt/solver/bin/dem\"], or " + fallback);
    return;
  }
  const std::string& program = solver.command.front();
  if (program.find('/') != std::string::npos) {
    const fs::path given(program);
    const fs::path full = scene_relative(program);
    if (!is_executable_file(full)) {
      diag_.add(line, r.key_path("command"), value,
                given.is_absolute() ? fmt::format("program '{}' does not exist or is not executable", program)
                                    : fmt::format("program '{}' does not exist or is not executable (looked for {})",
                                                  program, full.string()),
                "give an existing executable (absolute, or relative to the scene file's folder), or " + fallback);
      return;
    }
    solver.command.front() = full.string();
    return;
  }
  const char* path_variable = std::getenv("PATH");
  std::stringstream directories(path_variable != nullptr ? path_variable : "");
  std::string directory;
  while (std::getline(directories, directory, ':')) {
    if (!directory.empty() && is_executable_file(fs::path(directory) / program)) return;
  }
  diag_.add(line, r.key_path("command"), value, fmt::format("program '{}' is not found on PATH", program),
            "give the full path of the program, add its folder to PATH, or " + fallback);
}

void Builder::read_recording(Reader& root) {
  const toml::table* table = root.table("recording");
  Reader r(diag_, spec("recording"), table != nullptr ? *table : empty_table(), "recording");
  Recording& recording = scene_.recording;
  if (auto v = r.boolean("enabled")) recording.enabled = *v;
  if (auto v = r.strings("fields")) recording.fields = *v;
  if (auto v = r.integer("every")) recording.every = static_cast<std::uint64_t>(*v);
  const auto first = r.integer("first_step");
  const auto last = r.integer("last_step");
  if (first) recording.first_step = static_cast<std::uint64_t>(*first);
  if (last) recording.last_step = static_cast<std::uint64_t>(*last);
  if (first && last && *first > *last) {
    diag_.add(r.line("last_step"), r.key_path("last_step"), std::to_string(*last),
              fmt::format("the last step comes before first_step = {}", *first),
              "give last_step >= first_step, or swap the two");
  }
  if (auto v = r.number("flush_interval")) recording.flush_interval = *v;
}

}  // namespace sabo::scene::detail
