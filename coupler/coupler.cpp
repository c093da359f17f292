#include "coupler/coupler.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "coupler/contact/pair_factory.hpp"
#include "coupler/coupler_peer.hpp"
#include "coupler/effects.hpp"
#include "coupler/message_checks.hpp"
#include "coupler/restart_journal.hpp"
#include "coupler/sensors.hpp"
#include "libsabo/core/signals.hpp"
#include "libsabo/protocol/surface_codec.hpp"
#include "libsabo/protocol/walls_ahead.hpp"
#include "libsabo/protocol/wire.hpp"
#include "libsabo/scene/estimate.hpp"

namespace sabo::coupler {

namespace {

using sabo::v1::MessageType;

bool all_finite(const google::protobuf::RepeatedField<double>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// The position in `values` of the first value that is not finite (NaN, +-inf), or -1.
int first_non_finite(const google::protobuf::RepeatedField<double>& values) {
  const auto it = std::find_if(values.begin(), values.end(), [](double v) { return !std::isfinite(v); });
  return it == values.end() ? -1 : static_cast<int>(it - values.begin());
}

constexpr std::array<char, 3> kAxis = {'x', 'y', 'z'};

void add_boundary_particles(const std::vector<const physics::BoundaryParticles*>& parts, sabo::v1::StepForces& f);

}  // namespace

Coupler::Coupler(const scene::Scene& scene, CouplerOptions options, EventStream& events)
    : scene_(scene), options_(std::move(options)), events_(events), socket_(context_, zmq::socket_type::router) {
  // Frames larger than the scene's largest message (with a margin) are refused unread, so that a peer
  // cannot make the coupler read a 1 GiB frame (issue 18); peers that do not register are cut off.
  max_message_bytes_ = options_.max_message_bytes > 0 ? options_.max_message_bytes
                                                      : scene::max_message_bytes(scene::estimate_scene(scene_));
  socket_.set_max_message_size(max_message_bytes_);
  socket_.set_handshake_interval(options_.connections.window);
  secure();
  guard_ = std::make_unique<ConnectionGuard>(context_, socket_, options_.connections, authenticator_.get());
}

void Coupler::secure() {
  using protocol::Mechanism;
  using protocol::Transport;
  const Transport transport = protocol::transport_of(options_.endpoint);
  if (scene_.run.tcp_in_clear(options_.endpoint)) {
    security_warning_ = fmt::format(
        "tcp_security = \"none\": any process that reaches {} can register as a solver, read the run's state and "
        "send forces; nothing is encrypted",
        options_.endpoint);
    spdlog::warn("{}", security_warning_);
  } else if (!options_.keys.empty()) {
    std::vector<std::string> roles;
    for (const auto& solver : scene_.solvers) roles.emplace_back(role_name(solver.role));
    auto credentials = protocol::read_server_credentials(options_.keys, roles, options_.endpoint);
    mechanism_ = credentials.mechanism;
    if (mechanism_ != Mechanism::none) {
      socket_.secure_server(credentials);
      // Before the socket binds: a CURVE or PLAIN server without a ZAP handler would let every client in.
      authenticator_ = std::make_unique<Authenticator>(context_, std::move(credentials));
    }
  } else if (transport == Transport::tcp) {
    throw EndpointError(fmt::format(
        "{} is a tcp endpoint and the scene asks for CURVE (run.tcp_security = \"curve\", the default), but the "
        "coupler has no keys. Fix: start it with --keys DIR ('./sabo keys DIR' writes a key set; './sabo run' makes "
        "one in RUN_DIR/keys), or set tcp_security = \"none\" in the scene's [run] to run without authentication",
        options_.endpoint));
  }
  socket_.set_heartbeat(protocol::Heartbeat::after(scene_.run.heartbeat_timeout));
}

Coupler::~Coupler() = default;

std::string Coupler::journal_dropped(const Peer& peer) const {
  return fmt::format(
      "its restart journal passed run.restart_journal_limit = {} GB after its checkpoint of step {} "
      "and was dropped until its next checkpoint",
      scene_.run.restart_journal_limit, peer.journal->first_step());
}

void Coupler::fail(const std::string& process, const std::string& message) {
  failure_ = fmt::format("{}: {}", process, message);
  throw Error(failure_);
}

void Coupler::bind() {
  socket_.bind(options_.endpoint);
  const char* security = mechanism_ == protocol::Mechanism::curve   ? "CURVE: only this run's keys join, encrypted"
                         : mechanism_ == protocol::Mechanism::plain ? "only this run's token joins"
                                                                    : "no authentication";
  spdlog::info(
      "listening on {} ({}); frames above {:.3g} MB are refused, connections that do not register within {} s "
      "are closed (at most {} at once), a connection silent for {} s is closed",
      socket_.endpoint(), security, static_cast<double>(max_message_bytes_) / 1e6,
      std::chrono::duration<double>(options_.connections.window).count(), options_.connections.max_unregistered,
      scene_.run.heartbeat_timeout);
  events_.listening(socket_.endpoint());
}

template <class Message>
bool Coupler::reply_to_unregistered(const Message& message, const std::string& peer) {
  // A peer that sent one frame and left has no route any more (ZMQ_ROUTER_MANDATORY): the reply is lost,
  // and only the registered solvers matter to the run.
  try {
    socket_.send(message, peer);
    return true;
  } catch (const LibraryError& error) {
    spdlog::warn("could not answer a peer that is not registered (it may have left): {}", error.what());
    return false;
  }
}
// The registrations' replies (coupler_registration.cpp).
template bool Coupler::reply_to_unregistered(const sabo::v1::RegisterReply&, const std::string&);

Coupler::Peer* Coupler::route(const protocol::Inbound& inbound, MessageType expected, std::uint64_t step) {
  if (!inbound.valid()) {
    spdlog::warn("refused a malformed message: {}", inbound.problem);
    sabo::v1::Error error;
    error.set_code(sabo::v1::Error::CODE_MALFORMED);
    error.set_message(fmt::format("malformed message: {}", inbound.problem));
    reply_to_unregistered(error, inbound.peer);
    return nullptr;
  }
  auto it = std::find_if(peers_.begin(), peers_.end(), [&](const auto& p) { return p->identity == inbound.peer; });
  Peer* peer = it == peers_.end() ? nullptr : it->get();
  const auto type = inbound.header.type;
  if (type == sabo::v1::MESSAGE_TYPE_REGISTER) {
    accept_registration(inbound);
    return nullptr;
  }
  if (peer == nullptr) {
    sabo::v1::Error error;
    error.set_code(sabo::v1::Error::CODE_SEQUENCE);
    error.set_message(fmt::format("{} from an unregistered peer: register first", protocol::message_type_name(type)));
    spdlog::warn("{}", error.message());
    reply_to_unregistered(error, inbound.peer);
    return nullptr;
  }
  if (type == sabo::v1::MESSAGE_TYPE_ERROR) {
    sabo::v1::Error error;
    inbound.parse(error);
    fail(peer->name(), fmt::format("reported an error: {}", error.message()));
  }
  if (type == sabo::v1::MESSAGE_TYPE_GOODBYE) {
    inbound.parse(peer->goodbye);
    peer->said_goodbye = true;
    if (expected != sabo::v1::MESSAGE_TYPE_GOODBYE) {
      fail(peer->name(), fmt::format("left the run at step {}: {}", step, peer->goodbye.reason()));
    }
    return nullptr;
  }
  if (type != expected) {
    fail(peer->name(), fmt::format("sent {} while the coupler expected {} (step {})", protocol::message_type_name(type),
                                   protocol::message_type_name(expected), step));
  }
  return peer;
}

void Coupler::accept_state(Peer& peer, std::uint64_t step) {
  if (peer.has_state) fail(peer.name(), fmt::format("sent two states for step {}", step));
  try {
    inbound_.parse(peer.incoming);
  } catch (const ProtocolError& error) {
    fail(peer.name(), error.what());
  }
  if (peer.incoming.step() != step) {
    fail(peer.name(),
         fmt::format("sent the state of step {} while the coupler is at step {}", peer.incoming.step(), step));
  }
  peer.reported_compute = peer.incoming.compute_seconds();
  // Its wait is a sum over the process's life: a restarted process starts it again.
  peer.waited = std::max(0.0, peer.incoming.wait_seconds() - peer.reported_wait);
  peer.reported_wait = peer.incoming.wait_seconds();
  peer.waited_for_forces = std::max(0.0, peer.incoming.forces_wait_seconds() - peer.reported_forces_wait);
  peer.reported_forces_wait = peer.incoming.forces_wait_seconds();
  const bool held = peer.incoming.held();
  if (held) {
    validate_held_state(peer);
    // The first hold after a step carries that step's energies: the energy balance reads them from the
    // peer's state (the pairs read nothing else of a held state).
    if (peer.incoming.has_energies()) {
      peer.state.mutable_energies()->CopyFrom(peer.incoming.energies());
      peer.state.mutable_part_energies()->CopyFrom(peer.incoming.part_energies());
    }
  } else {
    peer.state.Swap(&peer.incoming);
    validate_state(peer);
  }
  peer.has_state = true;
  const sabo::v1::StepState& message = held ? peer.incoming : peer.state;
  if (recorder_) recorder_->record_state(peer.name(), message);
  if (peer.journal) {
    // The state after a checkpoint proves the solver has written it: the journal starts again there.
    if (peer.checkpoint_step && *peer.checkpoint_step == step) peer.journal->begin(step);
    peer.journal->add_state(message);
  }
}

bool Coupler::steps_now(const Peer& peer, std::uint64_t step) {
  return step >= peer.next_step_exchange;
}

std::size_t Coupler::peer_index(Role role) const {
  const auto it = std::find_if(peers_.begin(), peers_.end(), [&](const auto& p) { return p->role == role; });
  assert(it != peers_.end() && "a pair joins registered solvers");
  return static_cast<std::size_t>(it - peers_.begin());
}

void Coupler::validate_held_state(const Peer& peer) {
  const auto& s = peer.incoming;
  auto invalid = [&](const std::string& what) {
    fail(peer.name(), fmt::format("held state of step {}: {}", s.step(), what));
  };
  if (steps_now(peer, s.step())) invalid("it steps at this exchange (a held state answers a hold only)");
  if (s.index_size() != 0 || s.position_size() != 0 || s.node_position_size() != 0 || s.has_topology() ||
      s.has_particle_table() || s.boundary_force_size() != 0) {
    invalid(
        "it carries entities (a held state has step, time, stable_dt, the timings and, at the first hold, the "
        "energies only)");
  }
  const auto& e = s.energies();
  for (const double value : {e.kinetic(), e.potential(), e.elastic(), e.dissipated(), e.inflow()}) {
    if (!std::isfinite(value)) invalid(fmt::format("an energy is {} J (the solver has blown up)", value));
  }
  if (!(std::abs(s.time() - peer.ahead_time) <= 1e-9 * std::max(std::abs(peer.ahead_time), scene_.run.end_time))) {
    invalid(fmt::format("time = {} s, while its last step reached {} s", s.time(), peer.ahead_time));
  }
}

void Coupler::collect_states(std::uint64_t step) {
  auto pending = [&] {
    return static_cast<std::size_t>(
        std::count_if(peers_.begin(), peers_.end(), [](const auto& p) { return !p->has_state || p->catching_up; }));
  };
  auto wait_start = Clock::now();
  const auto hang = std::chrono::duration<double>(scene_.run.hang_timeout);
  while (pending() > 0) {
    if (stop_requested()) throw StopRequested(fmt::format("stopped by signal {} at step {}", stop_signal(), step));
    guard_->tick();
    check_lost_peers(step);
    if (!socket_.receive(inbound_, kPollSlice)) {
      if (Clock::now() - wait_start > hang) {
        std::vector<std::string> silent;
        Peer* first_silent = nullptr;
        for (auto& peer : peers_) {
          if (peer->has_state) continue;
          silent.push_back(fmt::format("{} (pid {})", peer->name(), peer->registration.pid()));
          peer->said_goodbye = true;  // a hung process will not say goodbye: do not wait for it
          if (first_silent == nullptr) first_silent = peer.get();
        }
        fail(first_silent->name(),
             fmt::format("{} sent no state for step {} within hang_timeout = {} s: the process is hung or dead (or "
                         "it sent a frame larger than the {:.3g} MB the coupler accepts, which ZeroMQ drops)",
                         fmt::join(silent, " and "), step, scene_.run.hang_timeout,
                         static_cast<double>(max_message_bytes_) / 1e6));
      }
      continue;
    }
    const auto receive_start = Clock::now();
    Peer* peer = route(inbound_, sabo::v1::MESSAGE_TYPE_STEP_STATE, step);
    if (peer == nullptr) {
      if (restarting()) wait_start = Clock::now();  // a replacement registered: the wait starts again
      continue;
    }
    if (peer->catching_up && catch_up(*peer, step)) {
      wait_start = Clock::now();
      continue;
    }
    accept_state(*peer, step);
    receive_seconds_ += seconds_since(receive_start);
    if (walls_ahead_ && !walls_placed_early_ && peer->role != Role::sph) place_walls_before_the_fluid(step);
  }
  wait_seconds_ += seconds_since(wait_start);
}

void Coupler::check_lost_peers(std::uint64_t step) {
  for (const int fd : guard_->take_lost()) {
    auto it = std::find_if(peers_.begin(), peers_.end(), [&](const auto& p) { return p->source_fd == fd; });
    if (it == peers_.end() || (*it)->said_goodbye) continue;
    Peer& peer = **it;
    peer.source_fd = -1;
    const std::string message = fmt::format(
        "{} (pid {}{}) lost its connection to the coupler at step {}: nothing heard from it for heartbeat_timeout = {} "
        "s, or its process ended (its host is unreachable, its network down, or the process stopped or killed)",
        peer.name(), peer.registration.pid(), peer.address.empty() ? "" : ", at " + peer.address, step,
        scene_.run.heartbeat_timeout);
    if (peer.journal && !peer.journal->dropped()) {
      // The supervisor ends what is left of it and starts it again from its checkpoint; the wait starts again.
      spdlog::warn("{}; waiting for it to be restarted from its checkpoint", message);
      events_.emit(
          {{"event", "lost"}, {"process", peer.name()}, {"pid", peer.registration.pid()}, {"message", message}});
      continue;
    }
    peer.said_goodbye = true;  // it will not say goodbye: do not wait for it
    fail(peer.name(), peer.journal ? message + "; it cannot be restarted: " + journal_dropped(peer) : message);
  }
}

void Coupler::validate_state(const Peer& peer) {
  const auto& s = peer.state;
  const auto n = static_cast<std::size_t>(s.index_size());
  const auto table_size = static_cast<std::uint32_t>(peer.registration.particles().id_size());
  auto invalid = [&](const std::string& what) {
    fail(peer.name(), fmt::format("state of step {}: {}", s.step(), what));
  };
  if (static_cast<std::size_t>(s.position_size()) != 3 * n || static_cast<std::size_t>(s.velocity_size()) != 3 * n) {
    invalid(fmt::format("{} indices but {} position and {} velocity values (expected 3 per index)", n,
                        s.position_size(), s.velocity_size()));
  }
  if (peer.registration.exposes_angular_velocity() && static_cast<std::size_t>(s.angular_velocity_size()) != 3 * n) {
    invalid(fmt::format("{} indices but {} angular velocity values", n, s.angular_velocity_size()));
  }
  for (auto index : s.index()) {
    if (index >= table_size) invalid(fmt::format("particle index {} is outside its table of {}", index, table_size));
  }
  // A NaN or an infinity names the particle, by index and id (issue 18: gravity = [0, 0, -1e300] ran to the end).
  for (const auto& [what, values] : {std::pair{"position", &s.position()}, std::pair{"velocity", &s.velocity()},
                                     std::pair{"angular velocity", &s.angular_velocity()}}) {
    const int k = first_non_finite(*values);
    if (k < 0) continue;
    const auto entity = static_cast<std::size_t>(k / 3);
    const std::uint32_t index = entity < n ? s.index(static_cast<int>(entity)) : 0;
    invalid(
        fmt::format("non-finite {}: {}_{} = {} of particle index {} (id {}) (the solver has blown up, or an "
                    "input such as the gravity is extreme)",
                    what, what, kAxis[static_cast<std::size_t>(k % 3)], (*values)[k], index,
                    peer.registration.particles().id(static_cast<int>(index))));
  }
  if (auto problem = stable_dt_problem(s.stable_dt(), scene_.run.end_time)) invalid(*problem);
  // Every solver adds the same dt_n to its time, so t_n is the coupler's sum (to round-off for a solver
  // that sums otherwise). A solver on hold is at the end of its last step's interval.
  const bool steps = steps_now(peer, s.step());
  const double expected = steps ? expected_time_ : peer.ahead_time;
  if (!(std::abs(s.time() - expected) <= 1e-9 * std::max(std::abs(expected), scene_.run.end_time))) {
    invalid(fmt::format("time = {} s, while {} is {} s ({})", s.time(), steps ? "t_n" : "its step's end", expected,
                        steps ? "the sum of the steps the coupler sent" : "it holds at this exchange"));
  }
  const auto& e = s.energies();
  for (const auto& [what, value] : {std::pair{"kinetic", e.kinetic()}, std::pair{"potential", e.potential()},
                                    std::pair{"elastic", e.elastic()}, std::pair{"dissipated", e.dissipated()}}) {
    if (!std::isfinite(value)) {
      invalid(fmt::format("its {} energy is {} J (the solver has blown up, or an input is extreme)", what, value));
    }
  }
  // The pairs' own needs of this state (e.g. a surface that may not change).
  for (const auto& slot : pairs_) {
    if (!slot.pair->joins(peer.role)) continue;
    try {
      slot.pair->check_state(*solvers_.find(peer.role));
    } catch (const ProtocolError& error) {
      invalid(error.what());
    }
  }
  if (peer.registration.exposes_surface() && s.has_topology()) {
    // Elements eroded: the surface's new topology replaces the registered one
    // from this step on (checked like the registration's).
    const auto& topology = s.topology();
    if (auto problem = surface_problem(topology, scene_))
      invalid(fmt::format("the new surface topology: {}", *problem));
    if (topology.revision() <= surface_revision_) {
      invalid(fmt::format("surface topology revision {} does not follow revision {}", topology.revision(),
                          surface_revision_));
    }
    surface_revision_ = topology.revision();
    surface_nodes_ = static_cast<std::size_t>(topology.node_id_size());
    surface_ids_stale_ = true;
    surface_topology_ = topology.SerializeAsString();  // what a resumed run's pairs start from
  }
  // Boundary particles go to the sph_solver only (docs/protocol.md, "SPH walls").
  const bool receives_boundary = peer.role == Role::sph && replies_.boundary().active();
  if (s.boundary_force_size() != 0 || s.has_boundary_step() || receives_boundary) {
    const std::uint64_t steps_back = s.has_boundary_step() ? s.step() - s.boundary_step() : 1;
    if (s.has_boundary_step() && (s.boundary_step() >= s.step() || steps_back > 2)) {
      invalid(fmt::format("boundary_step = {} must be step - 1 or step - 2", s.boundary_step()));
    }
    const std::size_t sent = receives_boundary ? replies_.boundary().sent(steps_back) : 0;
    const bool may_be_empty = s.step() <= 1;
    if (static_cast<std::size_t>(s.boundary_force_size()) != 3 * sent &&
        !(may_be_empty && s.boundary_force_size() == 0)) {
      invalid(
          fmt::format("{} boundary_force values for the {} boundary particles the coupler sent at step {} "
                      "(expected 3 each, in that order; boundary_step names the step)",
                      s.boundary_force_size(), sent, s.step() - steps_back));
    }
    if (!all_finite(s.boundary_force())) invalid("non-finite boundary_force");
  }
  if (peer.registration.exposes_surface() && s.node_position_size() != 0) {
    const auto nodes = static_cast<int>(surface_nodes_);
    if (s.node_position_size() != 3 * nodes || s.node_velocity_size() != 3 * nodes) {
      invalid(fmt::format("{} node positions for {} surface nodes", s.node_position_size(), nodes));
    }
    for (const auto& [what, values] :
         {std::pair{"node position", &s.node_position()}, std::pair{"node velocity", &s.node_velocity()}}) {
      const int k = first_non_finite(*values);
      if (k < 0) continue;
      const int node = k / 3;
      const auto& topology = s.has_topology() ? s.topology() : peer.registration.surface();
      invalid(
          fmt::format("non-finite {}: component {} = {} of surface node {} (id {}) (the solver has blown up, "
                      "or an input is extreme)",
                      what, kAxis[static_cast<std::size_t>(k % 3)], (*values)[k], node,
                      node < topology.node_id_size() ? topology.node_id(node) : 0));
    }
  }
}

void Coupler::prepare_contacts() {
  for (auto& pair : make_contact_pairs(scene_)) {
    pair->start(solvers_, replies_);
    PairSlot slot;
    if (auto source = pair->load_source()) {
      auto it = std::find(force_sources_.begin(), force_sources_.end(), *source);
      if (it == force_sources_.end()) it = force_sources_.insert(force_sources_.end(), *source);
      slot.source = static_cast<std::size_t>(it - force_sources_.begin());
    }
    slot.pair = std::move(pair);
    pairs_.push_back(std::move(slot));
  }
  const auto sph = std::find_if(peers_.begin(), peers_.end(), [](const auto& p) { return p->role == Role::sph; });
  walls_ahead_ = replies_.boundary().active() && sph != peers_.end() && (*sph)->registration.walls_ahead();
  if (walls_ahead_) {
    spdlog::info("boundary particles go to the sph_solver ahead of its forces: it computes while the other pairs do");
  }
}

RatePlan Coupler::plan_step() {
  std::vector<SolverRate> solvers;
  for (const auto& peer : peers_) {
    solvers.push_back({.stable_step = peer->beta * peer->state.stable_dt(),
                       .max_substeps = peer->registration.max_substeps(),
                       .holds = peer->registration.holds() && scene_.run.hold_exchanges});
  }
  std::vector<PairRate> pairs;
  for (const auto& slot : pairs_) {
    const auto roles = slot.pair->roles();
    pairs.push_back({.a = peer_index(roles[0]),
                     .b = peer_index(roles[1]),
                     .stable_dt = slot.pair->stable_dt(),
                     .held = slot.pair->holding().allowed,
                     .every_exchange = slot.pair->every_exchange()});
  }
  // Only rigid parts and nothing else that limits the step: take output-sized steps.
  const double until_output = std::min(next_output_time_, scene_.run.end_time) - time_;
  const RatePlan plan = plan_rates(solvers, pairs,
                                   {.max_dt = scene_.run.max_dt,
                                    .fallback_dt = scene_.run.output_interval,
                                    .until_next_output = until_output > 0 ? until_output : scene_.run.output_interval},
                                   scene_.run.multirate);
  if (scene_.run.multirate) {
    pair_rate_reported_.resize(pairs.size(), false);
    for (std::size_t j = 0; j < pairs.size(); ++j) {
      if (!pairs[j].held) {
        if (!pair_rate_reported_[j]) {
          pair_rate_reported_[j] = true;
          spdlog::info("multirate: the {} pair is exchanged at the step of its faster side: {}", pairs_[j].pair->name(),
                       pairs_[j].pair->holding().why_not);
        }
        continue;
      }
      const double slower = std::max(solvers[pairs[j].a].stable_step, solvers[pairs[j].b].stable_step);
      if (pair_rate_reported_[j] || !(pairs[j].stable_dt < slower) || plan.exchange_dt > pairs[j].stable_dt) continue;
      pair_rate_reported_[j] = true;
      spdlog::info(
          "multirate: the {} pair is exchanged every {:.3e} s, below the {:.3e} s step of its slower side ({}): its "
          "stiffness and the masses it joins would not be stable with its forces held longer",
          pairs_[j].pair->name(), pairs[j].stable_dt, slower,
          solvers[pairs[j].a].stable_step >= solvers[pairs[j].b].stable_step ? peers_[pairs[j].a]->name()
                                                                             : peers_[pairs[j].b]->name());
    }
  }
  return plan;
}

void Coupler::mark_evaluated_pairs(std::uint64_t step) {
  for (auto& slot : pairs_) {
    const auto roles = slot.pair->roles();
    slot.evaluated = steps_now(*peers_[peer_index(roles[0])], step) && steps_now(*peers_[peer_index(roles[1])], step);
  }
}

void Coupler::compute_contacts(std::uint64_t step) {
  walls_sent_ahead_ = false;
  const bool placed_early = std::exchange(walls_placed_early_, false);
  if (pairs_.empty()) return;
  const auto start = Clock::now();
  std::size_t contacts = 0;
  const auto compute = [&](PairSlot& slot) {
    if (!slot.evaluated) {
      contacts += slot.pair->contact_count();
      return;
    }
    const auto pair_start = Clock::now();
    // dt_{n-1} as the pair sees it: its own last interval (several exchanges where it held).
    slot.pair->compute(solvers_, {.step = step, .time = time_, .dt_previous = slot.dt_previous});
    contacts += slot.pair->contact_count();
    slot.seconds += seconds_since(pair_start);
  };
  double sending = 0;
  last_walls_contact_seconds_ = 0;
  if (walls_ahead_ && steps_now(*peers_[peer_index(Role::sph)], step)) {
    // Each pair computes from the states and its own history alone: the order changes no bit.
    for (auto& slot : pairs_) {
      if (slot.pair->boundary_particles() != nullptr) compute(slot);
    }
    // Placed early, what compute() did of these pairs now (the fluid's forces on the particles sent before) held
    // up no wall. A replacement of the sph_solver that joined after the walls went (to the process it replaced,
    // killed while it integrated) gets them now.
    last_walls_contact_seconds_ = placed_early ? early_walls_seconds_ : seconds_since(start);
    if (!placed_early || peers_[peer_index(Role::sph)]->identity != early_walls_to_) {
      const auto send_start = Clock::now();
      send_walls_ahead(step);
      sending = seconds_since(send_start);
    }
    walls_sent_ahead_ = true;
    for (auto& slot : pairs_) {
      if (slot.pair->boundary_particles() == nullptr) compute(slot);
    }
  } else {
    for (auto& slot : pairs_) compute(slot);
  }
  max_contacts_ = std::max(max_contacts_, contacts);
  last_contact_seconds_ = seconds_since(start) - sending + (placed_early ? early_walls_seconds_ : 0.0);
  contact_seconds_ += last_contact_seconds_;
  send_seconds_ += sending;
}

void Coupler::send_walls_ahead(std::uint64_t step) {
  walls_message_.Clear();
  walls_message_.set_step(step);
  walls_message_.set_walls_ahead(true);
  walls_parts_.clear();
  for (const auto& slot : pairs_) {
    const physics::BoundaryParticles* particles = slot.pair->boundary_particles();
    if (slot.evaluated && particles != nullptr) walls_parts_.push_back(particles);
  }
  add_boundary_particles(walls_parts_, walls_message_);
  Peer& sph = *peers_[peer_index(Role::sph)];
  try {
    socket_.send(walls_message_, walls_buffer_, sph.identity);
  } catch (const LibraryError&) {
    // Gone after its state: sending its forces fails too, and is handled there (its replacement gets the two
    // as one StepForces from the journal).
    if (!sph.journal) throw;
  }
}

void Coupler::place_walls_before_the_fluid(std::uint64_t step) {
  const Peer& sph = *peers_[peer_index(Role::sph)];
  if (sph.has_state || sph.catching_up || !steps_now(sph, step) || restarting()) return;
  bool any = false;
  for (const auto& slot : pairs_) {
    if (slot.pair->boundary_particles() == nullptr) continue;
    if (!slot.pair->can_place_ahead()) return;
    for (const Role role : slot.pair->roles()) {
      const Peer& side = *peers_[peer_index(role)];
      if (role != Role::sph && (!side.has_state || side.catching_up || !steps_now(side, step))) return;
    }
    any = true;
  }
  if (!any) return;
  const auto start = Clock::now();
  for (auto& slot : pairs_) {
    if (slot.pair->boundary_particles() == nullptr) continue;
    slot.evaluated = true;  // both its sides step now, as mark_evaluated_pairs() will find (send_walls_ahead reads it)
    const auto pair_start = Clock::now();
    // Its clock as compute_contacts() gives it: t_n is the time the coupler expects of this step's states.
    slot.pair->place_ahead(solvers_, {.step = step, .time = expected_time_, .dt_previous = slot.dt_previous});
    slot.seconds += seconds_since(pair_start);
  }
  early_walls_seconds_ = seconds_since(start);
  early_walls_to_ = sph.identity;
  const auto send_start = Clock::now();
  send_walls_ahead(step);
  send_seconds_ += seconds_since(send_start);
  walls_placed_early_ = true;
  ++walls_before_the_fluid_;
}

const SurfaceNodes& Coupler::surface_ids() {
  if (!surface_ids_stale_) return surface_ids_;
  if (!surface_topology_.empty()) {
    sabo::v1::SurfaceTopology topology;
    topology.ParseFromString(surface_topology_);
    surface_ids_.assign(topology.node_id());
  } else {
    const auto fem =
        std::find_if(peers_.begin(), peers_.end(), [](const auto& p) { return p->registration.exposes_surface(); });
    assert(fem != peers_.end() && "held node forces come from a pair with the surface");
    surface_ids_.assign((*fem)->registration.surface().node_id());
  }
  surface_ids_stale_ = false;
  return surface_ids_;
}

void Coupler::check_newton_third_law(std::uint64_t step) {
  // Each pair's forces on its two sides, and all of them together: every force the coupler hands out
  // has its reaction.
  NewtonBalance total;
  for (auto& slot : pairs_) {
    if (!slot.evaluated) continue;  // its forces are those it was checked with
    const NewtonBalance balance = slot.pair->newton_balance();
    if (balance.scale > 0) slot.max_residual = std::max(slot.max_residual, balance.sum.norm() / balance.scale);
    total.sum += balance.sum;
    total.scale += balance.scale;
  }
  if (total.scale == 0) return;
  const double residual = total.sum.norm() / total.scale;
  newton_max_residual_ = std::max(newton_max_residual_, residual);
  if (residual > 1e-10) {
    if (newton_violations_ == 0) {
      spdlog::error(
          "Newton's third law broken at step {}: the contact forces sum to ({:.3e}, {:.3e}, {:.3e}) N, "
          "{:.2e} of their total",
          step, total.sum.x(), total.sum.y(), total.sum.z(), residual);
    }
    ++newton_violations_;
  }
}

namespace {
void set_interest(sabo::v1::StepForces& f, const InterestRequest& request) {
  for (const Aabb& box : request.boxes) {
    auto* b = f.add_interest();
    b->set_min_x(box.min.x()), b->set_min_y(box.min.y()), b->set_min_z(box.min.z());
    b->set_max_x(box.max.x()), b->set_max_y(box.max.y()), b->set_max_z(box.max.z());
  }
  f.set_interest_all(request.all);
}

// Packs the parts' 3-vector field (position, velocity, ...) into one repeated field, in order.
void assign_vectors(google::protobuf::RepeatedField<double>& field,
                    const std::vector<const physics::BoundaryParticles*>& parts, std::size_t total,
                    std::vector<Vec3> physics::BoundaryParticles::*member) {
  field.Resize(3 * static_cast<int>(total), 0.0);
  double* out = field.mutable_data();
  for (const physics::BoundaryParticles* part : parts) {
    for (const Vec3& v : part->*member) *out++ = v.x(), *out++ = v.y(), *out++ = v.z();
  }
}

// Appends to f the particles of `index` (a state's) that carry a force or a torque (3 values each per index;
// torque may be empty: none given), with zero torques where `with_torque` and none were given.
void add_loaded_particles(std::span<const std::uint32_t> index, std::span<const double> force,
                          std::span<const double> torque, bool with_torque, sabo::v1::StepForces& f) {
  // Only the particles with a force or a torque: most of a slurry's interest region touches nothing, and a
  // particle a StepForces leaves out gets none (docs/protocol.md).
  const auto row_is_zero = [](std::span<const double> values, std::size_t k) {
    return values.empty() || (values[3 * k] == 0.0 && values[3 * k + 1] == 0.0 && values[3 * k + 2] == 0.0);
  };
  const auto n = static_cast<std::size_t>(index.size());
  assert(force.size() == 3 * n && (torque.empty() || torque.size() == 3 * n));
  for (std::size_t k = 0; k < n; ++k) {
    if (row_is_zero(force, k) && row_is_zero(torque, k)) continue;
    f.add_index(index[k]);
    f.mutable_force()->Add(force.begin() + static_cast<std::ptrdiff_t>(3 * k),
                           force.begin() + static_cast<std::ptrdiff_t>(3 * k + 3));
    if (!with_torque) continue;
    if (torque.empty()) {
      for (int c = 0; c < 3; ++c) f.add_torque(0.0);
    } else {
      f.mutable_torque()->Add(torque.begin() + static_cast<std::ptrdiff_t>(3 * k),
                              torque.begin() + static_cast<std::ptrdiff_t>(3 * k + 3));
    }
  }
}

// The boundary_* fields of `f`: the particles of `parts`, in order.
void add_boundary_particles(const std::vector<const physics::BoundaryParticles*>& parts, sabo::v1::StepForces& f) {
  using P = physics::BoundaryParticles;
  std::size_t size = 0;
  for (const P* part : parts) size += part->size();
  assign_vectors(*f.mutable_boundary_position(), parts, size, &P::position);
  // Walls at rest (rigid structures only) send no velocities and accelerations: empty means zero.
  const auto moving = [&](std::vector<Vec3> P::*member) {
    return std::any_of(parts.begin(), parts.end(), [&](const P* part) {
      return std::any_of((part->*member).begin(), (part->*member).end(), [](const Vec3& v) { return !v.isZero(0.0); });
    });
  };
  if (moving(&P::velocity)) assign_vectors(*f.mutable_boundary_velocity(), parts, size, &P::velocity);
  assign_vectors(*f.mutable_boundary_normal(), parts, size, &P::normal);
  if (moving(&P::acceleration)) assign_vectors(*f.mutable_boundary_acceleration(), parts, size, &P::acceleration);
  auto* volume = f.mutable_boundary_volume();
  volume->Reserve(static_cast<int>(size));
  for (const P* part : parts) volume->Add(part->volume.begin(), part->volume.end());
  const bool slips = std::any_of(parts.begin(), parts.end(), [](const P* p) { return !p->free_slip.empty(); });
  if (slips) {
    auto* free_slip = f.mutable_boundary_free_slip();
    free_slip->Reserve(static_cast<int>(size));
    for (const P* part : parts) {
      if (part->free_slip.empty()) {
        free_slip->Resize(free_slip->size() + static_cast<int>(part->size()), 0u);
      } else {
        free_slip->Add(part->free_slip.begin(), part->free_slip.end());
      }
    }
  }
}

}  // namespace

void Coupler::scatter_pairs(std::uint64_t step) {
  replies_.begin_step(solvers_, surface_nodes_);
  for (auto& slot : pairs_) {
    const auto pair_start = Clock::now();
    const auto roles = slot.pair->roles();
    const std::size_t a = peer_index(roles[0]), b = peer_index(roles[1]);
    const std::uint32_t interval_a = plan_.intervals[a], interval_b = plan_.intervals[b];
    if (slot.evaluated) {
      assert(slot.held_due == 0 && "the faster side got the held forces at each of its exchanges in between");
      const std::uint32_t interval = std::max(interval_a, interval_b);
      const double dt = interval * plan_.exchange_dt;
      slot.held.reset();
      if (interval_a == interval_b) {
        slot.pair->scatter(solvers_, dt, replies_);
      } else {
        // Held for its faster side: what it gives that side is kept by entity for that side's next exchanges.
        scratch_replies_.begin_step(solvers_, surface_nodes_);
        slot.pair->scatter(solvers_, dt, scratch_replies_);
        const Peer& faster = *peers_[interval_a < interval_b ? a : b];
        const bool surface = faster.registration.exposes_surface();
        slot.held = scratch_replies_.held(solvers_, faster.role, surface, surface ? surface_ids() : SurfaceNodes{});
        slot.held_due = interval / std::min(interval_a, interval_b) - 1;
        replies_.add(scratch_replies_);
      }
      slot.dt_previous = dt;
    } else if (slot.held) {
      const HeldForces& held = *slot.held;
      if (steps_now(*peers_[held.role == roles[0] ? a : b], step)) {
        assert(slot.held_due > 0);
        --slot.held_due;
        const std::size_t lost = replies_.add_held(solvers_, held, held.surface ? surface_ids() : SurfaceNodes{});
        if (lost > 0 && held_forces_lost_ == 0) {
          spdlog::warn(
              "step {}: {} held {} forces found no surface node (eroded since the pair was evaluated); they are "
              "dropped (warned once)",
              step, lost, slot.pair->name());
        }
        held_forces_lost_ += lost;
      }
    }
    slot.seconds += seconds_since(pair_start);
  }
}

void Coupler::send_forces(std::uint64_t step, bool output, bool stop, bool checkpoint) {
  const auto start = Clock::now();
  scatter_pairs(step);
  for (std::size_t k = 0; k < peers_.size(); ++k) {
    Peer* const peer = peers_[k].get();
    auto& f = peer->forces;
    f.Clear();
    f.set_step(step);
    f.set_checkpoint(checkpoint);
    const bool steps = steps_now(*peer, step);
    if (steps) {
      // Its interval in this block, and the fewest steps within its stable step (its own step may have changed
      // since the block began). substeps * dt is the interval to the rounding of the division: the solver's
      // time, a sum of its steps, stays within the check of its states (a relative 1e-9).
      const std::uint32_t exchanges = plan_.intervals[k];
      const double interval = exchanges * plan_.exchange_dt;
      const std::uint32_t substeps =
          step == block_start_ ? plan_.substeps[k]
                               : substeps_within(interval, peer->beta * peer->state.stable_dt(),
                                                 std::max<std::uint32_t>(peer->registration.max_substeps(), 1));
      f.set_dt(interval / substeps);
      if (substeps > 1) f.set_substeps(substeps);
      if (exchanges > 1) f.set_holds(exchanges - 1);
      if (!stop) peer->solver_steps += substeps;
      peer->next_step_exchange = step + exchanges;
      peer->ahead_time = expected_time_ + interval;
      f.set_output(output);
      f.set_stop(stop);
    } else {
      f.set_hold(true);
      ++peer->holds;
    }
    if (peer->registration.exposes_particles()) {
      const Role role = peer->role;
      if (steps) {
        const bool with_torque = peer->registration.exposes_angular_velocity();
        const auto& index = peer->state.index();
        add_loaded_particles({index.data(), static_cast<std::size_t>(index.size())}, replies_.particle_force(role),
                             replies_.particle_torque(role), with_torque, f);
        // Held forces on particles its state left out.
        const auto& extra = replies_.extra_particles(role);
        add_loaded_particles(extra.index, extra.force,
                             with_torque ? std::span<const double>(extra.torque) : std::span<const double>(),
                             with_torque, f);
      }
      // What the pairs need of this solver at the next step: the union of their regions.
      InterestRequest interest;
      for (const auto& pair_slot : pairs_) {
        if (!pair_slot.pair->joins(role)) continue;
        InterestRequest request = pair_slot.pair->interest(role);
        interest.all = interest.all || request.all;
        interest.boxes.insert(interest.boxes.end(), request.boxes.begin(), request.boxes.end());
      }
      if (interest.all) interest.boxes.clear();
      set_interest(f, interest);
      if (steps && role == Role::sph && replies_.boundary().active()) {
        if (walls_sent_ahead_) {
          assert(walls_parts_ == replies_.boundary().parts() && "the walls sent ahead are the replies' list");
        } else {
          add_boundary_particles(replies_.boundary().parts(), f);
        }
      }
    } else if (peer->registration.exposes_surface()) {
      if (steps && replies_.has_node_forces()) {
        f.mutable_node_force()->Assign(replies_.node_force().begin(), replies_.node_force().end());
      }
      // The coupler keeps the whole surface current.
      f.set_interest_all(true);
    }
    check_forces(*peer, f);
    if (checkpoint && peer->registration.checkpoints()) peer->checkpoint_step = step + 1;
    try {
      socket_.send(f, peer->buffer, peer->identity);
    } catch (const LibraryError& error) {
      if (!peer->journal) throw;
      // A solver that died after its state: its replacement gets these forces in the catch-up (journalled
      // below).
      peer->send_error = error.what();
    }
  }
  // What only the coupler keeps, once every solver has its forces and computes: the recording and the
  // restart journal (from the bytes the socket sent, when it sent them without a copy).
  for (auto& peer : peers_) {
    auto& f = peer->forces;
    // Walls ahead: recorded and journalled as the one StepForces a solver without them gets (replay, catch-up).
    const bool joined = walls_sent_ahead_ && peer->role == Role::sph;  // sent ahead only where it steps
    if (joined) protocol::move_boundary_particles(walls_message_, f);
    if (recorder_) recorder_->record_forces(peer->name(), f);
    if (peer->journal && !peer->journal->dropped()) {
      peer->journal->add_forces(
          f, peer->send_error || joined ? std::span<const std::uint8_t>() : peer->buffer.last_body());
      if (peer->journal->dropped()) {
        spdlog::warn(
            "the {} at step {}: {}, and it cannot be restarted until then. Fix: checkpoints more often "
            "(run.checkpoint_interval), or a larger run.restart_journal_limit",
            peer->name(), f.step(), journal_dropped(*peer));
      }
    }
    if (!peer->send_error) continue;
    const std::string error = *std::exchange(peer->send_error, std::nullopt);
    if (!peer->journal->dropped()) {
      spdlog::warn("could not send the forces of step {} to {} (it may have died; it can be restarted): {}", step,
                   peer->name(), error);
    } else {
      fail(peer->name(), fmt::format("could not send the forces of step {} to {} ({}), and it cannot be restarted: "
                                     "{}. Fix: checkpoints more often (run.checkpoint_interval), or a larger "
                                     "run.restart_journal_limit",
                                     step, peer->name(), error, journal_dropped(*peer)));
    }
  }
  send_seconds_ += seconds_since(start);
}

void Coupler::check_forces(const Peer& peer, const sabo::v1::StepForces& f) {
  // The contact forces are finite when the states were (checked on arrival); one that is not comes from an
  // input so extreme that the contact law overflows: it ends the run naming the entity, not reaching a solver.
  for (const auto& [what, values] : {std::pair{"force", &f.force()}, std::pair{"torque", &f.torque()}}) {
    const int k = first_non_finite(*values);
    if (k < 0) continue;
    const int entity = k / 3;
    const std::uint32_t index = entity < f.index_size() ? f.index(entity) : 0;
    fail("coupler",
         fmt::format("the contact {} on particle index {} (id {}) of the {} at step {} is not finite ({}_{} = "
                     "{}): an input is extreme (a speed, a stiffness, the gravity)",
                     what, index, peer.registration.particles().id(static_cast<int>(index)), peer.name(), f.step(),
                     what, kAxis[static_cast<std::size_t>(k % 3)], (*values)[k]));
  }
  if (const int k = first_non_finite(f.node_force()); k >= 0) {
    fail("coupler", fmt::format("the contact force on surface node {} of the {} at step {} is not finite (component "
                                "{} = {}): an input is extreme (a speed, a stiffness, the gravity)",
                                k / 3, peer.name(), f.step(), kAxis[static_cast<std::size_t>(k % 3)], f.node_force(k)));
  }
}

void Coupler::account(std::uint64_t step, double time, double dt, bool output) {
  if (forces_csv_) {
    for (const auto& slot : pairs_) {
      if (!slot.source) continue;
      const auto loads = slot.pair->loads();  // [part] -> force from this pair's source, N
      for (std::size_t part = 0; part < loads.size(); ++part) forces_csv_->add(part, *slot.source, loads[part], dt);
      if (sensors_) sensors_->add(*slot.pair, loads, *slot.source, dt);
    }
  }
  if (forces_csv_ && output) forces_csv_->write(time);
  if (sensors_ && output) sensors_->write(time);

  // A solver's energies in the state of step n describe step n - 1 (its kinetic
  // energy needs v_{n-1/2}), so they are paired with the contact energy of step n - 1. With hold exchanges
  // only the exchange after a block's start has every solver's state of its time.
  if (step > 0 && previous_block_start_) {
    EnergySample sample;
    sample.time = previous_time_;
    for (const auto& peer : peers_) {
      const auto& e = peer->state.energies();
      sample.kinetic += e.kinetic();
      sample.potential += e.potential();
      sample.solver_elastic += e.elastic();
      sample.dissipated += e.dissipated();
      sample.inflow += e.inflow();
    }
    sample.contact_elastic = previous_contact_elastic_;
    sample.dissipated += contact_dissipated_;
    if (energy_csv_) energy_csv_->observe(sample, previous_output_);
    for (const auto& peer : peers_) {
      for (const auto& p : peer->state.part_energies()) {
        part_energies_.observe({previous_time_, p.kinetic(), p.internal(), p.plastic_work(), p.hourglass(), p.eroded(),
                                p.external_work(), p.eroded_elements()},
                               p.part(), previous_output_);
      }
    }
  }
  previous_time_ = time;
  previous_output_ = output;
  previous_contact_elastic_ = 0;
  for (const auto& slot : pairs_) {
    const ContactPair::Energy energy = slot.pair->energy();
    previous_contact_elastic_ += energy.elastic;
    // Dashpot and slip power of step n acts over dt_n.
    contact_dissipated_ += energy.dissipated_power * dt;
  }
}

void Coupler::advance_output_time() {
  // One interval per output time as a rule; an interval so small against t_n that the steps skip many output
  // times (the scene check refuses more than scene::kMaxOutputs of them; a scene built by hand may not be
  // checked) jumps to the first one after t_n, or past t_n where t_n + interval rounds to t_n: bounded, so that
  // no step can loop for ever (issue 18: output_interval = 1e-300 kept the coupler at step 1, deaf to SIGTERM).
  const double interval = scene_.run.output_interval;
  const double reached = time_ + 1e-9 * interval;
  for (int k = 0; next_output_time_ <= reached; ++k) {
    if (k == 64) {
      next_output_time_ = std::max(std::nextafter(reached, std::numeric_limits<double>::infinity()),
                                   (std::floor(reached / interval) + 1) * interval);
      break;
    }
    next_output_time_ += interval;
  }
}

void Coupler::progress(std::uint64_t step, double time, double dt, bool force_emit) {
  const auto now = Clock::now();
  if (!force_emit && now - last_progress_ < std::chrono::milliseconds(500)) return;
  last_progress_ = now;
  const double wall = seconds_since(start_wall_);
  const double rate = wall > 0 ? static_cast<double>(step - resume_step_.value_or(0)) / wall : 0.0;
  eta_.observe(wall, time);
  const double eta = eta_.seconds_to(scene_.run.end_time);
  events_.emit({{"event", "progress"},
                {"step", step},
                {"time", time},
                {"end_time", scene_.run.end_time},
                {"dt", dt},
                {"steps_per_second", rate},
                {"eta_seconds", eta}});
}

void Coupler::stop_solvers(const std::string& reason) {
  sabo::v1::Stop stop;
  stop.set_reason(reason);
  for (const auto& peer : peers_) {
    if (peer->said_goodbye) continue;
    try {
      socket_.send(stop, peer->identity);
    } catch (const LibraryError& error) {
      spdlog::warn("could not send Stop to {}: {}", peer->name(), error.what());
    }
  }
}

void Coupler::wait_for_goodbyes(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  // After a stop signal the solvers still get a moment to say goodbye (they received Stop).
  stop_grace_end_ = Clock::now() + std::chrono::milliseconds(3000);
  auto missing = [&] {
    return std::any_of(peers_.begin(), peers_.end(), [](const auto& p) { return !p->said_goodbye; });
  };
  while (missing() && Clock::now() < deadline) {
    if (stop_requested() && Clock::now() > stop_grace_end_) return;  // SIGTERM: the run is ending anyway
    guard_->tick();
    if (!socket_.receive(inbound_, kPollSlice) || !inbound_.valid()) continue;
    auto it = std::find_if(peers_.begin(), peers_.end(), [&](const auto& p) { return p->identity == inbound_.peer; });
    if (it == peers_.end()) continue;
    if (inbound_.header.type == sabo::v1::MESSAGE_TYPE_GOODBYE) {
      try {
        inbound_.parse((*it)->goodbye);
      } catch (const ProtocolError&) {
      }
      (*it)->said_goodbye = true;
    } else if (inbound_.header.type == sabo::v1::MESSAGE_TYPE_ERROR) {
      (*it)->said_goodbye = true;
    }
  }
}

void Coupler::handle_failure(const std::exception& error, std::string& status, int& exit_code) {
  const bool solver_failed = !failure_.empty();
  const std::string process = solver_failed ? failure_.substr(0, failure_.find(':')) : "coupler";
  spdlog::error("{}", error.what());
  events_.error(process, solver_failed ? failure_.substr(failure_.find(':') + 2) : error.what());
  status = "failed";
  exit_code = solver_failed ? kSolverFailed : kFailed;
  if (failure_.empty()) failure_ = error.what();
  stop_solvers(fmt::format("the run failed: {}", failure_));
  wait_for_goodbyes(std::chrono::milliseconds(2000));
}

int Coupler::run() {
  start_wall_ = Clock::now();
  last_progress_ = start_wall_ - std::chrono::seconds(10);
  std::string status = "completed";
  int exit_code = kCompleted;
  try {
    checkpoint_store_ = std::make_unique<io::CheckpointStore>(
        options_.out_dir / "checkpoints", "coupler", io::file_digest(scene_.file), scene_.run.checkpoints_kept);
    if (!options_.resume.empty()) open_resume();
    const bool resuming = resume_step_.has_value();
    current_step_ = resume_step_.value_or(0);
    if (scene_.recording.enabled && options_.record) {
      std::ifstream scene_file(scene_.file);
      const std::string scene_text((std::istreambuf_iterator<char>(scene_file)), std::istreambuf_iterator<char>());
      const auto traffic = options_.out_dir / "traffic.h5";
      recorder_ = resuming ? std::make_unique<io::TrafficRecorder>(traffic, scene_.recording, scene_text,
                                                                   io::TrafficRecorder::ContinueAt{*resume_step_})
                           : std::make_unique<io::TrafficRecorder>(traffic, scene_.recording, scene_text);
    }
    // The run's files are opened before anyone can connect: connections of peers that do not register may
    // take every free descriptor between two of the connection guard's ticks.
    if (resuming) cut_histories();
    const auto close_file = [](std::FILE* f) { std::fclose(f); };
    const auto open_history = resuming ? open_for_appending : open_for_writing;
    std::unique_ptr<std::FILE, decltype(close_file)> forces_file(open_history(options_.out_dir / "forces.csv"),
                                                                 close_file);
    std::unique_ptr<std::FILE, decltype(close_file)> energy_file(open_history(options_.out_dir / "energy.csv"),
                                                                 close_file);
    std::unique_ptr<std::FILE, decltype(close_file)> sensors_file(
        scene_.sensors.empty() ? nullptr : open_history(options_.out_dir / "sensors.csv"), close_file);
    // The restart journals are opened before binding, as the run's other files: idle connections may take
    // every free descriptor later.
    if (scene_.run.restart) {
      for (const auto& solver : scene_.solvers) {
        journals_[solver.role] = std::make_unique<RestartJournal>(
            options_.out_dir / "checkpoints" / fmt::format("{}.journal", role_name(solver.role)),
            static_cast<std::uint64_t>(scene_.run.restart_journal_limit * 1e9));
      }
    }
    summary_out_.open(options_.out_dir / "summary.json.tmp");
    bind();
    bound_ = true;
    wait_for_registrations();
    if (resuming) restore_surface();
    prepare_contacts();
    std::vector<std::string> parts;
    for (const auto& s : scene_.structures) parts.push_back(s.name);
    forces_csv_ = std::make_unique<ForceHistory>(forces_file.release(), parts, force_sources_, !resuming);
    energy_csv_ = std::make_unique<EnergyHistory>(energy_file.release(), !resuming);
    if (sensors_file) {
      const auto fem =
          std::find_if(peers_.begin(), peers_.end(), [](const auto& p) { return p->registration.exposes_surface(); });
      assert(fem != peers_.end() && "sensors sit on structures, whose surface the fem_solver registers");
      sensors_ = std::make_unique<Sensors>(sensors_file.release(), scene_,
                                           protocol::surface_from_message((*fem)->registration.surface(), "fem_solver"),
                                           force_sources_, !resuming);
      if (sensors_->needs_point_loads()) {
        for (auto& slot : pairs_) slot.pair->want_point_loads();
      }
    }

    const double end_tolerance = 1e-12 * scene_.run.end_time;
    next_checkpoint_time_ = scene_.run.checkpoint_period();
    if (resuming) {
      restore_state();
      for (auto& [peer, inbound] : early_states_) {
        inbound_ = std::move(inbound);
        accept_state(*peer, current_step_);
      }
      early_states_.clear();
    }
    for (std::uint64_t step = current_step_;; ++step) {
      current_step_ = step;
      collect_states(step);
      // The coupler's own clock, the sum of the exchange steps it sent: each solver sums its own steps (with
      // substeps, in another order of rounding), and the first to register may be any of them.
      time_ = expected_time_;
      double step_compute = 0;
      cycles_.clear();
      for (auto& peer : peers_) {
        step_compute = std::max(step_compute, peer->reported_compute);
        peer->compute_seconds += peer->reported_compute;
        // Walls ahead went to the sph_solver at the exchange its state answers (reset at this one's pairs).
        const bool walls_came_ahead = walls_sent_ahead_ && peer->role == Role::sph;
        cycles_.push_back(
            {.compute = peer->reported_compute,
             .waited = peer->waited,
             .waited_for_forces = walls_came_ahead ? std::optional(peer->waited_for_forces) : std::nullopt});
      }
      critical_compute_seconds_ += step_compute;
      critical_contact_seconds_ +=
          pairs_on_critical_path(cycles_, {.all = last_contact_seconds_, .walls_ahead = last_walls_contact_seconds_});
      last_contact_seconds_ = 0;

      // A block of exchanges starts where every solver steps (every exchange without hold exchanges): its plan
      // is made there, after the pairs, whose limits it takes.
      const bool block_start = step - block_start_ >= block_length_;
      if (block_start) {
        block_start_ = step;
        for (auto& peer : peers_) peer->next_step_exchange = step;
      }
      const bool last = block_start && time_ >= scene_.run.end_time - end_tolerance;
      const bool output = block_start && (last || time_ >= next_output_time_ - 1e-9 * scene_.run.output_interval);
      if (block_start) advance_output_time();
      mark_evaluated_pairs(step);
      compute_contacts(step);
      check_newton_third_law(step);
      if (block_start) {
        plan_ = plan_step();
        block_length_ = *std::max_element(plan_.intervals.begin(), plan_.intervals.end());
      }
      const double dt = plan_.exchange_dt;
      if (!last) lock_step_equivalent_ += dt / plan_.lock_step_dt;
      dt_min_ = std::min(dt_min_, dt);
      dt_max_ = std::max(dt_max_, dt);
      if (last) events_.emit({{"event", "stopping"}, {"reason", "end_time reached"}});
      // Checkpoints of the state after this step, t_{n+1}, every checkpoint_period() of simulated time (none of
      // the final state: nothing would resume from it), where the next block starts.
      const double period = scene_.run.checkpoint_period();
      const bool next_starts_block = step + 1 - block_start_ >= block_length_;
      const bool checkpoint = !last && next_starts_block && period > 0 &&
                              time_ + dt < scene_.run.end_time - end_tolerance &&
                              time_ + dt >= next_checkpoint_time_ - 1e-9 * period;
      while (checkpoint && next_checkpoint_time_ <= time_ + dt + 1e-9 * period) next_checkpoint_time_ += period;
      if (checkpoint) ++checkpoints_;
      send_forces(step, output, last, checkpoint);
      // The run's own files, while the solvers compute.
      account(step, time_, dt, output);
      previous_block_start_ = block_start;
      for (auto& peer : peers_) peer->has_state = false;
      if (recorder_) recorder_->end_step(step);
      steps_ = step + 1;
      progress(step, time_, dt, last);
      if (last) break;
      dt_previous_ = dt;
      expected_time_ += dt;
      if (checkpoint) write_checkpoint(step + 1);
    }
    // Bounded whatever hang_timeout says (a SIGTERM ends the wait too).
    wait_for_goodbyes(
        std::chrono::milliseconds(static_cast<long>(1000 * std::clamp(scene_.run.hang_timeout, 5.0, 3600.0))));
    // The run is complete: nothing can restart any more.
    for (auto& peer : peers_) {
      if (peer->journal) peer->journal->remove();
    }
  } catch (const StopRequested& stop) {
    spdlog::warn("{}", stop.what());
    status = "stopped";
    exit_code = kStopped;
    events_.emit({{"event", "stopping"}, {"reason", stop.what()}});
    stop_solvers(stop.what());
    wait_for_goodbyes(std::chrono::milliseconds(3000));
  } catch (const SceneError& error) {
    spdlog::error("{}", error.what());
    events_.error("coupler", error.what());
    status = "failed";
    exit_code = kBadInput;
  } catch (const EndpointError& error) {
    // The scene's (or the command line's) endpoint cannot be bound: bad input, nothing was started.
    spdlog::error("{}", error.what());
    failure_ = error.what();
    events_.error("coupler", error.what());
    status = "failed";
    exit_code = kBadInput;
  } catch (const FileError& error) {
    if (bound_) {
      handle_failure(error, status, exit_code);
    } else {
      // A checkpoint to resume from (or a run file) that does not fit: bad input, nothing was started.
      spdlog::error("{}", error.what());
      failure_ = error.what();
      events_.error("coupler", error.what());
      status = "failed";
      exit_code = kBadInput;
    }
  } catch (const std::exception& error) {
    handle_failure(error, status, exit_code);
  }
  try {
    if (recorder_) recorder_->close();
    if (forces_csv_) forces_csv_->close();
    if (energy_csv_) energy_csv_->close();
    if (sensors_) sensors_->close();
    // A resume refused before it started leaves the run folder's summary as it was.
    if (bound_ || options_.resume.empty()) write_summary(status);
  } catch (const std::exception& error) {
    spdlog::error("while closing the run files: {}", error.what());
    if (exit_code == kCompleted) exit_code = kFailed;
  }
  events_.done(status, "summary.json");
  spdlog::info("{}: {} steps, t = {:.6g} s, {:.2f} s wall", status, steps_, time_, seconds_since(start_wall_));
  return exit_code;
}

}  // namespace sabo::coupler
