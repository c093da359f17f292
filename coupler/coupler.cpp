#include "coupler/coupler.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "libsabo/core/signals.hpp"
#include "libsabo/protocol/surface_codec.hpp"
#include "libsabo/protocol/wire.hpp"

namespace sabo::coupler {

namespace {

using Clock = std::chrono::steady_clock;
using sabo::v1::MessageType;
constexpr std::chrono::milliseconds kPollSlice{100};

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

bool all_finite(const google::protobuf::RepeatedField<double>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

}  // namespace

struct Coupler::Peer {
  std::string identity;
  sabo::v1::Role role = sabo::v1::ROLE_UNSPECIFIED;
  std::string role_name;
  double beta = 1.0;
  sabo::v1::Register registration;
  sabo::v1::StepState state;
  sabo::v1::StepForces forces;
  protocol::SendBuffer buffer;
  bool has_state = false;
  bool said_goodbye = false;
  sabo::v1::Goodbye goodbye;
  double compute_seconds = 0;  // reported in StepState, summed
};

Coupler::Coupler(const scene::Scene& scene, CouplerOptions options, EventStream& events)
    : scene_(scene), options_(std::move(options)), events_(events), socket_(context_, zmq::socket_type::router) {}

Coupler::~Coupler() = default;

void Coupler::fail(const std::string& process, const std::string& message) {
  failure_ = fmt::format("{}: {}", process, message);
  throw Error(failure_);
}

void Coupler::bind() {
  socket_.bind(options_.endpoint);
  spdlog::info("listening on {}", socket_.endpoint());
  events_.listening(socket_.endpoint());
}

Coupler::Peer* Coupler::route(const protocol::Inbound& inbound, MessageType expected, std::uint64_t step) {
  if (!inbound.valid()) {
    spdlog::warn("refused a malformed message: {}", inbound.problem);
    sabo::v1::Error error;
    error.set_code(sabo::v1::Error::CODE_MALFORMED);
    error.set_message(fmt::format("malformed message: {}", inbound.problem));
    socket_.send(error, inbound.peer);
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
    socket_.send(error, inbound.peer);
    return nullptr;
  }
  if (type == sabo::v1::MESSAGE_TYPE_ERROR) {
    sabo::v1::Error error;
    inbound.parse(error);
    fail(peer->role_name, fmt::format("reported an error: {}", error.message()));
  }
  if (type == sabo::v1::MESSAGE_TYPE_GOODBYE) {
    inbound.parse(peer->goodbye);
    peer->said_goodbye = true;
    if (expected != sabo::v1::MESSAGE_TYPE_GOODBYE) {
      fail(peer->role_name, fmt::format("left the run at step {}: {}", step, peer->goodbye.reason()));
    }
    return nullptr;
  }
  if (type != expected) {
    fail(peer->role_name, fmt::format("sent {} while the coupler expected {} (step {})",
                                      protocol::message_type_name(type), protocol::message_type_name(expected), step));
  }
  return peer;
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
    socket_.send(reply, inbound.peer);
  };
  try {
    inbound.parse(registration);
  } catch (const ProtocolError& error) {
    refuse(error.what());
    return;
  }
  const auto role = registration.role();
  const std::string name = protocol::role_name(role);
  if (registration.protocol_version() != protocol::kProtocolVersion ||
      inbound.header.version != protocol::kProtocolVersion) {
    refuse(
        fmt::format("{} speaks protocol version {}, this coupler speaks {}: rebuild the solver against "
                    "proto/sabo/v1 or use a matching coupler",
                    name, registration.protocol_version(), protocol::kProtocolVersion));
    return;
  }
  if (role != sabo::v1::ROLE_SPH && role != sabo::v1::ROLE_DEM && role != sabo::v1::ROLE_FEM) {
    refuse(fmt::format("unknown role {}: expected sph_solver, dem_solver or fem_solver", static_cast<int>(role)));
    return;
  }
  const scene::SolverSettings* settings = nullptr;
  for (const auto& s : scene_.solvers) {
    if (protocol::role_from_scene_name(scene::role_name(s.role)) == role) settings = &s;
  }
  if (settings == nullptr) {
    refuse(fmt::format("the scene {} has no bodies for a {}", scene_.file.string(), name));
    return;
  }
  for (const auto& peer : peers_) {
    if (peer->role == role) {
      refuse(fmt::format("the role {} is already taken by pid {}", name, peer->registration.pid()));
      return;
    }
  }
  const auto& table = registration.particles();
  const std::size_t n = static_cast<std::size_t>(table.id_size());
  if (static_cast<std::size_t>(table.radius_size()) != n || static_cast<std::size_t>(table.mass_size()) != n ||
      static_cast<std::size_t>(table.body_size()) != n) {
    refuse(fmt::format("{}: the particle table's arrays differ in length", name));
    return;
  }
  if (registration.exposes_surface()) {
    const auto& surface = registration.surface();
    if (!protocol::arrays_consistent(surface)) {
      refuse(fmt::format("{}: the surface's arrays are inconsistent", name));
      return;
    }
    fem_surface_nodes_ = surface.node_id_size();
    fem_surface_revision_ = surface.revision();
  }

  auto peer = std::make_unique<Peer>();
  peer->identity = inbound.peer;
  peer->role = role;
  peer->role_name = name;
  peer->beta = settings->beta;
  peer->registration = std::move(registration);
  reply.set_accepted(true);
  reply.set_interest_all(true);
  socket_.send(reply, inbound.peer);
  spdlog::info("registered {} (pid {}, '{}'): {} particles, {} surface nodes", name, peer->registration.pid(),
               peer->registration.name(), n, peer->registration.surface().node_id_size());
  events_.registered(name, peer->registration.pid(), peer->registration.name());
  if (recorder_) recorder_->record_registration(name, peer->registration);
  if (role == sabo::v1::ROLE_SPH) sph_ = peer.get();
  if (role == sabo::v1::ROLE_DEM) dem_ = peer.get();
  if (role == sabo::v1::ROLE_FEM) fem_ = peer.get();
  peers_.push_back(std::move(peer));
}

void Coupler::wait_for_registrations() {
  const auto deadline = Clock::now() + options_.registration_timeout;
  while (peers_.size() < scene_.solvers.size()) {
    if (stop_requested()) throw StopRequested("stopped by signal while waiting for the solvers to register");
    if (Clock::now() > deadline) {
      std::vector<std::string> missing;
      for (const auto& s : scene_.solvers) {
        const auto role = protocol::role_from_scene_name(scene::role_name(s.role));
        if (std::none_of(peers_.begin(), peers_.end(), [&](const auto& p) { return p->role == role; })) {
          missing.emplace_back(scene::role_name(s.role));
        }
      }
      fail("coupler", fmt::format("no registration from {} within {} s", fmt::join(missing, ", "),
                                  std::chrono::duration<double>(options_.registration_timeout).count()));
    }
    if (!socket_.receive(inbound_, kPollSlice)) continue;
    // A solver registered early may send its first state while others still register.
    const bool is_state = inbound_.valid() && inbound_.header.type == sabo::v1::MESSAGE_TYPE_STEP_STATE;
    Peer* peer = route(inbound_, is_state ? sabo::v1::MESSAGE_TYPE_STEP_STATE : sabo::v1::MESSAGE_TYPE_REGISTER, 0);
    if (peer != nullptr && is_state) accept_state(*peer, 0);
  }
}

void Coupler::accept_state(Peer& peer, std::uint64_t step) {
  if (peer.has_state) fail(peer.role_name, fmt::format("sent two states for step {}", step));
  try {
    inbound_.parse(peer.state);
  } catch (const ProtocolError& error) {
    fail(peer.role_name, error.what());
  }
  if (peer.state.step() != step) {
    fail(peer.role_name,
         fmt::format("sent the state of step {} while the coupler is at step {}", peer.state.step(), step));
  }
  validate_state(peer);
  peer.has_state = true;
  if (recorder_) recorder_->record_state(peer.role_name, peer.state);
}

void Coupler::collect_states(std::uint64_t step) {
  auto pending = [&] {
    return static_cast<std::size_t>(
        std::count_if(peers_.begin(), peers_.end(), [](const auto& p) { return !p->has_state; }));
  };
  auto wait_start = Clock::now();
  const auto hang = std::chrono::duration<double>(scene_.run.hang_timeout);
  while (pending() > 0) {
    if (stop_requested()) throw StopRequested(fmt::format("stopped by signal {} at step {}", stop_signal(), step));
    if (!socket_.receive(inbound_, kPollSlice)) {
      if (Clock::now() - wait_start > hang) {
        std::vector<std::string> silent;
        Peer* first_silent = nullptr;
        for (auto& peer : peers_) {
          if (peer->has_state) continue;
          silent.push_back(fmt::format("{} (pid {})", peer->role_name, peer->registration.pid()));
          peer->said_goodbye = true;  // a hung process will not say goodbye: do not wait for it
          if (first_silent == nullptr) first_silent = peer.get();
        }
        fail(first_silent->role_name,
             fmt::format("{} sent no state for step {} within hang_timeout = {} s: the process is hung or dead",
                         fmt::join(silent, " and "), step, scene_.run.hang_timeout));
      }
      continue;
    }
    const auto receive_start = Clock::now();
    Peer* peer = route(inbound_, sabo::v1::MESSAGE_TYPE_STEP_STATE, step);
    if (peer == nullptr) continue;
    accept_state(*peer, step);
    receive_seconds_ += seconds_since(receive_start);
  }
  wait_seconds_ += seconds_since(wait_start);
}

void Coupler::validate_state(const Peer& peer) {
  const auto& s = peer.state;
  const auto n = static_cast<std::size_t>(s.index_size());
  const auto table_size = static_cast<std::uint32_t>(peer.registration.particles().id_size());
  auto invalid = [&](const std::string& what) {
    fail(peer.role_name, fmt::format("state of step {}: {}", s.step(), what));
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
  if (!all_finite(s.position()) || !all_finite(s.velocity()) || !all_finite(s.angular_velocity())) {
    invalid("non-finite position or velocity (the solver has blown up)");
  }
  if (!std::isfinite(s.stable_dt()) && !std::isinf(s.stable_dt())) invalid("stable_dt is NaN");
  if (s.stable_dt() <= 0) invalid(fmt::format("stable_dt = {} must be > 0", s.stable_dt()));
  if (peer.registration.exposes_surface() && s.has_topology()) {
    // Elements eroded: the surface's new topology replaces the registered one
    // from this step on (checked like the registration's).
    if (walls_) {
      invalid(
          "a new surface topology (eroded elements) while the fluid's walls are boundary particles sampled "
          "at registration: not supported in this version (use [sph] wall_model = \"penalty\")");
    }
    const auto& topology = s.topology();
    if (!protocol::arrays_consistent(topology)) invalid("the new surface topology's arrays are inconsistent");
    if (topology.revision() <= fem_surface_revision_) {
      invalid(fmt::format("surface topology revision {} does not follow revision {}", topology.revision(),
                          fem_surface_revision_));
    }
    fem_surface_revision_ = topology.revision();
    fem_surface_nodes_ = topology.node_id_size();
  }
  if (s.boundary_force_size() != 0 || s.has_boundary_step() || (&peer == sph_ && walls_)) {
    const std::uint64_t steps_back = s.has_boundary_step() ? s.step() - s.boundary_step() : 1;
    if (s.has_boundary_step() && (s.boundary_step() >= s.step() || steps_back > 2)) {
      invalid(fmt::format("boundary_step = {} must be step - 1 or step - 2", s.boundary_step()));
    }
    const std::size_t sent = walls_ && &peer == sph_ ? walls_->selection(steps_back).size() : 0;
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
    const auto nodes = fem_surface_nodes_;
    if (s.node_position_size() != 3 * nodes || s.node_velocity_size() != 3 * nodes) {
      invalid(fmt::format("{} node positions for {} surface nodes", s.node_position_size(), nodes));
    }
    if (!all_finite(s.node_position()) || !all_finite(s.node_velocity())) invalid("non-finite node position");
  }
}

Coupler::PenaltyPair* Coupler::penalty_pair_of(const Peer* peer) const {
  for (const auto& pair : penalty_pairs_) {
    if (pair->solver == peer) return pair.get();
  }
  return nullptr;
}

void Coupler::warn_deep_overlap(PenaltyPair& pair) const {
  constexpr double kDeepOverlapRatio = 0.5;
  if (pair.warned_deep_overlap || !(pair.out.deepest_overlap_ratio > kDeepOverlapRatio)) return;
  pair.warned_deep_overlap = true;
  spdlog::warn(
      "t = {:.6g} s, contact of the {} with the structures: a particle overlaps a face by {:.3g} m, {:.2f} times the "
      "face's edge ({:.3g} m; "
      "warned once per run above {}). The penalty spring (paper eq. 6, k = k1 K A^2 / V, softer on finer meshes) "
      "is too soft for this mesh: the particle sinks through the element scale and contact forces and energies "
      "become unreliable. Fix: raise penalty_scale (k1) or set model = \"hertz_mindlin\" in [contact.dem_fem] "
      "([contact.sph_fem] for fluids; or the pair's [[interactions]]), or coarsen the structure's element_size",
      time_, force_sources_.at(pair.source), pair.out.deepest_overlap, pair.out.deepest_overlap_ratio,
      pair.out.deepest_face_edge, kDeepOverlapRatio);
}

void Coupler::prepare_contacts() {
  if (dem_ != nullptr) force_sources_.emplace_back("particles");
  if (sph_ != nullptr) force_sources_.emplace_back("fluid");
  if (fem_ == nullptr) return;
  const auto surface = protocol::surface_from_message(fem_->registration.surface(), "fem_solver");
  if (dem_ != nullptr) {
    auto pair = std::make_unique<PenaltyPair>();
    pair->solver = dem_;
    pair->source = 0;
    pair->contact = std::make_unique<SurfaceContact>(scene_);
    pair->contact->set_surface(surface);
    penalty_pairs_.push_back(std::move(pair));
  }
  if (sph_ == nullptr) return;
  const std::size_t fluid_source = force_sources_.size() - 1;
  if (scene_.sph.wall_model == scene::SphSettings::WallModel::penalty) {
    std::vector<std::string> fluids;
    for (const auto& fluid : scene_.fluids) fluids.push_back(fluid.name);
    // Settings of (fluid body, structure): an interaction naming both, else [contact.sph_fem].
    auto settings = [&scene = scene_](const std::string& fluid, const std::string& part) {
      return scene.surface_contact(fluid, part);
    };
    auto pair = std::make_unique<PenaltyPair>();
    pair->solver = sph_;
    pair->source = fluid_source;
    pair->contact = std::make_unique<SurfaceContact>(std::move(fluids), settings);
    pair->contact->set_surface(surface);
    penalty_pairs_.push_back(std::move(pair));
  } else {
    walls_ = std::make_unique<BoundaryWalls>(scene_.sph.particle_spacing, scene_.sph.kernel_support());
    walls_->set_surface(surface);
    walls_source_ = fluid_source;
    spdlog::info("sampled the FEM surface into {} boundary particles ({} layers at dx = {} m)",
                 walls_->sampling().size(), walls_->layers(), scene_.sph.particle_spacing);
  }
}

double Coupler::coupled_dt() const {
  double dt = std::numeric_limits<double>::infinity();
  for (const auto& peer : peers_) dt = std::min(dt, peer->beta * peer->state.stable_dt());
  for (const auto& pair : penalty_pairs_) dt = std::min(dt, pair->solver->beta * pair->contact->stable_dt());
  if (scene_.run.max_dt) dt = std::min(dt, *scene_.run.max_dt);
  // Only rigid parts and nothing else that limits the step: take output-sized steps.
  if (!std::isfinite(dt)) dt = scene_.run.output_interval;
  return dt;
}

void Coupler::compute_contacts(double dt_previous) {
  if (penalty_pairs_.empty() && !walls_) return;
  const auto start = Clock::now();
  const auto& fem_state = fem_->state;
  if (fem_state.has_topology()) {
    // Faces that left (eroded elements) leave the contact; exposed faces join.
    // Tangential springs carry over where their nodes remain (keyed by node ids).
    const auto surface = protocol::surface_from_message(fem_state.topology(), "fem_solver");
    for (auto& pair : penalty_pairs_) pair->contact->set_surface(surface);
  }
  const bool moved = fem_state.node_position_size() > 0;
  const std::span<const double> node_position{fem_state.node_position().data(),
                                              static_cast<std::size_t>(fem_state.node_position_size())};
  const std::span<const double> node_velocity{fem_state.node_velocity().data(),
                                              static_cast<std::size_t>(fem_state.node_velocity_size())};
  fem_node_force_.assign(3 * static_cast<std::size_t>(fem_surface_nodes_), 0.0);
  fem_node_force_nonzero_ = false;
  std::size_t contacts = 0;
  for (auto& pair : penalty_pairs_) {
    if (moved) pair->contact->update_nodes(node_position, node_velocity);
    pair->gather.gather(pair->solver->registration.particles(), pair->solver->state);
    pair->contact->compute(pair->gather.view(), dt_previous, pair->out);
    contacts += pair->out.contact_count;
    warn_deep_overlap(*pair);
    if (pair->out.contact_count > 0) {
      fem_node_force_nonzero_ = true;
      for (std::size_t i = 0; i < fem_node_force_.size(); ++i) fem_node_force_[i] += pair->out.node_force[i];
    }
  }
  if (walls_) {
    if (moved) walls_->update_nodes(node_position, node_velocity, dt_previous);
    const auto& returned = sph_->state.boundary_force();
    const std::size_t steps_back =
        sph_->state.has_boundary_step() ? sph_->state.step() - sph_->state.boundary_step() : 1;
    walls_->spread({returned.data(), static_cast<std::size_t>(returned.size())}, steps_back, walls_node_force_,
                   walls_part_force_);
    if (!returned.empty()) {
      fem_node_force_nonzero_ = true;
      for (std::size_t i = 0; i < fem_node_force_.size(); ++i) fem_node_force_[i] += walls_node_force_[i];
    }
    const auto& fluid = sph_->state.position();
    walls_->select_near({fluid.data(), static_cast<std::size_t>(fluid.size())});
    max_boundary_sent_ = std::max(max_boundary_sent_, walls_->selection().size());
  }
  max_contacts_ = std::max(max_contacts_, contacts);
  contact_seconds_ += seconds_since(start);
}

void Coupler::check_newton_third_law(std::uint64_t step) {
  if (penalty_pairs_.empty() && !walls_) return;
  Vec3 sum = Vec3::Zero();
  double scale = 0;
  for (const auto& pair : penalty_pairs_) {
    const auto& pf = pair->out.particle_force;
    for (std::size_t i = 0; i + 2 < pf.size(); i += 3) {
      sum += Vec3(pf[i], pf[i + 1], pf[i + 2]);
      scale += std::abs(pf[i]) + std::abs(pf[i + 1]) + std::abs(pf[i + 2]);
    }
  }
  if (walls_) {
    // The fluid feels minus the force it put on the boundary particles.
    const auto& bf = sph_->state.boundary_force();
    for (int i = 0; i + 2 < bf.size(); i += 3) {
      sum -= Vec3(bf[i], bf[i + 1], bf[i + 2]);
      scale += std::abs(bf[i]) + std::abs(bf[i + 1]) + std::abs(bf[i + 2]);
    }
  }
  const auto& nf = fem_node_force_;
  for (std::size_t i = 0; i + 2 < nf.size(); i += 3) sum += Vec3(nf[i], nf[i + 1], nf[i + 2]);
  if (scale == 0) return;
  const double residual = sum.norm() / scale;
  newton_max_residual_ = std::max(newton_max_residual_, residual);
  if (residual > 1e-10) {
    if (newton_violations_ == 0) {
      spdlog::error(
          "Newton's third law broken at step {}: the contact forces sum to ({:.3e}, {:.3e}, {:.3e}) N, "
          "{:.2e} of their total",
          step, sum.x(), sum.y(), sum.z(), residual);
    }
    ++newton_violations_;
  }
}

namespace {
// Adds the boxes to the peer's interest regions (it sends what lies in any of them).
void add_interest(sabo::v1::StepForces& f, const std::vector<Aabb>& boxes) {
  for (const Aabb& box : boxes) {
    auto* b = f.add_interest();
    b->set_min_x(box.min.x()), b->set_min_y(box.min.y()), b->set_min_z(box.min.z());
    b->set_max_x(box.max.x()), b->set_max_y(box.max.y()), b->set_max_z(box.max.z());
  }
  f.set_interest_all(false);
}

void assign_vectors(google::protobuf::RepeatedField<double>& field, const std::vector<Vec3>& values) {
  field.Resize(3 * static_cast<int>(values.size()), 0.0);
  double* out = field.mutable_data();
  for (std::size_t i = 0; i < values.size(); ++i) {
    out[3 * i] = values[i].x(), out[3 * i + 1] = values[i].y(), out[3 * i + 2] = values[i].z();
  }
}
}  // namespace

void Coupler::send_forces(std::uint64_t step, double dt, bool output, bool stop) {
  const auto start = Clock::now();
  for (auto& peer : peers_) {
    auto& f = peer->forces;
    f.Clear();
    f.set_step(step);
    f.set_dt(dt);
    f.set_output(output);
    f.set_stop(stop);
    if (peer.get() == dem_ || peer.get() == sph_) {
      const bool torque = peer->registration.exposes_angular_velocity();
      f.mutable_index()->CopyFrom(peer->state.index());
      const PenaltyPair* pair = penalty_pair_of(peer.get());
      if (pair != nullptr) {
        f.mutable_force()->Assign(pair->out.particle_force.begin(), pair->out.particle_force.end());
        if (torque) f.mutable_torque()->Assign(pair->out.particle_torque.begin(), pair->out.particle_torque.end());
        add_interest(f, pair->contact->interest_regions());
      } else {
        f.mutable_force()->Resize(3 * peer->state.index_size(), 0.0);
        if (torque) f.mutable_torque()->Resize(3 * peer->state.index_size(), 0.0);
        f.set_interest_all(false);  // nothing to touch: send nothing
      }
      if (peer.get() == sph_ && walls_) {
        const auto& b = walls_->selected();
        assign_vectors(*f.mutable_boundary_position(), b.position);
        assign_vectors(*f.mutable_boundary_velocity(), b.velocity);
        assign_vectors(*f.mutable_boundary_normal(), b.normal);
        assign_vectors(*f.mutable_boundary_acceleration(), b.acceleration);
        f.mutable_boundary_volume()->Assign(b.volume.begin(), b.volume.end());
        add_interest(f, walls_->interest_regions());
      }
    } else if (peer.get() == fem_) {
      if (fem_node_force_nonzero_) f.mutable_node_force()->Assign(fem_node_force_.begin(), fem_node_force_.end());
      f.set_interest_all(true);
    }
    if (recorder_) recorder_->record_forces(peer->role_name, f);
    socket_.send(f, peer->buffer, peer->identity);
  }
  send_seconds_ += seconds_since(start);
}

void Coupler::account(std::uint64_t step, double time, double dt, bool output) {
  if (forces_csv_) {
    for (const auto& pair : penalty_pairs_) {
      const auto& per_part = pair->out.part_force;  // [part] -> force from this solver's particles, N
      for (std::size_t part = 0; part < per_part.size(); ++part)
        forces_csv_->add(part, pair->source, per_part[part], dt);
    }
    if (walls_) {
      for (std::size_t part = 0; part < walls_part_force_.size(); ++part) {
        forces_csv_->add(part, walls_source_, walls_part_force_[part], dt);
      }
    }
  }
  if (forces_csv_ && output) forces_csv_->write(time);

  // A solver's energies in the state of step n describe step n - 1 (its kinetic
  // energy needs v_{n-1/2}), so they are paired with the contact energy of step n - 1.
  if (step > 0) {
    EnergySample sample;
    sample.time = previous_time_;
    for (const auto& peer : peers_) {
      const auto& e = peer->state.energies();
      sample.kinetic += e.kinetic();
      sample.potential += e.potential();
      sample.solver_elastic += e.elastic();
      sample.dissipated += e.dissipated();
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
  for (const auto& pair : penalty_pairs_) {
    previous_contact_elastic_ += pair->out.elastic_energy;
    // Dashpot and slip power of step n acts over dt_n.
    contact_dissipated_ += pair->out.dissipated_power * dt;
  }
}

void Coupler::progress(std::uint64_t step, double time, double dt, bool force_emit) {
  const auto now = Clock::now();
  if (!force_emit && now - last_progress_ < std::chrono::milliseconds(500)) return;
  last_progress_ = now;
  const double wall = seconds_since(start_wall_);
  const double rate = wall > 0 ? static_cast<double>(step) / wall : 0.0;
  const double remaining = std::max(0.0, scene_.run.end_time - time);
  const double eta = time > 0 ? wall * remaining / time : -1.0;
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
      spdlog::warn("could not send Stop to {}: {}", peer->role_name, error.what());
    }
  }
}

void Coupler::wait_for_goodbyes(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  auto missing = [&] {
    return std::any_of(peers_.begin(), peers_.end(), [](const auto& p) { return !p->said_goodbye; });
  };
  while (missing() && Clock::now() < deadline) {
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

void Coupler::write_summary(const std::string& status) {
  using nlohmann::json;
  const double wall = seconds_since(start_wall_);
  json processes = json::object();
  processes["coupler"] = {{"contact_seconds", contact_seconds_},
                          {"messaging_seconds", receive_seconds_ + send_seconds_},
                          {"wait_seconds", wait_seconds_ - receive_seconds_}};
  for (const auto& peer : peers_) {
    const bool have_goodbye = peer->said_goodbye && peer->goodbye.steps() > 0;
    processes[peer->role_name] = {
        {"pid", peer->registration.pid()},
        {"name", peer->registration.name()},
        {"compute_seconds", have_goodbye ? peer->goodbye.compute_seconds() : peer->compute_seconds},
        {"wait_seconds", have_goodbye ? peer->goodbye.wait_seconds() : peer->state.wait_seconds()},
        {"steps", have_goodbye ? peer->goodbye.steps() : steps_},
        {"exit", peer->said_goodbye ? peer->goodbye.reason() : std::string("no goodbye")}};
  }
  const double per_step = steps_ > 0 ? 1.0 / static_cast<double>(steps_) : 0.0;
  const double overhead = std::max(0.0, wall - critical_compute_seconds_ - contact_seconds_);
  json energies = json::object();
  if (energy_csv_) {
    auto sample_json = [](const EnergySample& e) {
      return json{{"time", e.time},
                  {"kinetic", e.kinetic},
                  {"potential", e.potential},
                  {"solver_elastic", e.solver_elastic},
                  {"contact_elastic", e.contact_elastic},
                  {"dissipated", e.dissipated},
                  {"total", e.total()}};
    };
    energies = {{"initial", sample_json(energy_csv_->initial())},
                {"final", sample_json(energy_csv_->last())},
                {"max_total", energy_csv_->max_total()},
                {"max_rise_over_initial", energy_csv_->max_total() - energy_csv_->initial().total()}};
  }
  // Deformable FEM parts: the history of internal, kinetic, plastic work,
  // hourglass and eroded energy at the output times (columns), and the largest
  // hourglass share of the internal energy among the samples holding at least
  // a tenth of the part's largest internal energy.
  json structures = json::object();
  for (const auto& [part, samples] : part_energies_.history()) {
    json columns = {{"time", json::array()},          {"kinetic", json::array()},        {"internal", json::array()},
                    {"plastic_work", json::array()},  {"hourglass", json::array()},      {"eroded", json::array()},
                    {"external_work", json::array()}, {"eroded_elements", json::array()}};
    double peak_internal = 0;
    for (const auto& e : samples) {
      columns["time"].push_back(e.time);
      columns["kinetic"].push_back(e.kinetic);
      columns["internal"].push_back(e.internal);
      columns["plastic_work"].push_back(e.plastic_work);
      columns["hourglass"].push_back(e.hourglass);
      columns["eroded"].push_back(e.eroded);
      columns["external_work"].push_back(e.external_work);
      columns["eroded_elements"].push_back(e.eroded_elements);
      peak_internal = std::max(peak_internal, e.internal);
    }
    double worst_hourglass = 0;
    for (const auto& e : samples) {
      if (e.internal > 0 && e.internal >= 0.1 * peak_internal) {
        worst_hourglass = std::max(worst_hourglass, e.hourglass / e.internal);
      }
    }
    structures[part] = {{"history", columns}, {"max_hourglass_over_internal", worst_hourglass}};
  }
  if (!structures.empty()) energies["structures"] = structures;
  json peak_forces = json::object();
  if (forces_csv_) {
    for (std::size_t part = 0; part < forces_csv_->part_names().size(); ++part) {
      for (std::size_t source = 0; source < forces_csv_->sources().size(); ++source) {
        peak_forces[forces_csv_->part_names()[part]][forces_csv_->sources()[source]] =
            forces_csv_->peak()[part][source];
      }
    }
  }
  json effects = json::array();
  if (dem_ != nullptr) {
    const auto& c = scene_.dem_contact;
    const double dem_seconds = processes["dem_solver"]["compute_seconds"].get<double>();
    effects.push_back({{"effect", "dem_dem_contact"}, {"process", "dem_solver"}, {"seconds", dem_seconds}});
    if (c.friction > 0) effects.push_back({{"effect", "dem_sliding_friction"}, {"process", "dem_solver"}});
    if (c.rolling_friction > 0) effects.push_back({{"effect", "dem_rolling_friction"}, {"process", "dem_solver"}});
  }
  for (const auto& pair : penalty_pairs_) {
    const char* effect = pair->solver == dem_ ? "dem_fem_contact" : "sph_fem_penalty_contact";
    effects.push_back({{"effect", effect}, {"process", "coupler"}, {"seconds", contact_seconds_}});
  }
  if (walls_) {
    effects.push_back({{"effect", "sph_fem_boundary_particles"},
                       {"process", "coupler"},
                       {"seconds", contact_seconds_},
                       {"boundary_particles", walls_->sampling().size()},
                       {"max_sent_per_step", max_boundary_sent_},
                       {"layers", walls_->layers()}});
  }
  if (recorder_) effects.push_back({{"effect", "traffic_recording"}, {"process", "coupler"}});

  json summary = {
      {"status", status},
      {"failure", failure_},
      {"scene", scene_.file.string()},
      {"steps", steps_},
      {"simulated_time", time_},
      {"end_time", scene_.run.end_time},
      {"wall_seconds", wall},
      {"steps_per_second", wall > 0 ? static_cast<double>(steps_) / wall : 0.0},
      {"dt", {{"min", std::isfinite(dt_min_) ? dt_min_ : 0.0}, {"max", dt_max_}}},
      {"processes", processes},
      {"coupling_overhead",
       {{"seconds", overhead},
        {"microseconds_per_step", 1e6 * overhead * per_step},
        {"fraction_of_wall", wall > 0 ? overhead / wall : 0.0}}},
      {"bytes_exchanged",
       {{"received", socket_.bytes_received()},
        {"sent", socket_.bytes_sent()},
        {"per_step", static_cast<double>(socket_.bytes_received() + socket_.bytes_sent()) * per_step}}},
      {"traffic", {{"file", "traffic.h5"}, {"bytes", recorder_ ? recorder_->bytes_written() : 0}}},
      {"energies", energies},
      {"newton_third_law", {{"max_relative_residual", newton_max_residual_}, {"violations", newton_violations_}}},
      {"contacts", {{"max_simultaneous", max_contacts_}}},
      {"peak_force", peak_forces},
      {"active_effects", effects},
  };
  const auto file = options_.out_dir / "summary.json";
  const auto temporary = options_.out_dir / "summary.json.tmp";
  {
    std::ofstream out(temporary);
    out << summary.dump(2) << "\n";
    if (!out) throw FileError(fmt::format("cannot write '{}'", temporary.string()));
  }
  std::filesystem::rename(temporary, file);
}

int Coupler::run() {
  start_wall_ = Clock::now();
  last_progress_ = start_wall_ - std::chrono::seconds(10);
  std::string status = "completed";
  int exit_code = kCompleted;
  try {
    if (scene_.recording.enabled) {
      std::ifstream scene_file(scene_.file);
      const std::string scene_text((std::istreambuf_iterator<char>(scene_file)), std::istreambuf_iterator<char>());
      recorder_ = std::make_unique<io::TrafficRecorder>(options_.out_dir / "traffic.h5", scene_.recording, scene_text);
    }
    bind();
    wait_for_registrations();
    prepare_contacts();
    std::vector<std::string> parts;
    for (const auto& s : scene_.structures) parts.push_back(s.name);
    forces_csv_ = std::make_unique<ForceHistory>(options_.out_dir / "forces.csv", parts, force_sources_);
    energy_csv_ = std::make_unique<EnergyHistory>(options_.out_dir / "energy.csv");

    double dt_previous = 0;
    const double end_tolerance = 1e-12 * scene_.run.end_time;
    for (std::uint64_t step = 0;; ++step) {
      collect_states(step);
      time_ = peers_.front()->state.time();
      double step_compute = 0;
      for (auto& peer : peers_) {
        step_compute = std::max(step_compute, peer->state.compute_seconds());
        peer->compute_seconds += peer->state.compute_seconds();
      }
      critical_compute_seconds_ += step_compute;

      const bool last = time_ >= scene_.run.end_time - end_tolerance;
      const bool output = last || time_ >= next_output_time_ - 1e-9 * scene_.run.output_interval;
      while (next_output_time_ <= time_ + 1e-9 * scene_.run.output_interval) {
        next_output_time_ += scene_.run.output_interval;
      }
      compute_contacts(dt_previous);
      check_newton_third_law(step);
      const double dt = coupled_dt();
      dt_min_ = std::min(dt_min_, dt);
      dt_max_ = std::max(dt_max_, dt);
      account(step, time_, dt, output);
      if (last) events_.emit({{"event", "stopping"}, {"reason", "end_time reached"}});
      send_forces(step, dt, output, last);
      for (auto& peer : peers_) peer->has_state = false;
      if (recorder_) recorder_->end_step(step);
      steps_ = step + 1;
      progress(step, time_, dt, last);
      if (last) break;
      dt_previous = dt;
    }
    wait_for_goodbyes(std::chrono::milliseconds(static_cast<long>(1000 * std::max(5.0, scene_.run.hang_timeout))));
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
  } catch (const std::exception& error) {
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
  try {
    if (recorder_) recorder_->close();
    if (forces_csv_) forces_csv_->close();
    if (energy_csv_) energy_csv_->close();
    write_summary(status);
  } catch (const std::exception& error) {
    spdlog::error("while closing the run files: {}", error.what());
    if (exit_code == kCompleted) exit_code = kFailed;
  }
  events_.done(status, "summary.json");
  spdlog::info("{}: {} steps, t = {:.6g} s, {:.2f} s wall", status, steps_, time_, seconds_since(start_wall_));
  return exit_code;
}

}  // namespace sabo::coupler
