#include "fem_solver/structure_contact.hpp"

#include <algorithm>
#include <cassert>
#include <limits>

namespace sabo::fem {

namespace {

std::vector<std::string> structure_names(const scene::Scene& scene) {
  std::vector<std::string> names;
  for (const auto& structure : scene.structures) names.push_back(structure.name);
  return names;
}

}  // namespace

bool StructureContact::any_pair(const scene::Scene& scene) {
  for (const auto& a : scene.structures) {
    for (const auto& b : scene.structures) {
      if (scene.fem_fem_contact(a.name, b.name).enabled) return true;
    }
  }
  return false;
}

StructureContact::StructureContact(const scene::Scene& scene) {
  // Keep only what the pair lookup needs, so that the scene need not outlive this object.
  scene::Scene pairs_only;
  pairs_only.structures = scene.structures;
  pairs_only.fem_fem_default = scene.fem_fem_default;
  pairs_only.fem_fem_interactions = scene.fem_fem_interactions;
  const std::vector<std::string> names = structure_names(scene);
  source_.assign(names.size(), 0);
  for (std::size_t a = 0; a < names.size(); ++a) {
    for (std::size_t b = 0; b < names.size(); ++b) {
      if (pairs_only.fem_fem_contact(names[a], names[b]).enabled) source_[a] = 1;
    }
  }
  contact::SurfaceContactOptions options;
  options.damping_mass = contact::SurfaceContactOptions::DampingMass::reduced;
  kernel_ = std::make_unique<contact::SurfaceContact>(
      names,
      [pairs_only = std::move(pairs_only)](const std::string& source, const std::string& part) {
        return pairs_only.fem_fem_contact(source, part);
      },
      options);
}

void StructureContact::set_surface(const geometry::SurfaceMesh& surface) {
  kernel_->set_surface(surface);
  const std::size_t nodes = surface.node_count();
  constexpr auto kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> part(nodes, kNone);
  std::vector<double> thickness(nodes, 0.0), shortest(nodes, std::numeric_limits<double>::infinity());
  for (std::size_t f = 0; f < surface.face_count(); ++f) {
    const auto& t = surface.triangle[f];
    double edge = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < 3; ++k) {
      edge = std::min(edge, (surface.node_position[t[k]] - surface.node_position[t[(k + 1) % 3]]).norm());
    }
    for (std::uint32_t n : t) {
      assert(part[n] == kNone || part[n] == surface.face_part[f]);  // parts share no nodes
      part[n] = surface.face_part[f];
      thickness[n] = std::max(thickness[n], surface.face_thickness[f]);
      shortest[n] = std::min(shortest[n], edge);
    }
  }
  node_.clear();
  id_.clear();
  radius_.clear();
  depth_.clear();
  mass_.clear();
  part_.clear();
  for (std::size_t i = 0; i < nodes; ++i) {
    if (part[i] == kNone || source_[part[i]] == 0) continue;
    const double radius = 0.5 * thickness[i];
    // A node whose faces are all degenerate has no length scale: it meets faces within its radius only.
    const double depth = std::isfinite(shortest[i]) && shortest[i] > 0 ? std::max(radius, 0.5 * shortest[i]) : radius;
    if (!(depth > 0)) continue;
    node_.push_back(static_cast<std::uint32_t>(i));
    id_.push_back(surface.node_id[i]);
    radius_.push_back(radius);
    depth_.push_back(depth);
    mass_.push_back(surface.mass_of(i));
    part_.push_back(part[i]);
  }
  point_position_.assign(3 * node_.size(), 0.0);
  point_velocity_.assign(3 * node_.size(), 0.0);
  node_position_.assign(3 * nodes, 0.0);
  node_velocity_.assign(3 * nodes, 0.0);
  node_force_.assign(nodes, Vec3::Zero());
}

void StructureContact::compute(std::span<const Vec3> position, std::span<const Vec3> velocity, double dt_previous) {
  assert(position.size() == node_force_.size() && velocity.size() == node_force_.size());
  for (std::size_t i = 0; i < position.size(); ++i) {
    for (int d = 0; d < 3; ++d) {
      node_position_[3 * i + static_cast<std::size_t>(d)] = position[i](d);
      node_velocity_[3 * i + static_cast<std::size_t>(d)] = velocity[i](d);
    }
  }
  kernel_->update_nodes(node_position_, node_velocity_);
  for (std::size_t k = 0; k < node_.size(); ++k) {
    for (std::size_t d = 0; d < 3; ++d) {
      point_position_[3 * k + d] = node_position_[3 * node_[k] + d];
      point_velocity_[3 * k + d] = node_velocity_[3 * node_[k] + d];
    }
  }
  const contact::ParticleView points{.id = id_,
                                     .position = point_position_,
                                     .velocity = point_velocity_,
                                     .angular_velocity = {},
                                     .radius = radius_,
                                     .mass = mass_,
                                     .body = part_,
                                     .depth = depth_};
  kernel_->compute(points, dt_previous, out_);
  for (std::size_t i = 0; i < node_force_.size(); ++i) {
    node_force_[i] = Vec3(out_.node_force[3 * i], out_.node_force[3 * i + 1], out_.node_force[3 * i + 2]);
  }
  for (std::size_t k = 0; k < node_.size(); ++k) {
    node_force_[node_[k]] +=
        Vec3(out_.particle_force[3 * k], out_.particle_force[3 * k + 1], out_.particle_force[3 * k + 2]);
  }
}

}  // namespace sabo::fem
