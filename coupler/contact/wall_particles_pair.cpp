#include "coupler/contact/wall_particles_pair.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "coupler/contact/history_io.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/protocol/surface_codec.hpp"

namespace sabo::coupler {

namespace {

std::span<const double> span_of(const google::protobuf::RepeatedField<double>& field) {
  return {field.data(), static_cast<std::size_t>(field.size())};
}

// Which earlier StepForces the boundary forces of this state answer (1: the last, 2: the one before).
std::size_t steps_back(const sabo::v1::StepState& state) {
  return state.has_boundary_step() ? state.step() - state.boundary_step() : 1;
}

}  // namespace

namespace {

std::vector<BoundaryWalls::PeriodicSpan> periodic_spans(const scene::SphSettings& sph) {
  std::vector<BoundaryWalls::PeriodicSpan> spans;
  if (sph.periodic_x) spans.push_back({0, (*sph.periodic_x)[0], (*sph.periodic_x)[1]});
  if (sph.periodic_y) spans.push_back({1, (*sph.periodic_y)[0], (*sph.periodic_y)[1]});
  return spans;
}

}  // namespace

WallParticlesPair::WallParticlesPair(const scene::Scene& scene)
    : walls_(scene.sph.wall_spacing(), scene.sph.kernel_support(), periodic_spans(scene.sph),
             scene.sph.free_slip_walls) {
  std::vector<std::string> deformable;
  for (const auto& structure : scene.structures) {
    if (!structure.rigid) deformable.push_back(structure.name);
  }
  if (!deformable.empty()) {
    holding_ = {.allowed = false,
                .why_not = fmt::format("its boundary particles sit on the deformable structure{} '{}': their "
                                       "acceleration enters the fluid's pressure on them, and held over several steps "
                                       "that force feeds the structure's vibration",
                                       deformable.size() > 1 ? "s" : "", fmt::join(deformable, "', '"))};
  }
}

void WallParticlesPair::start(const Solvers& solvers, Replies& replies) {
  walls_.set_surface(protocol::surface_from_message(solvers.at(Role::fem).registration->surface(), "fem_solver"));
  channel_ = &replies.boundary();
  slot_ = replies.boundary().join();
  spdlog::info("sampled the FEM surface into {} boundary particles ({} layers {} m apart)", walls_.sampling().size(),
               walls_.layers(), walls_.spacing());
}

void WallParticlesPair::check_state(const SolverView& solver) const {
  if (solver.role == Role::fem && solver.state->has_topology()) {
    throw ProtocolError(
        "a new surface topology (eroded elements) while the fluid's walls are boundary particles sampled "
        "at registration: not supported in this version (use [sph] wall_model = \"penalty\")");
  }
}

void WallParticlesPair::compute(const Solvers& solvers, const StepClock& clock) {
  const sabo::v1::StepState& surface = *solvers.at(Role::fem).state;
  if (surface.node_position_size() > 0) {
    walls_.update_nodes(span_of(surface.node_position()), span_of(surface.node_velocity()), clock.dt_previous);
  }
  const sabo::v1::StepState& fluid = *solvers.at(Role::sph).state;
  const std::size_t back = steps_back(fluid);
  returned_ = channel_->slice(slot_, span_of(fluid.boundary_force()), back);
  walls_.spread(returned_, back, node_force_, part_force_, want_point_loads_ ? &point_loads_ : nullptr);
  walls_.select_near(span_of(fluid.position()));
  max_sent_ = std::max(max_sent_, walls_.selection().size());
}

void WallParticlesPair::scatter(const Solvers& /*solvers*/, double /*dt*/, Replies& replies) {
  replies.boundary().append(slot_, walls_.selected());
  if (!returned_.empty()) replies.add_node_forces(node_force_);
}

InterestRequest WallParticlesPair::interest(Role role) const {
  if (role == Role::fem) return {.all = true, .boxes = {}};
  return {.all = false, .boxes = walls_.interest_regions()};
}

NewtonBalance WallParticlesPair::newton_balance() const {
  // The fluid feels minus the force it put on the boundary particles.
  NewtonBalance balance;
  for (std::size_t i = 0; i + 2 < returned_.size(); i += 3) {
    balance.sum -= Vec3(returned_[i], returned_[i + 1], returned_[i + 2]);
    balance.scale += std::abs(returned_[i]) + std::abs(returned_[i + 1]) + std::abs(returned_[i + 2]);
  }
  if (returned_.empty()) return balance;
  for (std::size_t i = 0; i + 2 < node_force_.size(); i += 3) {
    balance.sum += Vec3(node_force_[i], node_force_[i + 1], node_force_[i + 2]);
  }
  return balance;
}

nlohmann::json WallParticlesPair::effect() const {
  return {{"effect", "sph_fem_boundary_particles"},
          {"process", "coupler"},
          {"boundary_particles", walls_.sampling().size()},
          {"max_sent_per_step", max_sent_},
          {"layers", walls_.layers()}};
}

void WallParticlesPair::save_history(io::hdf5::Group& group) const {
  const BoundaryWalls::History history = walls_.history();
  std::vector<double> velocity;
  for (const Vec3& v : history.node_velocity) velocity.insert(velocity.end(), {v.x(), v.y(), v.z()});
  group.set_attribute("pair", std::string("sph_fem_boundary_particles"));
  group.set_attribute("max_sent_per_step", static_cast<std::int64_t>(max_sent_));
  write_array(group, "selection", history.selection);
  write_array(group, "previous_selection", history.previous_selection);
  write_array(group, "node_velocity", velocity);
}

void WallParticlesPair::restore_history(const io::hdf5::Group& group) {
  if (group.string_attribute("pair") != "sph_fem_boundary_particles") {
    throw FileError(fmt::format("{}: holds the history of the {} pair, not of the boundary-particle walls",
                                group.path(), group.string_attribute("pair")));
  }
  BoundaryWalls::History history;
  history.selection = read_array<std::uint32_t>(group, "selection");
  history.previous_selection = read_array<std::uint32_t>(group, "previous_selection");
  const auto velocity = read_array<double>(group, "node_velocity");
  for (std::size_t i = 0; i + 2 < velocity.size(); i += 3) {
    history.node_velocity.emplace_back(velocity[i], velocity[i + 1], velocity[i + 2]);
  }
  try {
    walls_.restore(std::move(history));
  } catch (const ProtocolError& error) {
    throw FileError(fmt::format("{}: {}", group.path(), error.what()));
  }
  max_sent_ = static_cast<std::size_t>(group.int_attribute("max_sent_per_step"));
}

}  // namespace sabo::coupler
