#include "coupler/contact/sph_dem_boundary_pair.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/Geometry>
#include <cassert>
#include <cmath>

#include "coupler/contact/history_io.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/covering_boxes.hpp"
#include "libsabo/physics/cell_list.hpp"

namespace sabo::coupler {

namespace {

std::span<const double> span_of(const google::protobuf::RepeatedField<double>& field) {
  return {field.data(), static_cast<std::size_t>(field.size())};
}

Vec3 vec3_at(const google::protobuf::RepeatedField<double>& field, std::size_t k) {
  const auto i = static_cast<int>(3 * k);
  return {field[i], field[i + 1], field[i + 2]};
}

std::size_t steps_back(const sabo::v1::StepState& state) {
  return state.has_boundary_step() ? state.step() - state.boundary_step() : 1;
}

}  // namespace

SphDemBoundaryPair::SphDemBoundaryPair(const scene::Scene& scene)
    : spacing_(scene.sph.particle_spacing),
      support_(scene.sph.kernel_support()),
      layers_(static_cast<std::size_t>(std::max(1.0, std::ceil(support_ / spacing_ - 1e-9)))),
      margin_(0.25 * support_) {
  for (const auto& set : scene.particle_sets) boundary_set_.push_back(scene.boundary_particle_set(set.name) ? 1 : 0);
  if (scene.sph.periodic_x) periodic_.emplace_back(0, *scene.sph.periodic_x);
  if (scene.sph.periodic_y) periodic_.emplace_back(1, *scene.sph.periodic_y);
}

void SphDemBoundaryPair::start(const Solvers& solvers, Replies& replies) {
  channel_ = &replies.boundary();
  slot_ = replies.boundary().join();
  const auto& table = solvers.at(Role::dem).registration->particles();
  const auto n = static_cast<std::size_t>(table.id_size());
  sampling_.assign(n, nullptr);
  std::size_t sampled = 0, particles = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t body = table.body(static_cast<int>(i));
    if (body >= boundary_set_.size() || boundary_set_[body] == 0) continue;
    const double radius = table.radius(static_cast<int>(i));
    auto it = sampling_by_radius_.find(radius);
    if (it == sampling_by_radius_.end()) {
      it = sampling_by_radius_.emplace(radius, geometry::sample_sphere(radius, spacing_, layers_)).first;
    }
    sampling_[i] = &it->second;
    max_radius_ = std::max(max_radius_, radius);
    for (const Vec3& offset : it->second.offset) max_reach_ = std::max(max_reach_, offset.norm());
    ++sampled;
    particles += it->second.size();
  }
  // The coupler checks every state's indices against the table (and restore_history() the kept ones).
  kept_slot_of_id_.assign(static_cast<std::size_t>(solvers.at(Role::sph).registration->particles().id_size()), -1);
  force_.assign(n, Vec3::Zero());
  torque_.assign(n, Vec3::Zero());
  last_velocity_.assign(n, Vec3::Zero());
  last_spin_.assign(n, Vec3::Zero());
  has_last_.assign(n, 0);
  spdlog::info("sampled {} boulders into {} boundary particles ({} layers at dx = {} m)", sampled, particles, layers_,
               spacing_);
}

void SphDemBoundaryPair::compute(const Solvers& solvers, const StepClock& clock) {
  // 1. The fluid's forces on the particles of an earlier StepForces, summed per boulder.
  const sabo::v1::StepState& fluid = *solvers.at(Role::sph).state;
  const std::size_t back = steps_back(fluid);
  const std::span<const double> returned = channel_->slice(slot_, span_of(fluid.boundary_force()), back);
  for (const std::uint32_t o : touched_) force_[o] = torque_[o] = Vec3::Zero();
  touched_.clear();
  balance_ = {};
  if (!returned.empty()) {
    const Sent& then = sent_[back - 1];
    if (returned.size() != 3 * then.owner.size()) {
      throw ProtocolError(fmt::format("{} boundary_force values for the {} boulder particles sent then",
                                      returned.size(), then.owner.size()));
    }
    for (std::size_t k = 0; k < then.owner.size(); ++k) {
      const Vec3 f(returned[3 * k], returned[3 * k + 1], returned[3 * k + 2]);
      const std::uint32_t o = then.owner[k];
      if (k == 0 || then.owner[k - 1] != o) touched_.push_back(o);  // each boulder's particles are consecutive
      force_[o] += f;
      torque_[o] += then.lever[k].cross(f);
      balance_.sum -= f;  // the fluid feels minus what it put on the particles
      balance_.scale += std::abs(f.x()) + std::abs(f.y()) + std::abs(f.z());
    }
    for (const std::uint32_t o : touched_) balance_.sum += force_[o];
    // The fluid's step that just ended (that of the last StepForces) whatever wall particles it took: those of
    // that step, or with lagged boundary particles those of the step before, moved ahead.
    force_dt_avg_ = sent_[0].dt_avg;
  }
  boulders_touched_ = touched_.size();

  // 2. The boulders' particles of this step, unless the coupler had them placed ahead of the fluid's state.
  fluid_position_.resize(static_cast<std::size_t>(fluid.position_size()) / 3);
  for (std::size_t f = 0; f < fluid_position_.size(); ++f) fluid_position_[f] = vec3_at(fluid.position(), f);
  if (!placed_) {
    place(solvers, clock, kept_ ? std::span<const Vec3>(kept_position_) : std::span<const Vec3>(fluid_position_),
          margin_);
  }
  if (kept_) check_fluid_moved_within_margin(fluid, clock.step);  // placed from it, ahead or just now
  std::swap(kept_position_, fluid_position_);
  kept_index_.assign(fluid.index().begin(), fluid.index().end());
  kept_ = true;
  placed_ = false;
}

void SphDemBoundaryPair::place_ahead(const Solvers& solvers, const StepClock& clock) {
  assert(kept_ && "the coupler places ahead only a pair that can_place_ahead()");
  place(solvers, clock, kept_position_, margin_);
  placed_ = true;
}

void SphDemBoundaryPair::place(const Solvers& solvers, const StepClock& clock, std::span<const Vec3> fluid,
                               double margin) {
  const SolverView& dem = solvers.at(Role::dem);
  const sabo::v1::StepState& boulders = *dem.state;
  const double dt_previous = clock.dt_previous;
  candidate_position_.clear();
  candidate_owner_.clear();
  candidate_point_.clear();
  centre_cover_.clear();
  struct Motion {
    std::uint32_t table;  // DEM table index
    Vec3 centre, velocity, spin, acceleration, angular_acceleration;
  };
  std::vector<Motion> motion;
  const bool spins = boulders.angular_velocity_size() == boulders.position_size();
  for (std::size_t k = 0; k < static_cast<std::size_t>(boulders.index_size()); ++k) {
    const std::uint32_t i = boulders.index(static_cast<int>(k));
    if (i >= sampling_.size() || sampling_[i] == nullptr) continue;
    Motion m;
    m.table = i;
    m.centre = vec3_at(boulders.position(), k);
    m.velocity = vec3_at(boulders.velocity(), k);
    m.spin = spins ? vec3_at(boulders.angular_velocity(), k) : Vec3::Zero();
    const bool known = has_last_[i] != 0 && dt_previous > 0;
    m.acceleration = known ? Vec3((m.velocity - last_velocity_[i]) / dt_previous) : Vec3::Zero();
    m.angular_acceleration = known ? Vec3((m.spin - last_spin_[i]) / dt_previous) : Vec3::Zero();
    last_velocity_[i] = m.velocity;
    last_spin_[i] = m.spin;
    has_last_[i] = 1;
    centre_cover_.push_back(m.centre);
    const auto& sampling = *sampling_[i];
    for (std::size_t p = 0; p < sampling.size(); ++p) {
      Vec3 x = m.centre + sampling.offset[p];
      // A boulder at a periodic seam: its particles beyond it stand where the fluid's images are.
      for (const auto& [axis, span] : periodic_) {
        const double period = span[1] - span[0];
        x[axis] -= period * std::floor((x[axis] - span[0]) / period);
      }
      candidate_position_.push_back(x);
      candidate_owner_.push_back(static_cast<std::uint32_t>(motion.size()));
      candidate_point_.push_back(static_cast<std::uint32_t>(p));
    }
    motion.push_back(m);
  }
  // Boulders that were not in this state lose their velocity history (it would be of another step).
  std::vector<std::uint8_t> seen(sampling_.size(), 0);
  for (int k = 0; k < boulders.index_size(); ++k) seen[boulders.index(k)] = 1;
  for (std::size_t i = 0; i < sampling_.size(); ++i) has_last_[i] = has_last_[i] && seen[i];

  // A candidate goes when a fluid particle lies within the reach: each candidate asks the fluid's grid on its
  // own (parallel, and the answer is the same whatever the order).
  near_.assign(candidate_position_.size(), 0);
  if (!candidate_position_.empty()) {
    fluid_grid_.build_points(fluid, support_);
    const double reach = support_ + margin;
    const double reach2 = reach * reach;
    const auto count = static_cast<std::int64_t>(candidate_position_.size());
#pragma omp parallel for schedule(static) if (count > 4096)
    for (std::int64_t signed_c = 0; signed_c < count; ++signed_c) {
      const auto c = static_cast<std::size_t>(signed_c);
      const Vec3& x = candidate_position_[c];
      const Aabb box{x.array() - reach, x.array() + reach};
      near_[c] =
          fluid_grid_.any_in(box, [&](std::uint32_t f) { return (fluid[f] - x).squaredNorm() <= reach2; }) ? 1 : 0;
    }
  }
  selected_.resize(0);
  selected_.free_slip.clear();
  pending_ = Sent{};
  for (std::size_t c = 0; c < candidate_position_.size(); ++c) {
    if (!near_[c]) continue;
    const Motion& m = motion[candidate_owner_[c]];
    const auto& sampling = *sampling_[m.table];
    const std::uint32_t p = candidate_point_[c];
    const Vec3& r = sampling.offset[p];
    selected_.position.push_back(candidate_position_[c]);
    selected_.velocity.push_back(m.velocity + m.spin.cross(r));
    selected_.normal.push_back(sampling.normal[p]);
    selected_.acceleration.push_back(m.acceleration + m.angular_acceleration.cross(r) + m.spin.cross(m.spin.cross(r)));
    selected_.volume.push_back(sampling.volume[p]);
    pending_.owner.push_back(m.table);
    pending_.lever.push_back(r);
  }
  max_sent_ = std::max(max_sent_, selected_.size());
  dt_previous_ = dt_previous;
}

Vec3 SphDemBoundaryPair::minimum_image(Vec3 d) const {
  for (const auto& [axis, span] : periodic_) {
    const double period = span[1] - span[0];
    d[axis] -= period * std::round(d[axis] / period);
  }
  return d;
}

void SphDemBoundaryPair::check_fluid_moved_within_margin(const sabo::v1::StepState& fluid, std::uint64_t step) {
  // fluid_position_: the fluid at x_n; kept_: at the exchange before. A particle there moved less than the
  // margin; one that was not there must be beyond the support of every boulder particle.
  for (std::size_t k = 0; k < kept_index_.size(); ++k) kept_slot_of_id_[kept_index_[k]] = static_cast<std::int64_t>(k);
  std::string problem;
  const double new_reach = max_reach_ + support_;
  for (std::size_t f = 0; f < fluid_position_.size() && problem.empty(); ++f) {
    const std::uint32_t id = fluid.index(static_cast<int>(f));
    const Vec3& x = fluid_position_[f];
    const std::int64_t slot = kept_slot_of_id_[id];
    if (slot >= 0) {
      const double moved = minimum_image(x - kept_position_[static_cast<std::size_t>(slot)]).norm();
      if (!(moved <= margin_)) {
        problem = fmt::format("fluid particle {} moved {:.4g} m from its state of the exchange before", id, moved);
      }
      continue;
    }
    for (const Vec3& centre : centre_cover_) {
      const double distance = minimum_image(x - centre).norm();
      if (distance <= new_reach) {
        problem = fmt::format(
            "fluid particle {}, absent from the state of the exchange before, lies {:.4g} m from a boulder's centre",
            id, distance);
        break;
      }
    }
  }
  for (const std::uint32_t id : kept_index_) kept_slot_of_id_[id] = -1;
  if (!problem.empty()) {
    throw ProtocolError(fmt::format(
        "state of step {}: {}, while the boulders' boundary particles of this step were placed, ahead of this "
        "state, within {:.4g} m of the fluid's earlier positions (the support {:.4g} m plus a margin of {:.4g} m, "
        "many times the distance a stable SPH step moves a particle): the sph_solver's step is unstable, or it "
        "moved the particle by other than its velocity",
        step, problem, support_ + margin_, support_, margin_));
  }
}

void SphDemBoundaryPair::scatter(const Solvers& solvers, double dt, Replies& replies) {
  replies.boundary().append(slot_, selected_);
  const double dt_avg = 0.5 * (dt_previous_ + dt);  // dt_n / 2 at step 0, where dt_{n-1} = 0
  pending_.dt_avg = dt_avg;
  sent_[1] = std::move(sent_[0]);
  sent_[0] = std::move(pending_);
  pending_ = Sent{};
  if (touched_.empty()) return;

  // The impulse the fluid gave over its step, delivered over the boulder's.
  const double scale = force_dt_avg_ / dt_avg;
  const SolverView& dem = solvers.at(Role::dem);
  const sabo::v1::StepState& boulders = *dem.state;
  const auto n = static_cast<std::size_t>(boulders.index_size());
  std::vector<std::int64_t> slot_of(sampling_.size(), -1);
  for (std::size_t k = 0; k < n; ++k) slot_of[boulders.index(static_cast<int>(k))] = static_cast<std::int64_t>(k);
  reply_force_.assign(3 * n, 0.0);
  reply_torque_.assign(3 * n, 0.0);
  for (const std::uint32_t o : touched_) {
    if (slot_of[o] < 0) {
      throw ProtocolError(fmt::format(
          "the dem_solver's state of step {} leaves out sphere {}, which the fluid pushed at an earlier step: the "
          "coupler asks for every sphere (interest_all)",
          boulders.step(), o));
    }
    const auto k = static_cast<std::size_t>(slot_of[o]);
    for (int c = 0; c < 3; ++c) {
      reply_force_[3 * k + static_cast<std::size_t>(c)] = scale * force_[o][c];
      reply_torque_[3 * k + static_cast<std::size_t>(c)] = scale * torque_[o][c];
    }
  }
  const bool torque = dem.registration->exposes_angular_velocity();
  replies.add_particle_forces(Role::dem, reply_force_,
                              torque ? std::span<const double>(reply_torque_) : std::span<const double>());
}

InterestRequest SphDemBoundaryPair::interest(Role role) const {
  if (role == Role::dem) return {.all = true, .boxes = {}};
  // The fluid within the support of a boulder's particles at the next step: a support of the boulders'
  // and the fluid's motion over one step on top.
  std::vector<Aabb> boxes = geometry::covering_boxes(centre_cover_, geometry::kMaxInterestBoxes);
  for (Aabb& box : boxes) box = box.inflated(max_radius_ + 2 * support_);
  return {.all = false, .boxes = std::move(boxes)};
}

nlohmann::json SphDemBoundaryPair::effect() const {
  std::size_t boulders = 0, particles = 0;
  for (const auto* sampling : sampling_) {
    if (sampling == nullptr) continue;
    ++boulders;
    particles += sampling->size();
  }
  return {{"effect", "sph_dem_boundary_particles"}, {"process", "coupler"},           {"boulders", boulders},
          {"boundary_particles", particles},        {"max_sent_per_step", max_sent_}, {"layers", layers_}};
}

void SphDemBoundaryPair::save_history(io::hdf5::Group& group) const {
  group.set_attribute("pair", std::string("sph_dem_boundary_particles"));
  group.set_attribute("dt_previous", dt_previous_);
  group.set_attribute("max_sent_per_step", static_cast<std::int64_t>(max_sent_));
  for (std::size_t s = 0; s < sent_.size(); ++s) {
    auto sent = group.create_group(fmt::format("sent_{}", s + 1));
    sent.set_attribute("dt_avg", sent_[s].dt_avg);
    std::vector<double> lever;
    for (const Vec3& r : sent_[s].lever) lever.insert(lever.end(), {r.x(), r.y(), r.z()});
    write_array(sent, "owner", sent_[s].owner);
    write_array(sent, "lever", lever);
  }
  std::vector<double> velocity, spin;
  for (std::size_t i = 0; i < last_velocity_.size(); ++i) {
    velocity.insert(velocity.end(), {last_velocity_[i].x(), last_velocity_[i].y(), last_velocity_[i].z()});
    spin.insert(spin.end(), {last_spin_[i].x(), last_spin_[i].y(), last_spin_[i].z()});
  }
  write_array(group, "last_velocity", velocity);
  write_array(group, "last_spin", spin);
  write_array(group, "has_last", has_last_);
  // The fluid the next step's particles are placed from (none before the first step).
  if (kept_) {
    std::vector<double> position;
    for (const Vec3& x : kept_position_) position.insert(position.end(), {x.x(), x.y(), x.z()});
    write_array(group, "kept_fluid_index", kept_index_);
    write_array(group, "kept_fluid_position", position);
  }
}

void SphDemBoundaryPair::restore_history(const io::hdf5::Group& group) {
  if (group.string_attribute("pair") != "sph_dem_boundary_particles") {
    throw FileError(fmt::format("{}: holds the history of the {} pair, not of the boulders' boundary particles",
                                group.path(), group.string_attribute("pair")));
  }
  const std::size_t n = sampling_.size();
  const auto velocity = read_array<double>(group, "last_velocity");
  const auto spin = read_array<double>(group, "last_spin");
  const auto has_last = read_array<std::uint8_t>(group, "has_last");
  if (velocity.size() != 3 * n || spin.size() != 3 * n || has_last.size() != n) {
    throw FileError(
        fmt::format("{}: velocities of {} spheres, the dem_solver has {}", group.path(), has_last.size(), n));
  }
  for (std::size_t s = 0; s < sent_.size(); ++s) {
    const auto sent = group.group(fmt::format("sent_{}", s + 1));
    Sent record;
    record.dt_avg = sent.double_attribute("dt_avg");
    record.owner = read_array<std::uint32_t>(sent, "owner");
    const auto lever = read_array<double>(sent, "lever");
    if (lever.size() != 3 * record.owner.size() ||
        std::any_of(record.owner.begin(), record.owner.end(), [&](std::uint32_t o) { return o >= n; })) {
      throw FileError(fmt::format("{}: the particles sent do not fit the {} spheres", sent.path(), n));
    }
    for (std::size_t k = 0; k < record.owner.size(); ++k) {
      record.lever.emplace_back(lever[3 * k], lever[3 * k + 1], lever[3 * k + 2]);
    }
    sent_[s] = std::move(record);
  }
  for (std::size_t i = 0; i < n; ++i) {
    last_velocity_[i] = Vec3(velocity[3 * i], velocity[3 * i + 1], velocity[3 * i + 2]);
    last_spin_[i] = Vec3(spin[3 * i], spin[3 * i + 1], spin[3 * i + 2]);
    has_last_[i] = has_last[i];
  }
  // A checkpoint of an older Sabo keeps no fluid: the next step places from the fluid's state, as a first step.
  kept_ = group.exists("kept_fluid_index");
  kept_index_.clear();
  kept_position_.clear();
  if (kept_) {
    kept_index_ = read_array<std::uint32_t>(group, "kept_fluid_index");
    const auto position = read_array<double>(group, "kept_fluid_position");
    if (position.size() != 3 * kept_index_.size()) {
      throw FileError(fmt::format("{}: {} positions for the {} fluid particles kept", group.path(), position.size(),
                                  kept_index_.size()));
    }
    for (const std::uint32_t id : kept_index_) {
      if (id >= kept_slot_of_id_.size()) {
        throw FileError(fmt::format("{}: a kept fluid particle has index {}, the sph_solver has {} particles",
                                    group.path(), id, kept_slot_of_id_.size()));
      }
    }
    for (std::size_t k = 0; k < kept_index_.size(); ++k) {
      kept_position_.emplace_back(position[3 * k], position[3 * k + 1], position[3 * k + 2]);
    }
  }
  dt_previous_ = group.double_attribute("dt_previous");
  max_sent_ = static_cast<std::size_t>(group.int_attribute("max_sent_per_step"));
}

}  // namespace sabo::coupler
