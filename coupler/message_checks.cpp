#include "coupler/message_checks.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace sabo::coupler {

namespace {

template <class T>
std::optional<std::size_t> first_duplicate(const google::protobuf::RepeatedField<T>& ids) {
  std::vector<std::pair<T, std::size_t>> sorted;
  sorted.reserve(static_cast<std::size_t>(ids.size()));
  for (int k = 0; k < ids.size(); ++k) sorted.emplace_back(ids[k], static_cast<std::size_t>(k));
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 1; k < sorted.size(); ++k) {
    if (sorted[k].first == sorted[k - 1].first) return std::max(sorted[k].second, sorted[k - 1].second);
  }
  return std::nullopt;
}

std::size_t bodies_of(const scene::Scene& scene, Role role) {
  switch (role) {
    case Role::sph: return scene.fluids.size();
    case Role::dem: return scene.particle_sets.size();
    case Role::fem: return scene.structures.size();
  }
  return 0;
}

}  // namespace

std::optional<std::string> particle_table_problem(const sabo::v1::ParticleTable& table, const scene::Scene& scene,
                                                  Role role) {
  const int n = table.id_size();
  if (table.radius_size() != n || table.mass_size() != n || table.body_size() != n ||
      (table.material_size() != n && table.material_size() != 0)) {
    return fmt::format(
        "the particle table's arrays differ in length ({} ids, {} radii, {} masses, {} bodies, {} "
        "materials)",
        n, table.radius_size(), table.mass_size(), table.body_size(), table.material_size());
  }
  if (const auto k = first_duplicate(table.id())) {
    return fmt::format("particle {} has the id {} of an earlier particle: ids must be unique", *k,
                       table.id(static_cast<int>(*k)));
  }
  const std::size_t bodies = bodies_of(scene, role);
  for (int k = 0; k < n; ++k) {
    if (!(std::isfinite(table.radius(k)) && table.radius(k) > 0)) {
      return fmt::format("particle {} (id {}) has radius {} m: it must be finite and > 0", k, table.id(k),
                         table.radius(k));
    }
    if (!(std::isfinite(table.mass(k)) && table.mass(k) > 0)) {
      return fmt::format("particle {} (id {}) has mass {} kg: it must be finite and > 0", k, table.id(k),
                         table.mass(k));
    }
    if (table.material_size() == n && table.material(k) >= scene.materials.size()) {
      return fmt::format("particle {} (id {}) has material {}, the scene has {} materials", k, table.id(k),
                         table.material(k), scene.materials.size());
    }
    if (table.body(k) >= bodies) {
      return fmt::format("particle {} (id {}) belongs to body {}, the scene has {} bodies of this role", k, table.id(k),
                         table.body(k), bodies);
    }
  }
  return std::nullopt;
}

std::optional<std::string> surface_problem(const sabo::v1::SurfaceTopology& s, const scene::Scene& scene) {
  const int nodes = s.node_id_size(), faces = s.face_part_size();
  const auto optional_per_face = [&](int size) { return size == 0 || size == faces; };
  if (s.node_position_size() != 3 * nodes || s.triangle_size() != 3 * faces ||
      !optional_per_face(s.face_thickness_size()) || !optional_per_face(s.face_bulk_modulus_size()) ||
      !optional_per_face(s.face_element_volume_size()) || !optional_per_face(s.face_material_size()) ||
      (s.node_mass_size() != 0 && s.node_mass_size() != nodes)) {
    return fmt::format(
        "the surface's arrays differ in length ({} node ids, {} node coordinates, {} triangle "
        "corners, {} face parts, {} thicknesses, {} bulk moduli, {} element volumes, {} face "
        "materials, {} node masses)",
        nodes, s.node_position_size(), s.triangle_size(), faces, s.face_thickness_size(), s.face_bulk_modulus_size(),
        s.face_element_volume_size(), s.face_material_size(), s.node_mass_size());
  }
  if (const auto k = first_duplicate(s.node_id())) {
    return fmt::format("surface node {} has the id {} of an earlier node: node ids must be unique", *k,
                       s.node_id(static_cast<int>(*k)));
  }
  for (int k = 0; k < 3 * nodes; ++k) {
    if (!std::isfinite(s.node_position(k))) {
      return fmt::format("surface node {} (id {}) has a non-finite position ({})", k / 3, s.node_id(k / 3),
                         s.node_position(k));
    }
  }
  for (int k = 0; k < s.node_mass_size(); ++k) {
    if (!(std::isfinite(s.node_mass(k)) && s.node_mass(k) >= 0)) {
      return fmt::format("surface node {} (id {}) has mass {} kg: it must be finite and >= 0", k, s.node_id(k),
                         s.node_mass(k));
    }
  }
  const auto parts = static_cast<std::uint32_t>(s.part_name_size() > 0 ? s.part_name_size() : scene.structures.size());
  for (int f = 0; f < faces; ++f) {
    for (int c = 0; c < 3; ++c) {
      if (s.triangle(3 * f + c) >= static_cast<std::uint32_t>(nodes)) {
        return fmt::format("face {} names node {}, the surface has {} nodes", f, s.triangle(3 * f + c), nodes);
      }
    }
    if (s.face_part(f) >= parts) {
      return fmt::format("face {} belongs to part {}, there are {} parts", f, s.face_part(f), parts);
    }
    if (s.face_material_size() > 0 && s.face_material(f) >= scene.materials.size()) {
      return fmt::format("face {} has material {}, the scene has {} materials", f, s.face_material(f),
                         scene.materials.size());
    }
    if (s.face_thickness_size() > 0 && !(std::isfinite(s.face_thickness(f)) && s.face_thickness(f) >= 0)) {
      return fmt::format("face {} has thickness {} m: it must be finite and >= 0", f, s.face_thickness(f));
    }
    if (s.face_bulk_modulus_size() > 0 && !(std::isfinite(s.face_bulk_modulus(f)) && s.face_bulk_modulus(f) > 0)) {
      return fmt::format("face {} has bulk modulus {} Pa: it must be finite and > 0", f, s.face_bulk_modulus(f));
    }
    if (s.face_element_volume_size() > 0 &&
        !(std::isfinite(s.face_element_volume(f)) && s.face_element_volume(f) >= 0)) {
      return fmt::format("face {} has element volume {} m^3: it must be finite and >= 0", f, s.face_element_volume(f));
    }
  }
  return std::nullopt;
}

std::optional<std::string> stable_dt_problem(double stable_dt, double end_time) {
  if (std::isnan(stable_dt)) return std::string("stable_dt is NaN");
  if (!(stable_dt > 0)) return fmt::format("stable_dt = {} s must be > 0", stable_dt);
  if (std::isfinite(stable_dt) && stable_dt * kMaxSteps < end_time) {
    return fmt::format(
        "stable_dt = {:.3g} s would need more than {:.0e} steps to reach end_time = {} s: the solver's model has "
        "blown up, or an input is extreme (a Young's modulus, a stiffness, a tiny element or particle)",
        stable_dt, kMaxSteps, end_time);
  }
  return std::nullopt;
}

}  // namespace sabo::coupler
