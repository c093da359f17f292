#pragma once
// The coupler's extension point: one contact pair joins two solver roles
// (DEM-FEM, SPH-FEM, SPH-DEM) with one contact law. The coupler's loop knows
// pairs, not roles; pairs are built from the scene by make_contact_pairs()
// (pair_factory.hpp). docs/architecture.md, "Adding a contact pair", is the
// recipe.
//
// The contract of one coupling step n, in the order the coupler calls it:
//
//   start(solvers)             once, after every solver registered: the static
//                              data (particle tables, the registered surface)
//   check_state(solver)        for each state of step n of a role the pair joins,
//                              after the generic checks: what this pair needs of
//                              it (throws ProtocolError; the run ends naming
//                              the solver)
//   place_ahead(solvers, clock) only if can_place_ahead(), before the fluid's
//                              state of step n is in: places this step's
//                              boundary particles from the other side's state
//                              and what the pair kept of the fluid, so that
//                              the coupler sends them while the sph_solver
//                              integrates (compute() then places none)
//   compute(solvers, clock)    gathers what it needs of the states at x_n (and
//                              of forces a solver returned for an earlier step)
//                              and computes the contact forces of step n with
//                              v_{n-1/2}; tangential springs grow by v_t dt_{n-1}
//   stable_dt()                its term of paper eq. 7 for dt_n, beta included
//   newton_balance()           the forces it put on both sides this step
//   energy(), loads()          its springs and dissipation, its force on the
//                              structure parts (forces.csv); point_loads() the
//                              same force by point of contact (sensors.csv)
//   scatter(solvers, dt, out)  once dt_n is known: adds its forces (and
//                              torques) to BOTH sides' replies, its boundary
//                              particles to the sph_solver's (placed by
//                              compute(): boundary_particles(), which the
//                              coupler may send ahead of the other pairs)
//   interest(role)             the region of each side it needs at step n + 1
//
// History: everything that carries over from one step to the next (tangential
// springs, the boundary particles sent at the last steps) is the pair's
// history state, saved with save_history() and read back with
// restore_history(), so that a checkpoint of the coupler holds it.
//
// Determinism: compute() and scatter() are pure functions of the received
// states, the history and dt; parallel loops give the same bits for any
// number of threads.
#include <array>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "coupler/contact/point_load.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/physics/boundary_particles.hpp"
#include "libsabo/scene/scene.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::coupler {

// One registered solver as the pairs see it: its registration and its state of this step.
struct SolverView {
  Role role = Role::dem;  // its process: role_name(role)
  double beta = 1;        // eq. 7 scale of its stable step
  const sabo::v1::Register* registration = nullptr;
  const sabo::v1::StepState* state = nullptr;
};

// The registered solvers, by role.
class Solvers {
 public:
  void set(const SolverView& view) { by_role_[index(view.role)] = view; }
  [[nodiscard]] const SolverView* find(Role role) const {
    return by_role_[index(role)] ? &*by_role_[index(role)] : nullptr;
  }
  [[nodiscard]] const SolverView& at(Role role) const;  // asserts that it is registered

 private:
  static std::size_t index(Role role) { return static_cast<std::size_t>(role); }
  std::array<std::optional<SolverView>, 3> by_role_;
};

// Where a pair needs a solver's entities at the next step.
struct InterestRequest {
  bool all = false;         // every entity
  std::vector<Aabb> boxes;  // else those inside any box (none: nothing)
};

// Time of the step being coupled.
struct StepClock {
  std::uint64_t step = 0;
  double time = 0;         // s, t_n
  double dt_previous = 0;  // s, dt_{n-1} (0 at step 0)
};

// The forces one pair put on both sides this step: their sum should vanish.
struct NewtonBalance {
  Vec3 sum = Vec3::Zero();  // N, over both sides
  double scale = 0;         // N, sum of |components| on one side: the residual is |sum| / scale
};

// The SPH boundary particles of every pair that sends some (structure walls,
// boulder surfaces), one list per step, the pairs' parts in pair order. The
// forces the fluid put on them come back in a later StepState (boundary_step
// names the step); each pair reads its own part of them.
class BoundaryChannel {
 public:
  // A pair that sends boundary particles takes a slot once, at start.
  std::size_t join() { return slots_++; }
  [[nodiscard]] bool active() const { return slots_ > 0; }
  // Starts the list of a new step; the lists of the two steps before are remembered.
  void begin_step();
  // Adds a slot's particles to this step's list; `particles` must live until the list is sent.
  void append(std::size_t slot, const physics::BoundaryParticles& particles);
  // This step's list, as the pairs appended it.
  [[nodiscard]] std::size_t size() const { return layout_[0].total; }
  [[nodiscard]] const std::vector<const physics::BoundaryParticles*>& parts() const { return parts_; }
  // Particles of the list sent steps_back (1 or 2) steps before the current one (before begin_step: the
  // list of the last step is steps_back 1).
  [[nodiscard]] std::size_t sent(std::size_t steps_back) const;
  // The forces of `slot`'s particles within `returned` (3 doubles per particle of that list). Empty when
  // nothing came back.
  [[nodiscard]] std::span<const double> slice(std::size_t slot, std::span<const double> returned,
                                              std::size_t steps_back) const;
  // The layouts of the lists of the last steps, for the coupler's checkpoint: a state's boundary_force refers
  // to them. restore() after every pair joined; FileError when the saved slots are not the pairs'.
  void save(io::hdf5::Group& group) const;
  void restore(const io::hdf5::Group& group);

 private:
  struct Layout {
    std::vector<std::size_t> offset, count;  // per slot
    std::size_t total = 0;
  };
  [[nodiscard]] const Layout& layout(std::size_t steps_back) const;
  std::size_t slots_ = 0;
  std::array<Layout, 3> layout_;  // [0]: being built (or the last step's, before begin_step), [1], [2]: before
  bool begun_ = false;            // begin_step() called for the list in layout_[0]
  std::vector<const physics::BoundaryParticles*> parts_;
};

// Hold exchanges (docs/architecture.md, "Multirate"): the forces one pair put on one side at the exchange
// where it was last evaluated, by entity (particle-table index or surface node id), given again at that
// side's exchanges until the pair is evaluated again.
struct HeldForces {
  Role role = Role::dem;
  bool surface = false;                // the surface's nodes (node_id), else the role's particles (index)
  std::vector<std::uint32_t> index;    // particle-table indices
  std::vector<std::uint64_t> node_id;  // surface node ids
  std::vector<double> force, torque;   // 3 per entity (N, N m); torque empty: none
};

// The surface's node ids now and each id's row (the order of its node forces).
struct SurfaceNodes {
  std::vector<std::uint64_t> id;
  std::unordered_map<std::uint64_t, std::size_t> row;
  void assign(const google::protobuf::RepeatedField<std::uint64_t>& ids);
};

// The replies of one step, built up pair by pair in the factory's order; the
// coupler turns them into StepForces.
class Replies {
 public:
  // Clears for a new step: every particle solver's forces are zero for each
  // particle of its state, the surface's node forces zero for `surface_nodes`.
  void begin_step(const Solvers& solvers, std::size_t surface_nodes);

  // force: 3 doubles per particle of the role's state index (N); torque: the
  // same (N m) or empty. The first pair's forces are copied, later ones added.
  void add_particle_forces(Role role, std::span<const double> force, std::span<const double> torque);
  // 3 doubles per surface node (N).
  void add_node_forces(std::span<const double> node_force);
  // Hold exchanges: adds everything `other` (begun for the same states) holds but its boundary particles.
  void add(const Replies& other);
  // What this reply gives `role`'s particles (or, `surface`, the surface's nodes), by entity: the rows that
  // carry a force or a torque.
  [[nodiscard]] HeldForces held(const Solvers& solvers, Role role, bool surface, const SurfaceNodes& nodes) const;
  // Adds held forces: a particle's to its row of the state, or, when the state left it out, to a row of its
  // own (extra_particles); a node's to its row of the surface now. Returns the forces that found no entity
  // (surface nodes gone with eroded elements).
  std::size_t add_held(const Solvers& solvers, const HeldForces& held, const SurfaceNodes& nodes);
  struct ExtraParticles {
    std::vector<std::uint32_t> index;
    std::vector<double> force, torque;  // 3 per index each (torque zero where none was held)
  };
  // Held forces on particles outside the role's state, in the order they came.
  [[nodiscard]] const ExtraParticles& extra_particles(Role role) const { return of(role).extra; }
  [[nodiscard]] BoundaryChannel& boundary() { return boundary_; }
  [[nodiscard]] const BoundaryChannel& boundary() const { return boundary_; }

  [[nodiscard]] const std::vector<double>& particle_force(Role role) const { return of(role).force; }
  // Empty when no pair gave torques.
  [[nodiscard]] const std::vector<double>& particle_torque(Role role) const { return of(role).torque; }
  [[nodiscard]] bool has_node_forces() const { return node_force_written_; }
  [[nodiscard]] const std::vector<double>& node_force() const { return node_force_; }

 private:
  struct ParticleReply {
    std::vector<double> force, torque;
    bool force_written = false, torque_written = false;
    ExtraParticles extra;
  };
  [[nodiscard]] const ParticleReply& of(Role role) const { return particles_[static_cast<std::size_t>(role)]; }
  std::array<ParticleReply, 3> particles_;
  std::vector<double> node_force_;
  bool node_force_written_ = false;
  BoundaryChannel boundary_;
};

class ContactPair {
 public:
  virtual ~ContactPair() = default;

  // "dem_fem", "sph_fem", "sph_dem": the scene section it comes from.
  [[nodiscard]] virtual std::string name() const = 0;
  // The two roles it joins.
  [[nodiscard]] virtual std::array<Role, 2> roles() const = 0;
  [[nodiscard]] bool joins(Role role) const { return roles()[0] == role || roles()[1] == role; }

  // See the step contract at the top of this file.
  virtual void start(const Solvers& solvers, Replies& replies) = 0;
  virtual void check_state(const SolverView& /*solver*/) const {}
  virtual void compute(const Solvers& solvers, const StepClock& clock) = 0;
  virtual void scatter(const Solvers& solvers, double dt, Replies& replies) = 0;
  [[nodiscard]] virtual InterestRequest interest(Role role) const = 0;

  // Paper eq. 7's term of this pair after compute(), beta included, s; infinity: no limit.
  [[nodiscard]] virtual double stable_dt() const { return std::numeric_limits<double>::infinity(); }
  // Multirate (docs/architecture.md): whether its forces may be held over several steps of either side.
  // False: the pair is exchanged at the step of its faster side, whatever its sides' rates; with the
  // reason, for the coupler's log.
  struct Holding {
    bool allowed = true;
    std::string why_not;
  };
  [[nodiscard]] virtual const Holding& holding() const {
    static const Holding allowed;
    return allowed;
  }
  // Hold exchanges: true when both its sides must step at every exchange (a pair that sends boundary
  // particles: the sph_solver takes them at every step, and the fluid's force on them comes back a step later).
  [[nodiscard]] virtual bool every_exchange() const { return false; }
  // Walls ahead: the boundary particles this pair sends the sph_solver, those of this step once compute() placed
  // them (the list scatter() appends to the replies); nullptr: it sends none.
  [[nodiscard]] virtual const physics::BoundaryParticles* boundary_particles() const { return nullptr; }
  // Walls ahead of the fluid's state: whether place_ahead() can place this step's boundary particles now, before
  // the sph_solver's state of the step is in (the other side's state must be).
  [[nodiscard]] virtual bool can_place_ahead() const { return false; }
  virtual void place_ahead(const Solvers& /*solvers*/, const StepClock& /*clock*/) {}
  [[nodiscard]] virtual NewtonBalance newton_balance() const = 0;
  // J in the pair's springs at x_n, and W dissipated by its dashpots and slip in step n (acts over dt_n).
  struct Energy {
    double elastic = 0;
    double dissipated_power = 0;
  };
  [[nodiscard]] virtual Energy energy() const { return {}; }
  // forces.csv: the source name of the loads this pair puts on the structure parts ("particles", "fluid"),
  // none if it loads no structure; loads(): the force on each part (scene structure order) this step, N.
  [[nodiscard]] virtual std::optional<std::string> load_source() const { return std::nullopt; }
  [[nodiscard]] virtual std::span<const Vec3> loads() const { return {}; }
  // The loads of loads() one by one, appended to `out` with their points (and their part's index in the
  // surface): per part they sum to loads() to rounding. For sensors that cover a box of a part; only a
  // pair with a load_source() has any, and only after want_point_loads() (called once, before the first
  // compute(), when the scene has such sensors).
  virtual void want_point_loads() {}
  virtual void point_loads(std::vector<PointLoad>& /*out*/) const {}
  // Active contacts after compute().
  [[nodiscard]] virtual std::size_t contact_count() const { return 0; }
  // summary.json's active_effects entry ("effect", "process" and what the pair wants to report); the
  // coupler adds the seconds it spent in the pair.
  [[nodiscard]] virtual nlohmann::json effect() const = 0;

  virtual void save_history(io::hdf5::Group& group) const = 0;
  // Throws FileError when the group does not hold this pair's history.
  virtual void restore_history(const io::hdf5::Group& group) = 0;
};

}  // namespace sabo::coupler
