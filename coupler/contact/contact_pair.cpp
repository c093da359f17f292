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

}  // namespace sabo::coupler
