#include "coupler/contact/boundary_walls.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/covering_boxes.hpp"

namespace sabo::coupler {

BoundaryWalls::BoundaryWalls(double spacing, double support, std::vector<PeriodicSpan> periodic,
                             std::vector<std::string> free_slip_parts)
    : spacing_(spacing),
      support_(support),
      layers_(static_cast<std::size_t>(std::max(1.0, std::ceil(support / spacing - 1e-9)))),
      periodic_(std::move(periodic)),
      free_slip_parts_(std::move(free_slip_parts)) {}

void BoundaryWalls::set_surface(const geometry::SurfaceMesh& surface) {
  surface_ = surface;
  sampling_ = geometry::sample_surface(surface_, spacing_, layers_);
  if (!periodic_.empty()) {
    std::vector<char> keep(sampling_.size(), 1);
    for (std::size_t k = 0; k < sampling_.size(); ++k) {
      const Vec3 x = geometry::boundary_particle_position(surface_, sampling_, k);
      for (const PeriodicSpan& span : periodic_) {
        if (x[span.axis] < span.min || x[span.axis] >= span.max) keep[k] = 0;
      }
    }
    geometry::keep_particles(sampling_, keep);
  }
  free_slip_.clear();
  if (!free_slip_parts_.empty()) {
    std::vector<std::uint8_t> part_slips(surface_.part_name.size(), 0);
    for (std::size_t part = 0; part < part_slips.size(); ++part) {
      const auto& name = surface_.part_name[part];
      part_slips[part] = std::find(free_slip_parts_.begin(), free_slip_parts_.end(), name) != free_slip_parts_.end();
    }
    free_slip_.resize(sampling_.size());
    for (std::size_t k = 0; k < sampling_.size(); ++k)
      free_slip_[k] = part_slips[surface_.face_part[sampling_.face[k]]];
  }
  node_velocity_.assign(surface_.node_count(), Vec3::Zero());
  previous_node_velocity_ = node_velocity_;
  node_acceleration_ = node_velocity_;
  selection_.clear();
  previous_selection_.clear();
  selected_.resize(0);
  place_all();
}

void BoundaryWalls::place_all() {
  all_position_.resize(sampling_.size());
  for (std::size_t k = 0; k < sampling_.size(); ++k) {
    all_position_[k] = geometry::boundary_particle_position(surface_, sampling_, k);
  }
  grid_valid_ = false;
  cover_.reset();
}

void BoundaryWalls::update_nodes(std::span<const double> position, std::span<const double> velocity,
                                 double dt_previous) {
  const std::size_t n = surface_.node_count();
  if (position.size() != 3 * n || (!velocity.empty() && velocity.size() != 3 * n)) {
    throw ProtocolError(fmt::format("boundary walls: {} node positions and {} velocities for {} nodes", position.size(),
                                    velocity.size(), n));
  }
  previous_node_velocity_ = node_velocity_;
  for (std::size_t i = 0; i < n; ++i) {
    surface_.node_position[i] = Vec3(position[3 * i], position[3 * i + 1], position[3 * i + 2]);
    node_velocity_[i] =
        velocity.empty() ? Vec3::Zero() : Vec3(velocity[3 * i], velocity[3 * i + 1], velocity[3 * i + 2]);
    node_acceleration_[i] =
        dt_previous > 0 ? Vec3((node_velocity_[i] - previous_node_velocity_[i]) / dt_previous) : Vec3::Zero();
  }
  place_all();
}

void BoundaryWalls::spread(std::span<const double> boundary_force, std::size_t steps_back,
                           std::vector<double>& node_force, std::vector<Vec3>& part_force,
                           std::vector<PointLoad>* point_loads) const {
  const auto& sent = selection(steps_back);
  node_force.assign(3 * surface_.node_count(), 0.0);
  part_force.assign(surface_.part_name.size(), Vec3::Zero());
  if (point_loads != nullptr) point_loads->clear();
  if (boundary_force.empty()) return;
  if (boundary_force.size() != 3 * sent.size()) {
    throw ProtocolError(
        fmt::format("{} boundary_force values for the {} boundary particles sent {} step(s) before "
                    "(expected 3 each)",
                    boundary_force.size(), sent.size(), steps_back));
  }
  geometry::spread_boundary_forces(surface_, sampling_, sent, boundary_force, node_force);
  const auto add = [&](std::uint32_t face, const std::array<double, 3>& weight, const Vec3& share) {
    part_force[surface_.face_part[face]] += share;
    if (point_loads == nullptr) return;
    const auto& t = surface_.triangle[face];
    const Vec3 point = weight[0] * surface_.node_position[t[0]] + weight[1] * surface_.node_position[t[1]] +
                       weight[2] * surface_.node_position[t[2]];
    point_loads->push_back(PointLoad{surface_.face_part[face], point, share});
  };
  for (std::size_t s = 0; s < sent.size(); ++s) {
    const std::uint32_t k = sent[s];
    const auto shares = geometry::split_boundary_force(
        surface_, sampling_, k, Vec3(boundary_force[3 * s], boundary_force[3 * s + 1], boundary_force[3 * s + 2]));
    add(sampling_.face[k], sampling_.weight[k], shares[0]);
    if (sampling_.partner_face[k] != geometry::kNoFace) {
      add(sampling_.partner_face[k], sampling_.partner_weight[k], shares[1]);
    }
  }
}

void BoundaryWalls::select_near(std::span<const double> fluid_position) {
  // Visit the wall particles around each fluid particle (the wall grid is
  // rebuilt only when the nodes move): the cost follows the fluid near the
  // walls, not the whole sampled surface.
  if (!grid_valid_) {
    grid_.build_points(all_position_, support_);
    grid_valid_ = true;
  }
  const std::size_t n = fluid_position.size() / 3;
  near_.assign(all_position_.size(), 0);
  const double reach2 = support_ * support_;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 x(fluid_position[3 * i], fluid_position[3 * i + 1], fluid_position[3 * i + 2]);
    if (!x.allFinite()) continue;
    grid_.for_each_near(x, [&](std::uint32_t k) {
      if (!near_[k] && (all_position_[k] - x).squaredNorm() <= reach2) near_[k] = 1;
    });
  }
  previous_selection_.swap(selection_);
  selection_.clear();
  for (std::size_t k = 0; k < near_.size(); ++k) {
    if (near_[k]) selection_.push_back(static_cast<std::uint32_t>(k));
  }
  place_selected();
}

void BoundaryWalls::place_selected() {
  geometry::place_boundary_particles(surface_, sampling_, node_velocity_, node_acceleration_, selection_, selected_);
  selected_.free_slip.clear();
  if (free_slip_.empty()) return;
  selected_.free_slip.reserve(selection_.size());
  for (const std::uint32_t k : selection_) selected_.free_slip.push_back(free_slip_[k]);
}

void BoundaryWalls::restore(History history) {
  const auto fits = [&](const std::vector<std::uint32_t>& selection) {
    return std::all_of(selection.begin(), selection.end(), [&](std::uint32_t k) { return k < sampling_.size(); });
  };
  if (!fits(history.selection) || !fits(history.previous_selection) ||
      history.node_velocity.size() != surface_.node_count()) {
    throw ProtocolError(fmt::format(
        "boundary walls history: selections beyond the {} sampled particles or {} node velocities for {} nodes",
        sampling_.size(), history.node_velocity.size(), surface_.node_count()));
  }
  selection_ = std::move(history.selection);
  previous_selection_ = std::move(history.previous_selection);
  node_velocity_ = std::move(history.node_velocity);
  place_selected();
}

std::vector<Aabb> BoundaryWalls::interest_regions() const {
  if (!cover_) cover_ = geometry::covering_boxes(all_position_, geometry::kMaxInterestBoxes);
  std::vector<Aabb> boxes = *cover_;
  for (Aabb& box : boxes) box = box.inflated(2 * support_);
  return boxes;
}

}  // namespace sabo::coupler
