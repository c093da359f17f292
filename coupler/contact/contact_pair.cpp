#include "coupler/contact/contact_pair.hpp"

#include <fmt/format.h>

#include <cassert>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"

namespace sabo::coupler {

const SolverView& Solvers::at(Role role) const {
  const SolverView* view = find(role);
  assert(view != nullptr && "a pair asked for a role the factory did not check");
  return *view;
}

void BoundaryChannel::begin_step() {
  layout_[2] = std::move(layout_[1]);
  layout_[1] = std::move(layout_[0]);
  layout_[0] = Layout{};
  layout_[0].offset.assign(slots_, 0);
  layout_[0].count.assign(slots_, 0);
  parts_.clear();
  begun_ = true;
}

void BoundaryChannel::append(std::size_t slot, const physics::BoundaryParticles& particles) {
  assert(begun_ && slot < slots_);
  Layout& now = layout_[0];
  assert(now.count[slot] == 0 && "one part per slot and step");
  now.offset[slot] = now.total;
  now.count[slot] = particles.size();
  now.total += particles.size();
  parts_.push_back(&particles);
}

const BoundaryChannel::Layout& BoundaryChannel::layout(std::size_t steps_back) const {
  assert(steps_back == 1 || steps_back == 2);
  // Between the end of a step's scatter and the next begin_step(), layout_[0] is the list just sent.
  return layout_[steps_back - 1];
}

std::size_t BoundaryChannel::sent(std::size_t steps_back) const {
  return layout(steps_back).total;
}

std::span<const double> BoundaryChannel::slice(std::size_t slot, std::span<const double> returned,
                                               std::size_t steps_back) const {
  const Layout& sent_then = layout(steps_back);
  if (returned.empty() || slot >= sent_then.count.size()) return {};
  assert(returned.size() == 3 * sent_then.total);
  return returned.subspan(3 * sent_then.offset[slot], 3 * sent_then.count[slot]);
}

void BoundaryChannel::save(io::hdf5::Group& group) const {
  group.set_attribute("slots", static_cast<std::int64_t>(slots_));
  for (std::size_t k = 0; k < layout_.size(); ++k) {
    io::hdf5::Group list = group.create_group(fmt::format("list_{}", k));
    list.set_attribute("total", static_cast<std::int64_t>(layout_[k].total));
    io::write_array<std::uint64_t>(list, "offset", layout_[k].offset);
    io::write_array<std::uint64_t>(list, "count", layout_[k].count);
  }
}

void BoundaryChannel::restore(const io::hdf5::Group& group) {
  const auto slots = static_cast<std::size_t>(group.int_attribute("slots"));
  if (slots != slots_) {
    throw FileError(
        fmt::format("{}: {} pairs sent boundary particles when the checkpoint was written, {} do now. "
                    "Fix: resume with the scene the run was started with, unchanged",
                    group.path(), slots, slots_));
  }
  for (std::size_t k = 0; k < layout_.size(); ++k) {
    const io::hdf5::Group list = group.group(fmt::format("list_{}", k));
    Layout layout;
    layout.total = static_cast<std::size_t>(list.int_attribute("total"));
    layout.offset = io::read_array<std::uint64_t>(list, "offset");
    layout.count = io::read_array<std::uint64_t>(list, "count");
    layout_[k] = std::move(layout);
  }
  parts_.clear();
  begun_ = false;
}

void Replies::begin_step(const Solvers& solvers, std::size_t surface_nodes) {
  for (const Role role : kRoles) {
    ParticleReply& reply = particles_[static_cast<std::size_t>(role)];
    const SolverView* solver = solvers.find(role);
    const std::size_t n = solver != nullptr ? 3 * static_cast<std::size_t>(solver->state->index_size()) : 0;
    reply.force.assign(n, 0.0);
    reply.torque.clear();
    reply.force_written = reply.torque_written = false;
    reply.extra = {};
  }
  node_force_.assign(3 * surface_nodes, 0.0);
  node_force_written_ = false;
  boundary_.begin_step();
}

void Replies::add_particle_forces(Role role, std::span<const double> force, std::span<const double> torque) {
  ParticleReply& reply = particles_[static_cast<std::size_t>(role)];
  assert(force.size() == reply.force.size());
  // The first pair's forces are copied, so that a single pair's forces go out with their own bits
  // (0 + -0 would be +0).
  if (!reply.force_written) {
    std::copy(force.begin(), force.end(), reply.force.begin());
  } else {
    for (std::size_t k = 0; k < force.size(); ++k) reply.force[k] += force[k];
  }
  reply.force_written = true;
  if (torque.empty()) return;
  assert(torque.size() == reply.force.size());
  if (!reply.torque_written) {
    reply.torque.assign(torque.begin(), torque.end());
  } else {
    for (std::size_t k = 0; k < torque.size(); ++k) reply.torque[k] += torque[k];
  }
  reply.torque_written = true;
}

void Replies::add_node_forces(std::span<const double> node_force) {
  assert(node_force.size() == node_force_.size());
  for (std::size_t k = 0; k < node_force.size(); ++k) node_force_[k] += node_force[k];
  node_force_written_ = true;
}

void SurfaceNodes::assign(const google::protobuf::RepeatedField<std::uint64_t>& ids) {
  id.assign(ids.begin(), ids.end());
  row.clear();
  row.reserve(id.size());
  for (std::size_t k = 0; k < id.size(); ++k) row.emplace(id[k], k);
}

void Replies::add(const Replies& other) {
  for (const Role role : kRoles) {
    const ParticleReply& from = other.of(role);
    if (!from.force_written) continue;
    add_particle_forces(role, from.force,
                        from.torque_written ? std::span<const double>(from.torque) : std::span<const double>());
  }
  if (other.node_force_written_) add_node_forces(other.node_force_);
}

HeldForces Replies::held(const Solvers& solvers, Role role, bool surface, const SurfaceNodes& nodes) const {
  HeldForces out{.role = role, .surface = surface, .index = {}, .node_id = {}, .force = {}, .torque = {}};
  const auto nonzero = [](const std::vector<double>& values, std::size_t k) {
    return !values.empty() && (values[3 * k] != 0.0 || values[3 * k + 1] != 0.0 || values[3 * k + 2] != 0.0);
  };
  const auto push = [](std::vector<double>& into, const std::vector<double>& values, std::size_t k) {
    if (values.empty()) {
      into.insert(into.end(), {0.0, 0.0, 0.0});
    } else {
      into.insert(into.end(), values.begin() + static_cast<std::ptrdiff_t>(3 * k),
                  values.begin() + static_cast<std::ptrdiff_t>(3 * k + 3));
    }
  };
  if (surface) {
    if (!node_force_written_) return out;
    assert(node_force_.size() == 3 * nodes.id.size());
    for (std::size_t k = 0; k < nodes.id.size(); ++k) {
      if (!nonzero(node_force_, k)) continue;
      out.node_id.push_back(nodes.id[k]);
      push(out.force, node_force_, k);
    }
    return out;
  }
  const ParticleReply& reply = of(role);
  if (!reply.force_written) return out;
  const auto& index = solvers.at(role).state->index();
  for (std::size_t k = 0; k < static_cast<std::size_t>(index.size()); ++k) {
    if (!nonzero(reply.force, k) && !nonzero(reply.torque, k)) continue;
    out.index.push_back(index[static_cast<int>(k)]);
    push(out.force, reply.force, k);
    if (reply.torque_written) push(out.torque, reply.torque, k);
  }
  return out;
}

std::size_t Replies::add_held(const Solvers& solvers, const HeldForces& held, const SurfaceNodes& nodes) {
  std::size_t lost = 0;
  if (held.surface) {
    if (held.node_id.empty()) return 0;
    for (std::size_t k = 0; k < held.node_id.size(); ++k) {
      const auto it = nodes.row.find(held.node_id[k]);
      if (it == nodes.row.end()) {
        ++lost;
        continue;
      }
      for (int c = 0; c < 3; ++c) node_force_[3 * it->second + c] += held.force[3 * k + c];
    }
    node_force_written_ = true;
    return lost;
  }
  if (held.index.empty()) return 0;
  ParticleReply& reply = particles_[static_cast<std::size_t>(held.role)];
  const auto& index = solvers.at(held.role).state->index();
  std::uint32_t largest = 0;
  for (const std::uint32_t i : index) largest = std::max(largest, i);
  for (const std::uint32_t i : held.index) largest = std::max(largest, i);
  std::vector<std::int64_t> row(static_cast<std::size_t>(largest) + 1, -1);
  for (int k = 0; k < index.size(); ++k) row[index[k]] = k;
  const bool torque = !held.torque.empty();
  if (torque && !reply.torque_written) {
    reply.torque.assign(reply.force.size(), 0.0);
    reply.torque_written = true;
  }
  // Rows of their own for particles the state left out, one per index.
  std::unordered_map<std::uint32_t, std::size_t> extra_row;
  for (std::size_t k = 0; k < reply.extra.index.size(); ++k) extra_row.emplace(reply.extra.index[k], k);
  for (std::size_t k = 0; k < held.index.size(); ++k) {
    const std::int64_t at = row[held.index[k]];
    if (at >= 0) {
      const auto r = static_cast<std::size_t>(at);
      for (std::size_t c = 0; c < 3; ++c) {
        reply.force[3 * r + c] += held.force[3 * k + c];
        if (torque) reply.torque[3 * r + c] += held.torque[3 * k + c];
      }
      continue;
    }
    auto [it, added] = extra_row.emplace(held.index[k], reply.extra.index.size());
    if (added) {
      reply.extra.index.push_back(held.index[k]);
      reply.extra.force.insert(reply.extra.force.end(), {0.0, 0.0, 0.0});
      reply.extra.torque.insert(reply.extra.torque.end(), {0.0, 0.0, 0.0});
    }
    for (std::size_t c = 0; c < 3; ++c) {
      reply.extra.force[3 * it->second + c] += held.force[3 * k + c];
      if (torque) reply.extra.torque[3 * it->second + c] += held.torque[3 * k + c];
    }
  }
  reply.force_written = true;
  return lost;
}

}  // namespace sabo::coupler
