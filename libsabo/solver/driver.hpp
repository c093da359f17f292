#pragma once
// The lock-step loop every solver process runs (docs/design.md, "An explicit, lock-step step"), written once.
// A solver implements CoupledSolver; run_solver() does the protocol, timing,
// signals and error reporting.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "libsabo/io/hdf5.hpp"
#include "libsabo/scene/scene.hpp"
#include "libsabo/solver/stability.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::solver {

// The most steps a built solver takes per exchange with held forces (multirate).
inline constexpr std::uint32_t kMaxSubsteps = 64;

// Interest regions received from the coupler: only entities inside need to be sent.
class Interest {
 public:
  void update(const google::protobuf::RepeatedPtrField<sabo::v1::Box>& boxes, bool all);
  [[nodiscard]] bool all() const { return all_; }
  [[nodiscard]] bool contains(const Vec3& point) const;
  // In and out of a checkpoint: the regions of the next step are part of the solver's state.
  void save(io::hdf5::Group& group) const;
  void load(const io::hdf5::Group& group);

 private:
  bool all_ = true;
  std::vector<Aabb> boxes_;
  Aabb bounds_;  // of boxes_
};

// The contract of one solver step. At step n the solver holds positions x_n and
// half-step velocities v_{n-1/2}. run_solver() calls, in this order:
//   1. stable_dt() and fill_state(): the state at x_n sent to the coupler;
//   2. compute_internal_forces(dt_{n-1}) while the coupler computes contacts
//      (dt_{n-1} is the step that led to x_n, 0 at n = 0);
//   3. apply_coupling_forces(): the contact forces received for step n;
//   4. write_output() when the coupler asks for output at t_n;
//   5. integrate(dt_{n-1}, dt_n): v_{n+1/2}, x_{n+1} (skipped on the last step), then
//      check_stability(): the state it reached, judged against the scene's limits (stability.hpp); a
//      finding stops the solver with InstabilityError after write_instability() wrote the culprits.
//   5b. take_state() when StepForces carries `taken` (replay with --take only, never in a run): the
//      recorded values of the named fields replace the solver's own, as the state of step n + 1;
//   6. save_checkpoint() when StepForces.checkpoint is set (after integrate:
//      the state a restart resumes from at step n + 1, docs/restart.md). The
//      driver writes step, time, dt_n and the interest regions beside it.
// Multirate (docs/protocol.md, "Multirate"): with StepForces.substeps = m > 1, step 5 is followed
// by m - 1 further steps, each compute_internal_forces(dt_n), apply_coupling_forces() with the
// same forces (held) and integrate(dt_n, dt_n); the next state is at t_n + m dt_n. A solver
// whose held inputs would not be exact over several steps says so with max_substeps() = 1.
// Hold exchanges (docs/protocol.md): with StepForces.holds = h > 0 the next h exchanges are holds
// (StepForces.hold): the driver answers each at once without a step (no compute_internal_forces, no
// integrate), sending held StepStates (the first with the energies of the step just taken); its next whole
// StepState after them is followed by compute_internal_forces as at any step. A checkpoint is written at
// the last hold only (the state of the exchange after it). A solver that can hold says so with can_hold()
// (by default: one that can take several steps per exchange).
// Walls ahead (docs/protocol.md): a solver that takes_walls_ahead() may get, after sending its state and
// before step 3, a StepForces carrying only the step's boundary particles (StepForces.walls_ahead):
// take_walls_ahead() computes with them while the coupler computes its other pairs, and the step's
// apply_coupling_forces() then gets a StepForces without them (the driver refuses one with them). A solver
// that registered it must also take the boundary particles inside the step's StepForces (a replay, a
// restart's catch-up send them so).
// A solver started with --resume FILE is built from the scene as usual, then
// load_checkpoint() puts it back at step n + 1: from there it must produce
// the same bits as the process that wrote the file.
class CoupledSolver {
 public:
  virtual ~CoupledSolver() = default;
  // Registration: role, what the solver exposes, particle table or surface.
  virtual void describe(sabo::v1::Register& registration) = 0;
  virtual double stable_dt() = 0;
  // Fills positions, velocities (and topology/table changes) of the entities
  // inside `interest`, plus the energies. Step, time and stable dt are set by the driver.
  virtual void fill_state(const Interest& interest, sabo::v1::StepState& state) = 0;
  virtual void compute_internal_forces(double dt_previous) = 0;
  virtual void apply_coupling_forces(const sabo::v1::StepForces& forces) = 0;
  virtual void write_output(std::uint64_t step, double time) = 0;
  virtual void integrate(double dt_previous, double dt) = 0;
  // What is wrong with the state integrate() reached (stability.hpp), or nullopt; called after every step.
  [[nodiscard]] virtual std::optional<Instability> check_stability() const { return std::nullopt; }
  // Writes the culprits of `instability` and their neighbours into `file` (write_instability of stability.hpp).
  virtual void write_instability(const Instability& /*instability*/, const std::filesystem::path& /*file*/) const {}
  // The most steps this solver takes per exchange with held forces (1: lock-step).
  [[nodiscard]] virtual std::uint32_t max_substeps() const { return 1; }
  // Whether it may answer hold exchanges (step less often than it exchanges).
  [[nodiscard]] virtual bool can_hold() const { return max_substeps() > 1; }
  // Walls ahead: whether it takes a step's boundary particles ahead of its forces, and taking them.
  [[nodiscard]] virtual bool takes_walls_ahead() const { return false; }
  virtual void take_walls_ahead(const sabo::v1::StepForces& /*walls*/) {}
  // Restarts: a solver that can write its whole state says so; save writes it into `group`, load
  // restores it from a group that save wrote for the same scene (FileError otherwise).
  [[nodiscard]] virtual bool can_checkpoint() const { return false; }
  virtual void save_checkpoint(io::hdf5::Group& /*group*/) const {}
  virtual void load_checkpoint(const io::hdf5::Group& /*group*/) {}
  // Replay (`./sabo replay --take FIELD`): a solver that can put recorded values in place of its own state
  // says so; take_state overwrites the fields `recorded` holds (StepForces.taken of sabo.proto says which
  // entities they are), ProtocolError for values that do not fit its entities.
  [[nodiscard]] virtual bool can_take_state() const { return false; }
  virtual void take_state(const sabo::v1::StepState& /*recorded*/) {}
  // The solver's own results at the end of a run, a JSON object for summary.json's results.ROLE (Goodbye
  // results_json); empty: none.
  [[nodiscard]] virtual std::string results() const { return {}; }
  // Called once at the end, also after errors: close files.
  virtual void finish() = 0;
};

// Energies of the solver at the previous step (J), for the coupler's balance:
// kinetic, gravitational potential, internal elastic, accumulated dissipation.
struct EnergyReport {
  double kinetic = 0, potential = 0, elastic = 0, dissipated = 0;
  double inflow = 0;  // J, accumulated: brought in from outside the scene (Energies.inflow)
};
void set_energies(sabo::v1::StepState& state, const EnergyReport& energies);

// The particles of a particle solver (DEM spheres, SPH particles), by id.
struct ParticleStates {
  std::span<const Vec3> position;            // m
  std::span<const Vec3> velocity;            // m/s
  std::span<const Vec3> angular_velocity{};  // rad/s; empty: not exposed
  std::span<const std::uint8_t> active{};    // empty: all active; 0: taken out, never sent
};
// Appends index, position, velocity (and angular velocity) of the active
// particles inside `interest` to `state`.
void add_particle_states(const Interest& interest, const ParticleStates& particles, sabo::v1::StepState& state);
// take_state of a particle solver: writes the fields `recorded` holds (position, velocity, angular_velocity:
// each empty or 3 per index) into the spans, by index; ProtocolError when an index or an array does not fit
// (a field the solver has no span for, empty here, is one that does not fit).
void take_particle_states(const sabo::v1::StepState& recorded, std::span<Vec3> position, std::span<Vec3> velocity,
                          std::span<Vec3> angular_velocity = {});

struct SolverOptions {
  std::filesystem::path scene;
  std::string coupler_endpoint;
  std::filesystem::path out_dir = ".";
  std::string log_level = "info";
  std::filesystem::path resume;  // a checkpoint file to start from; empty: start at step 0
  std::filesystem::path keys;    // the run's key set (libsabo/protocol/security.hpp); empty: none
};

// Parses the command line shared by every solver:
//   <solver> --scene FILE --coupler ENDPOINT [--out DIR] [--log-level L] [--resume CHECKPOINT]
// Returns nullopt after printing help; throws sabo::Error on a bad command line.
std::optional<SolverOptions> parse_solver_command_line(int argc, char** argv, const std::string& program);

// Runs the coupled loop until the coupler says stop. Returns the process exit
// code: 0 done, 130 stopped by signal or by the coupler's Stop, 1 on errors
// (logged, and reported to the coupler when possible).
int run_solver(CoupledSolver& solver, const scene::Scene& scene, const SolverOptions& options, Role role);

// main() of the solver of `role` (its program is role_name(role)): parses the command line, sets up logging, loads the
// scene, builds the solver with `make` and runs it. Every error becomes a log
// line and an exit code (2: bad scene or command line).
using SolverFactory =
    std::function<std::unique_ptr<CoupledSolver>(const scene::Scene& scene, const SolverOptions& options)>;
int solver_main(int argc, char** argv, Role role, const SolverFactory& make);

}  // namespace sabo::solver
