#include "libsabo/geometry/surface_mesh.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "libsabo/core/error.hpp"

namespace sabo::geometry {

namespace {

Vec3 doubled_area_vector(const SurfaceMesh& mesh, std::size_t face) {
  const auto& t = mesh.triangle[face];
  const Vec3& a = mesh.node_position[t[0]];
  return (mesh.node_position[t[1]] - a).cross(mesh.node_position[t[2]] - a);
}

}  // namespace

Vec3 SurfaceMesh::face_normal(std::size_t face) const {
  return doubled_area_vector(*this, face).normalized();
}

double SurfaceMesh::face_area(std::size_t face) const {
  return 0.5 * doubled_area_vector(*this, face).norm();
}

Aabb SurfaceMesh::bounds() const {
  Aabb box;
  for (const Vec3& p : node_position) box.extend(p);
  return box;
}

double SurfaceMesh::mass_of(std::size_t node) const {
  const double mass = node < node_mass.size() ? node_mass[node] : 0.0;
  return mass > 0 ? mass : std::numeric_limits<double>::infinity();
}

void SurfaceMesh::make_single_part(const std::string& name) {
  node_id.resize(node_position.size());
  for (std::size_t i = 0; i < node_id.size(); ++i) node_id[i] = i;
  const std::size_t faces = triangle.size();
  face_part.assign(faces, 0);
  face_material.assign(faces, 0);
  face_thickness.assign(faces, 0.0);
  face_bulk_modulus.assign(faces, 0.0);
  face_element_volume.assign(faces, 0.0);
  part_name = {name};
  node_mass.clear();
}

void SurfaceMesh::append(const SurfaceMesh& other) {
  const auto node_offset = static_cast<std::uint32_t>(node_position.size());
  const auto part_offset = static_cast<std::uint32_t>(part_name.size());
  node_id.insert(node_id.end(), other.node_id.begin(), other.node_id.end());
  if (!node_mass.empty() || !other.node_mass.empty()) {
    node_mass.resize(node_offset, 0.0);
    if (other.node_mass.empty()) {
      node_mass.resize(node_offset + other.node_position.size(), 0.0);
    } else {
      node_mass.insert(node_mass.end(), other.node_mass.begin(), other.node_mass.end());
    }
  }
  node_position.insert(node_position.end(), other.node_position.begin(), other.node_position.end());
  triangle.reserve(triangle.size() + other.triangle.size());
  for (const auto& t : other.triangle) triangle.push_back({t[0] + node_offset, t[1] + node_offset, t[2] + node_offset});
  face_part.reserve(face_part.size() + other.face_part.size());
  for (std::uint32_t part : other.face_part) face_part.push_back(part + part_offset);
  face_material.insert(face_material.end(), other.face_material.begin(), other.face_material.end());
  face_thickness.insert(face_thickness.end(), other.face_thickness.begin(), other.face_thickness.end());
  face_bulk_modulus.insert(face_bulk_modulus.end(), other.face_bulk_modulus.begin(), other.face_bulk_modulus.end());
  face_element_volume.insert(face_element_volume.end(), other.face_element_volume.begin(),
                             other.face_element_volume.end());
  part_name.insert(part_name.end(), other.part_name.begin(), other.part_name.end());
}

void SurfaceMesh::validate(const std::string& what) const {
  auto fail = [&](const std::string& problem) {
    throw Error(fmt::format("{}: invalid surface mesh: {}", what, problem));
  };
  const std::size_t nodes = node_position.size();
  const std::size_t faces = triangle.size();
  if (node_id.size() != nodes) fail(fmt::format("{} node ids for {} nodes", node_id.size(), nodes));
  if (!node_mass.empty() && node_mass.size() != nodes) {
    fail(fmt::format("{} node masses for {} nodes", node_mass.size(), nodes));
  }
  for (std::size_t i = 0; i < node_mass.size(); ++i) {
    if (!std::isfinite(node_mass[i]) || node_mass[i] < 0) {
      fail(fmt::format("node {} (id {}) has mass {} kg (must be finite and >= 0; 0: rigid)", i, node_id[i],
                       node_mass[i]));
    }
  }
  auto check_face_array = [&](std::size_t size, const char* name) {
    if (size != faces) fail(fmt::format("{} has {} entries for {} faces", name, size, faces));
  };
  check_face_array(face_part.size(), "face_part");
  check_face_array(face_material.size(), "face_material");
  check_face_array(face_thickness.size(), "face_thickness");
  check_face_array(face_bulk_modulus.size(), "face_bulk_modulus");
  check_face_array(face_element_volume.size(), "face_element_volume");
  for (std::size_t i = 0; i < nodes; ++i) {
    if (!node_position[i].allFinite()) {
      fail(fmt::format("node {} (id {}) has a non-finite position ({}, {}, {})", i, node_id[i], node_position[i].x(),
                       node_position[i].y(), node_position[i].z()));
    }
  }
  std::vector<std::uint64_t> ids = node_id;
  std::sort(ids.begin(), ids.end());
  if (auto duplicate = std::adjacent_find(ids.begin(), ids.end()); duplicate != ids.end()) {
    fail(fmt::format("node id {} is used twice", *duplicate));
  }
  for (std::size_t f = 0; f < faces; ++f) {
    const auto& t = triangle[f];
    for (std::uint32_t node : t) {
      if (node >= nodes) fail(fmt::format("face {} refers to node {} but there are {} nodes", f, node, nodes));
    }
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      fail(fmt::format("face {} repeats a node ({}, {}, {})", f, t[0], t[1], t[2]));
    }
    const Vec3 doubled_area = doubled_area_vector(*this, f);
    if (!(doubled_area.norm() > 0)) {
      fail(fmt::format("face {} (nodes {}, {}, {}) has zero area", f, t[0], t[1], t[2]));
    }
    if (face_part[f] >= part_name.size()) {
      fail(fmt::format("face {} belongs to part {} but there are {} parts", f, face_part[f], part_name.size()));
    }
    auto non_negative = [&](double value, const char* name) {
      if (!std::isfinite(value) || value < 0) fail(fmt::format("face {} has {} = {}", f, name, value));
    };
    non_negative(face_thickness[f], "face_thickness");
    non_negative(face_bulk_modulus[f], "face_bulk_modulus");
    non_negative(face_element_volume[f], "face_element_volume");
  }
}

}  // namespace sabo::geometry
