// The coupler's registrations: a solver's Register checked against the scene and answered, a restarted
// solver's replacement accepted and caught up from its checkpoint (docs/restart.md), and the wait for every
// role the scene needs.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

#include "coupler/coupler.hpp"
#include "coupler/coupler_peer.hpp"
#include "coupler/message_checks.hpp"
#include "libsabo/core/signals.hpp"
#include "libsabo/protocol/wire.hpp"

namespace sabo::coupler {

std::optional<std::string> Coupler::identity_problem(const protocol::Inbound& inbound, const protocol::PeerInfo& who,
                                                     const std::string& name) const {
  if (authenticator_ && inbound.user_id != name) {
    return fmt::format(
        "this connection authenticated as '{}' (with that role's {}) and cannot register as {}: each role joins "
        "with its own keys (RUN_DIR/keys/{}.key_secret)",
        inbound.user_id, mechanism_ == protocol::Mechanism::curve ? "key" : "name", name, name);
  }
  if (who.uid >= 0 && static_cast<unsigned>(who.uid) != ::geteuid()) {
    return fmt::format(
        "the process at the other end ({}) belongs to user {}, and this run to user {}: only the run's "
        "user may join it",
        who.address, who.uid, ::geteuid());
  }
  return std::nullopt;
}

void Coupler::accept_registration(const protocol::Inbound& inbound) {
  sabo::v1::Register registration;
  sabo::v1::RegisterReply reply;
  reply.set_protocol_version(protocol::kProtocolVersion);
  reply.set_end_time(scene_.run.end_time);
  auto refuse = [&](const std::string& why) {
    spdlog::warn("refused a registration: {}", why);
    reply.set_accepted(false);
    reply.set_error(why);
    reply_to_unregistered(reply, inbound.peer);
  };
  try {
    inbound.parse(registration);
  } catch (const ProtocolError& error) {
    refuse(error.what());
    return;
  }
  const std::string name = protocol::role_name(registration.role());
  if (registration.protocol_version() != protocol::kProtocolVersion ||
      inbound.header.version != protocol::kProtocolVersion) {
    refuse(
        fmt::format("{} speaks protocol version {}, this coupler speaks {}: rebuild the solver against "
                    "proto/sabo/v1 or use a matching coupler",
                    name, registration.protocol_version(), protocol::kProtocolVersion));
    return;
  }
  const std::optional<Role> known_role = protocol::from_wire(registration.role());
  if (!known_role) {
    refuse(fmt::format("unknown role {}: expected sph_solver, dem_solver or fem_solver",
                       static_cast<int>(registration.role())));
    return;
  }
  const Role role = *known_role;
  const protocol::PeerInfo who = protocol::peer_info(inbound.source_fd);
  if (auto problem = identity_problem(inbound, who, name)) {
    refuse(*problem);
    return;
  }
  const scene::SolverSettings* settings = scene_.solver(role);
  if (settings == nullptr) {
    refuse(fmt::format("the scene {} has no bodies for a {}", scene_.file.string(), name));
    return;
  }
  const bool role_taken =
      std::any_of(peers_.begin(), peers_.end(), [&](const auto& peer) { return peer->role == role; });
  if (registration.resumed() && (role_taken || !resume_step_)) {
    accept_replacement(inbound, registration);
    return;
  }
  if (resume_step_ && !role_taken) {
    // A resumed run (docs/restart.md, "Resuming a run"): every solver continues from its checkpoint of the
    // coupler's step.
    const std::string fix = fmt::format("start it with --resume RUN_DIR/checkpoints/{}_{:010}.h5", name, *resume_step_);
    if (!registration.resumed()) {
      refuse(
          fmt::format("the coupler resumes this run at step {} from its checkpoint, and {} registered to start at "
                      "step 0: {}",
                      *resume_step_, name, fix));
      return;
    }
    if (registration.resume_step() != *resume_step_) {
      refuse(fmt::format("{} resumes at step {}, the coupler at step {}: {}", name, registration.resume_step(),
                         *resume_step_, fix));
      return;
    }
  }
  for (const auto& peer : peers_) {
    if (peer->role == role) {
      refuse(fmt::format("the role {} is already taken by pid {}", name, peer->registration.pid()));
      return;
    }
  }
  const auto& table = registration.particles();
  const std::size_t n = static_cast<std::size_t>(table.id_size());
  if (auto problem = particle_table_problem(table, scene_, settings->role)) {
    refuse(fmt::format("{}: {}", name, *problem));
    return;
  }
  if (registration.exposes_surface()) {
    if (auto problem = surface_problem(registration.surface(), scene_)) {
      refuse(fmt::format("{}: the surface: {}", name, *problem));
      return;
    }
  }
  // The registration's stable step is informative (0: not given); the states' are checked every step.
  if (registration.stable_dt() != 0) {
    if (auto problem = stable_dt_problem(registration.stable_dt(), scene_.run.end_time)) {
      refuse(fmt::format("{}: {}", name, *problem));
      return;
    }
  }
  if (registration.exposes_surface()) {
    surface_nodes_ = static_cast<std::size_t>(registration.surface().node_id_size());
    surface_revision_ = registration.surface().revision();
  }

  auto peer = std::make_unique<Peer>();
  if (auto journal = journals_.find(role); journal != journals_.end()) peer->journal = std::move(journal->second);
  peer->identity = inbound.peer;
  peer->source_fd = inbound.source_fd;
  if (who.uid < 0) peer->address = who.address;  // tcp (over ipc the pid is the registration's)
  peer->role = role;
  peer->beta = settings->beta;
  peer->registration = std::move(registration);
  reply.set_accepted(true);
  reply.set_interest_all(true);
  if (!reply_to_unregistered(reply, inbound.peer)) {
    spdlog::warn("{} (pid {}) left before its registration was answered: not registered", name,
                 peer->registration.pid());
    return;
  }
  guard_->registered(inbound.source_fd);
  spdlog::info("registered {} (pid {}, '{}'): {} particles, {} surface nodes", name, peer->registration.pid(),
               peer->registration.name(), n, peer->registration.surface().node_id_size());
  events_.registered(name, peer->registration.pid(), peer->registration.name(), who.pid,
                     who.uid < 0 ? who.address : std::string());
  // A resumed run's recording holds the registrations of its start already.
  if (recorder_ && !resume_step_) recorder_->record_registration(name, peer->registration);
  if (resume_step_) peer->checkpoint_step = *resume_step_;  // its restart journal starts at its checkpoint
  solvers_.set({.role = peer->role, .beta = peer->beta, .registration = &peer->registration, .state = &peer->state});
  peers_.push_back(std::move(peer));
}

void Coupler::accept_replacement(const protocol::Inbound& inbound, const sabo::v1::Register& registration) {
  const std::string name = protocol::role_name(registration.role());
  sabo::v1::RegisterReply reply;
  reply.set_protocol_version(protocol::kProtocolVersion);
  reply.set_end_time(scene_.run.end_time);
  auto refuse = [&](const std::string& why) {
    spdlog::warn("refused the restarted {}: {}", name, why);
    reply.set_accepted(false);
    reply.set_error(why);
    reply_to_unregistered(reply, inbound.peer);
  };
  const std::optional<Role> role = protocol::from_wire(registration.role());
  auto it = std::find_if(peers_.begin(), peers_.end(), [&](const auto& p) { return p->role == role; });
  if (it == peers_.end()) {
    refuse(fmt::format("{} registered as resumed from step {}, but no {} has run yet: start it without --resume", name,
                       registration.resume_step(), name));
    return;
  }
  Peer& peer = **it;
  const std::uint64_t from = registration.resume_step();
  if (!peer.journal) {
    refuse(fmt::format("the scene does not restart solvers ([run] restart = \"off\"): {} cannot rejoin", name));
    return;
  }
  if (peer.journal->dropped()) {
    refuse(fmt::format("{} resumes at step {}, but it cannot rejoin: {}", name, from, journal_dropped(peer)));
    return;
  }
  if (from < peer.journal->first_step() || from > current_step_) {
    refuse(fmt::format(
        "{} resumes at step {}; the coupler, at step {}, can feed it steps {} to {} (from its newest "
        "checkpoint): restart it from RUN_DIR/checkpoints/{}_{:010}.h5",
        name, from, current_step_, peer.journal->first_step(), current_step_, name, peer.journal->first_step()));
    return;
  }
  if (registration.particles().SerializeAsString() != peer.registration.particles().SerializeAsString() ||
      registration.exposes_surface() != peer.registration.exposes_surface()) {
    refuse(
        fmt::format("the restarted {} registers another particle table or surface than the one it replaces: "
                    "restart the same program with the same scene",
                    name));
    return;
  }
  reply.set_accepted(true);
  reply.set_interest_all(true);  // a resumed solver keeps the regions of its checkpoint
  if (!reply_to_unregistered(reply, inbound.peer)) return;
  guard_->registered(inbound.source_fd);
  spdlog::warn("{} (pid {}) rejoins from its checkpoint of step {} (pid {} before): catching up {} steps", name,
               registration.pid(), from, peer.registration.pid(), current_step_ - from);
  peer.identity = inbound.peer;
  peer.source_fd = inbound.source_fd;
  if (const auto who = protocol::peer_info(inbound.source_fd); who.uid < 0) peer.address = who.address;
  peer.registration.set_pid(registration.pid());
  peer.catching_up = from < peer.journal->end_step() || (peer.has_state && from <= current_step_);
  peer.resumed_at = from;
  peer.restarted_wall = Clock::now();
  ++peer.restarts;
  nlohmann::json restarted = {{"event", "restarted"},      {"process", name},
                              {"pid", registration.pid()}, {"from_step", from},
                              {"at_step", current_step_},  {"catch_up_steps", current_step_ - from}};
  if (!peer.address.empty()) restarted["address"] = peer.address;
  events_.emit(restarted);
  // Killed after its checkpoint and before its next state, it has nothing to catch up: it is back already.
  if (!peer.catching_up) caught_up(peer, current_step_);
}

bool Coupler::restarting() const {
  return std::any_of(peers_.begin(), peers_.end(), [](const auto& p) { return p->catching_up; });
}

bool Coupler::catch_up(Peer& peer, std::uint64_t step) {
  sabo::v1::StepState state;
  try {
    inbound_.parse(state);
  } catch (const ProtocolError& error) {
    fail(peer.name(), error.what());
  }
  const std::uint64_t s = state.step();
  const bool replayed = s < step || (s == step && peer.has_state);
  if (!replayed) {  // the live step: caught up
    caught_up(peer, step);
    return false;
  }
  const bool known = s >= peer.journal->first_step() && (s < peer.journal->end_step() || (s == step && peer.has_state));
  if (!known) {
    fail(peer.name(), fmt::format("the restarted process sent the state of step {}; the coupler can check steps {} "
                                  "to {} (it resumed at step {})",
                                  s, peer.journal->first_step(), step, peer.resumed_at));
  }
  const std::string differs = peer.journal->first_difference(state);
  if (!differs.empty()) {
    fail(peer.name(),
         fmt::format("restarted from its checkpoint of step {}, it sent a state of step {} that differs from the one "
                     "it sent before it died, first in field {}: the restart would change the answer, so the run "
                     "stops. Find where with ./sabo replay RUN_DIR {} --resume RUN_DIR/checkpoints/{}_{:010}.h5",
                     peer.resumed_at, s, differs, role_key(peer.role), peer.name(), peer.resumed_at));
  }
  if (s < step) socket_.send(peer.journal->forces(s), peer.buffer, peer.identity);
  if (s + 1 == step || s == step) caught_up(peer, step);
  return true;
}

void Coupler::caught_up(Peer& peer, std::uint64_t step) {
  peer.catching_up = false;
  const double seconds = seconds_since(peer.restarted_wall);
  spdlog::info("{} caught up from step {} to step {} in {:.2f} s", peer.name(), peer.resumed_at, step, seconds);
  events_.emit({{"event", "caught_up"},
                {"process", peer.name()},
                {"from_step", peer.resumed_at},
                {"at_step", step},
                {"seconds", seconds}});
  restarts_.push_back({{"process", peer.name()},
                       {"pid", peer.registration.pid()},
                       {"from_step", peer.resumed_at},
                       {"at_step", step},
                       {"catch_up_steps", step - peer.resumed_at},
                       {"catch_up_seconds", seconds}});
}

void Coupler::wait_for_registrations() {
  const auto deadline = Clock::now() + options_.registration_timeout;
  while (peers_.size() < scene_.solvers.size()) {
    if (stop_requested()) throw StopRequested("stopped by signal while waiting for the solvers to register");
    if (Clock::now() > deadline) {
      std::vector<std::string> missing;
      for (const auto& s : scene_.solvers) {
        if (std::none_of(peers_.begin(), peers_.end(), [&](const auto& p) { return p->role == s.role; })) {
          missing.emplace_back(role_name(s.role));
        }
      }
      fail("coupler", fmt::format("no registration from {} within {} s", fmt::join(missing, ", "),
                                  std::chrono::duration<double>(options_.registration_timeout).count()));
    }
    guard_->tick();
    if (!socket_.receive(inbound_, kPollSlice)) continue;
    // A solver registered early may send its first state while others still register.
    const bool is_state = inbound_.valid() && inbound_.header.type == sabo::v1::MESSAGE_TYPE_STEP_STATE;
    Peer* peer = route(inbound_, is_state ? sabo::v1::MESSAGE_TYPE_STEP_STATE : sabo::v1::MESSAGE_TYPE_REGISTER, 0);
    if (peer == nullptr || !is_state) continue;
    if (resume_step_) {
      // Checked once the pairs and the boundary particles' lists are restored (they judge it).
      early_states_.emplace_back(peer, std::move(inbound_));
      inbound_ = protocol::Inbound{};
    } else {
      accept_state(*peer, current_step_);
    }
  }
}

}  // namespace sabo::coupler
