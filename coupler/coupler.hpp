#pragma once
// The coupler process: the lock-step loop of docs/design.md, "An explicit, lock-step step". It registers the
// solvers the scene needs, then per step gathers every StepState, sets
// dt_n = min_i(beta_i * stable_dt_i) (paper eq. 7, with the contact's own
// limit), computes the contact forces of the enabled pairs, checks Newton's
// third law, accounts the forces per structure part and source, records the
// traffic and replies with StepForces.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "coupler/accounting.hpp"
#include "coupler/authenticator.hpp"
#include "coupler/connection_guard.hpp"
#include "coupler/contact/contact_pair.hpp"
#include "coupler/eta.hpp"
#include "coupler/events.hpp"
#include "coupler/multirate.hpp"
#include "coupler/sensors.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "libsabo/io/traffic.hpp"
#include "libsabo/protocol/socket.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::coupler {

class RestartJournal;

struct CouplerOptions {
  std::string endpoint;           // bound by the coupler
  std::filesystem::path out_dir;  // run folder
  std::chrono::milliseconds registration_timeout{30000};
  ConnectionLimits connections;  // peers that do not register (connection_guard.hpp)
  // The largest frame accepted, bytes (ZMQ_MAXMSGSIZE); 0: scene::max_message_bytes of the scene's estimate.
  std::int64_t max_message_bytes = 0;
  // The coupler's checkpoint to continue the run in out_dir from (docs/restart.md, "Resuming a run"); empty:
  // start at step 0. The solvers must register resumed from their checkpoints of the same step.
  std::filesystem::path resume;
  std::string resume_reason;  // why the run is resumed, for summary.json (the supervisor says)
  // The run's key set (libsabo/protocol/security.hpp): over tcp CURVE with these keys, over ipc the run's token.
  // Empty: no authentication (ipc only; over tcp the scene must say tcp_security = "none").
  std::filesystem::path keys;
  // false: no traffic.h5 whatever the scene's [recording] says (./sabo replay of the coupler, which would only
  // record what it compares, and may resume from a checkpoint that names the unchanged scene file).
  bool record = true;
};

// Exit codes of the coupler process (the supervisor reads them).
enum ExitCode : int { kCompleted = 0, kFailed = 1, kBadInput = 2, kSolverFailed = 3, kStopped = 130 };

class Coupler {
 public:
  Coupler(const scene::Scene& scene, CouplerOptions options, EventStream& events);
  ~Coupler();
  // Runs the whole coupled simulation; returns the process exit code.
  int run();

 private:
  struct Peer;

  // Authentication (docs/security.md) and heartbeats, before the socket binds.
  void secure();
  void bind();
  void wait_for_registrations();
  // Handles one message outside of the expected flow (unknown peers, bad
  // frames, late registrations). Returns the peer it came from, if known.
  Peer* route(const protocol::Inbound& inbound, sabo::v1::MessageType expected, std::uint64_t step);
  void accept_registration(const protocol::Inbound& inbound);
  // Why the connection `inbound` came on may not register as `name`: it authenticated as another role, or
  // another user's process is at its other end; nullopt when it may.
  // `who`: protocol::peer_info of its connection.
  [[nodiscard]] std::optional<std::string> identity_problem(const protocol::Inbound& inbound,
                                                            const protocol::PeerInfo& who,
                                                            const std::string& name) const;
  // Registered solvers whose connection ended (a vanished host, a stopped or dead process): the run stops, or,
  // when it restarts its processes, waits for the replacement that the supervisor starts.
  void check_lost_peers(std::uint64_t step);
  // A solver restarted from its checkpoint registers again (docs/restart.md): it takes its role back and is fed
  // the journalled forces from its checkpoint's step while its states are checked against the journal.
  void accept_replacement(const protocol::Inbound& inbound, const sabo::v1::Register& registration);
  // A state of a peer that is catching up, in inbound_: checked and answered from the journal. False when it is
  // the live step's (the catch-up is over; accept it as usual).
  bool catch_up(Peer& peer, std::uint64_t step);
  void caught_up(Peer& peer, std::uint64_t step);  // a restarted peer is back: summary.json names its restart
  [[nodiscard]] bool restarting() const;
  // Sends a reply to a peer that has not registered (yet); false when it could not be delivered.
  template <class Message>
  bool reply_to_unregistered(const Message& message, const std::string& peer);
  void collect_states(std::uint64_t step);
  // Parses, checks and records the state in inbound_ from `peer` for `step`.
  void accept_state(Peer& peer, std::uint64_t step);
  void validate_state(const Peer& peer);
  void prepare_contacts();
  // The exchange step of this step and each solver's steps in it (multirate.hpp); logs a pair whose own
  // limit holds the exchange below its slower side's step, once.
  RatePlan plan_step();
  // Which pairs are evaluated at this exchange: those whose sides both step (all of them at a block's start).
  void mark_evaluated_pairs(std::uint64_t step);
  // The evaluated pairs' forces at t_n (time_), each with its own last interval as dt_{n-1}. With walls ahead
  // the pairs that place boundary particles come first, and their particles go to the sph_solver before the
  // others are computed (send_walls_ahead).
  void compute_contacts(std::uint64_t step);
  // Walls ahead (docs/protocol.md): this step's boundary particles, of the evaluated pairs in pair order (the
  // list scatter_pairs() builds again in replies_.boundary()), in a StepForces of their own to the sph_solver.
  void send_walls_ahead(std::uint64_t step);
  // With walls ahead, once the states that the boundary-particle pairs read besides the fluid's are in: they
  // place this step's particles from what they kept of the fluid, and the walls go before the fluid's state.
  void place_walls_before_the_fluid(std::uint64_t step);
  // The surface's node ids now (held forces on nodes are kept by id).
  const SurfaceNodes& surface_ids();
  void check_newton_third_law(std::uint64_t step);
  void send_forces(std::uint64_t step, bool output, bool stop, bool checkpoint);
  // The pairs' forces of this exchange into replies_: those evaluated scatter (a pair held for one side keeps
  // that side's part, HeldForces), the others give their held forces again to a side that steps.
  void scatter_pairs(std::uint64_t step);
  // Whether `peer` steps at exchange `step` (it holds before its next_step_exchange).
  [[nodiscard]] static bool steps_now(const Peer& peer, std::uint64_t step);
  // The place in peers_ (and in a RatePlan's per-solver lists) of the solver of `role`.
  [[nodiscard]] std::size_t peer_index(Role role) const;
  void validate_held_state(const Peer& peer);
  // Ends the run (naming the entity) when a force about to be sent is not finite.
  void check_forces(const Peer& peer, const sabo::v1::StepForces& forces);
  void account(std::uint64_t step, double time, double dt, bool output);
  // next_output_time_ past time_: the next output time.
  void advance_output_time();
  void progress(std::uint64_t step, double time, double dt, bool force_emit);
  void stop_solvers(const std::string& reason);
  void wait_for_goodbyes(std::chrono::milliseconds timeout);
  void write_summary(const std::string& status);
  [[nodiscard]] nlohmann::json multirate_summary() const;
  [[nodiscard]] nlohmann::json security_summary() const;
  // A failure after the run started: reported, and the solvers told to stop.
  void handle_failure(const std::exception& error, std::string& status, int& exit_code);

  // Checkpoints of the coupler (coupler_checkpoint.cpp, docs/restart.md): everything the loop carries from
  // one step to the next, written when the solvers write theirs.
  void write_checkpoint(std::uint64_t step);
  void write_checkpoint_file(std::uint64_t step);
  // Resuming: the checkpoint opened and checked; forces.csv and energy.csv cut back to their length at it
  // (before anything binds, once traffic.h5 has been continued); after the registrations, the surface the
  // pairs start from; after the pairs and the histories exist, their state.
  void open_resume();
  void cut_histories();
  void restore_surface();
  void restore_state();
  [[noreturn]] void fail(const std::string& process, const std::string& message);
  // Why a peer whose restart journal was dropped (RestartJournal::dropped()) cannot be restarted.
  [[nodiscard]] std::string journal_dropped(const Peer& peer) const;

  const scene::Scene& scene_;
  CouplerOptions options_;
  EventStream& events_;
  zmq::context_t context_{1};
  protocol::Socket socket_;
  std::int64_t max_message_bytes_ = 0;            // frames above are refused (ZMQ_MAXMSGSIZE)
  std::unique_ptr<Authenticator> authenticator_;  // before guard_: the guard asks it why a handshake failed
  protocol::Mechanism mechanism_ = protocol::Mechanism::none;
  std::string security_warning_;  // for summary.json: tcp without CURVE
  std::unique_ptr<ConnectionGuard> guard_;
  protocol::Inbound inbound_;
  std::vector<std::unique_ptr<Peer>> peers_;           // in registration order
  Solvers solvers_;                                    // the same, by role, as the pairs see them
  std::size_t surface_nodes_ = 0;                      // nodes of the surface now (registration or last topology)
  std::uint64_t surface_revision_ = 0;                 // its topology revision
  double expected_time_ = 0;                           // s, t_n: the sum of the dt sent
  std::uint64_t current_step_ = 0;                     // the step whose states are being collected
  nlohmann::json restarts_ = nlohmann::json::array();  // for summary.json
  std::map<Role, std::unique_ptr<RestartJournal>> journals_;  // opened before binding, until registered
  // summary.json's temporary file, opened before binding as the other run files: at the end of a run idle
  // connections may hold every descriptor, and one freed for it can be taken by the next accept.
  std::ofstream summary_out_;

  // The contact pairs of the scene (pair_factory.hpp), in the order their forces are summed.
  struct PairSlot {
    std::unique_ptr<ContactPair> pair;
    std::optional<std::size_t> source;  // column of its loads in forces.csv
    double seconds = 0;                 // wall time in compute and scatter
    double max_residual = 0;            // largest relative Newton residual
    // Hold exchanges: evaluated at this exchange; dt_{n-1} as it sees it (its last interval, the larger of its
    // sides'); what it gave its faster side, given again until the next evaluation.
    bool evaluated = true;
    double dt_previous = 0;
    std::optional<HeldForces> held;
    std::uint32_t held_due = 0;  // exchanges of the faster side still to get `held` (an internal check)
  };
  std::vector<PairSlot> pairs_;
  Replies replies_;
  Replies scratch_replies_;  // a pair held for one side scatters here first (scatter_pairs)
  // Walls ahead: on when the sph_solver registered walls_ahead and a pair sends it boundary particles; the
  // message of the step, its particles' lists (checked against the replies' list) and its send buffer.
  bool walls_ahead_ = false;
  bool walls_sent_ahead_ = false;  // this step's
  // Placed and sent before the fluid's state of the step was in (place_walls_before_the_fluid), in s; and how
  // many exchanges did so over the run.
  bool walls_placed_early_ = false;
  double early_walls_seconds_ = 0;
  std::string early_walls_to_;  // the sph_solver's connection they went to
  std::uint64_t walls_before_the_fluid_ = 0;
  sabo::v1::StepForces walls_message_;
  std::vector<const physics::BoundaryParticles*> walls_parts_;
  protocol::SendBuffer walls_buffer_;
  // Hold exchanges: the plan of the block of exchanges in progress (a block starts where every solver steps),
  // its first exchange and its length (0: the next exchange starts one); whether the previous exchange
  // started one (energy.csv samples there: every state describes its time).
  RatePlan plan_;
  std::uint64_t block_start_ = 0;
  std::uint32_t block_length_ = 0;
  bool previous_block_start_ = true;
  SurfaceNodes surface_ids_;
  bool surface_ids_stale_ = true;
  std::uint64_t held_forces_lost_ = 0;      // held forces on surface nodes that eroded away
  std::vector<std::string> force_sources_;  // forces.csv sources, in pair order: "particles", "fluid"

  std::unique_ptr<io::TrafficRecorder> recorder_;
  std::unique_ptr<ForceHistory> forces_csv_;
  std::unique_ptr<EnergyHistory> energy_csv_;
  std::unique_ptr<Sensors> sensors_;  // only with [[sensors]]
  PartEnergyHistory part_energies_;   // deformable FEM parts, for summary.json

  // Run statistics for summary.json.
  std::uint64_t steps_ = 0;
  double time_ = 0;
  double dt_min_ = std::numeric_limits<double>::infinity();
  double dt_max_ = 0;
  // Multirate: the steps lock-step would have taken (the sum of exchange_dt / lock_step_dt), and the pairs
  // already reported as holding the exchange below their slower side's step.
  double lock_step_equivalent_ = 0;
  std::vector<bool> pair_rate_reported_;
  double contact_seconds_ = 0;
  double receive_seconds_ = 0;  // parsing, checking and recording the states
  double send_seconds_ = 0;     // building, recording and sending the replies
  double wait_seconds_ = 0;     // collecting the states, receiving included
  double critical_compute_seconds_ = 0;
  // The pairs' seconds that lengthened the exchanges (pairs_on_critical_path: with penalty contacts the slurry
  // computes its own forces meanwhile), and the pairs' seconds at the last exchange.
  double critical_contact_seconds_ = 0;
  double last_contact_seconds_ = 0;
  double last_walls_contact_seconds_ = 0;  // of those, the pairs whose boundary particles went ahead
  std::vector<SolverCycle> cycles_;        // scratch: each solver's part of the exchange
  double newton_max_residual_ = 0;
  std::uint64_t newton_violations_ = 0;
  std::size_t max_contacts_ = 0;
  double next_output_time_ = 0;
  double next_checkpoint_time_ = 0;  // s; set to the first period at the start
  std::uint64_t checkpoints_ = 0;    // steps whose StepForces asked for a checkpoint
  double previous_time_ = 0;
  bool previous_output_ = false;
  double previous_contact_elastic_ = 0;
  double contact_dissipated_ = 0;  // J, accumulated dashpot and slip work of the coupler's contacts
  std::chrono::steady_clock::time_point start_wall_;
  std::chrono::steady_clock::time_point last_progress_;
  std::chrono::steady_clock::time_point stop_grace_end_;  // wait_for_goodbyes: the wait after a stop signal
  EtaEstimate eta_;                                       // the progress line's time to go
  std::string failure_;

  // Checkpoints and resuming.
  std::unique_ptr<io::CheckpointStore> checkpoint_store_;
  io::hdf5::File resume_file_;                // the checkpoint being resumed from, until restored
  std::optional<std::uint64_t> resume_step_;  // the step the run resumes at
  bool bound_ = false;                        // the endpoint is bound: the run has started
  std::uint64_t checkpoint_failures_ = 0;     // coupler checkpoints that could not be written
  double checkpoint_seconds_ = 0;             // wall time writing them (traffic.h5's flush included)
  double dt_previous_ = 0;                    // s, dt_{n-1}
  std::string surface_topology_;              // the FEM surface's newest topology (serialized), if it changed
  double wall_before_ = 0;                    // s of wall time of the run before it was resumed
  std::uint64_t bytes_received_before_ = 0, bytes_sent_before_ = 0;
  nlohmann::json resumes_ = nlohmann::json::array();  // for summary.json
  // States that arrived while the others registered, in a resumed run: accepted once its state is restored.
  std::vector<std::pair<Peer*, protocol::Inbound>> early_states_;
};

}  // namespace sabo::coupler
