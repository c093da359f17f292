#include "libsabo/protocol/surface_codec.hpp"

#include <fmt/format.h>

#include "libsabo/core/error.hpp"

namespace sabo::protocol {

void surface_to_message(const geometry::SurfaceMesh& mesh, std::uint64_t revision, sabo::v1::SurfaceTopology& out) {
  out.Clear();
  out.set_revision(revision);
  out.mutable_node_id()->Assign(mesh.node_id.begin(), mesh.node_id.end());
  auto* positions = out.mutable_node_position();
  positions->Reserve(static_cast<int>(3 * mesh.node_count()));
  for (const auto& p : mesh.node_position) {
    positions->Add(p.x());
    positions->Add(p.y());
    positions->Add(p.z());
  }
  auto* triangles = out.mutable_triangle();
  triangles->Reserve(static_cast<int>(3 * mesh.face_count()));
  for (const auto& t : mesh.triangle) {
    triangles->Add(t[0]);
    triangles->Add(t[1]);
    triangles->Add(t[2]);
  }
  out.mutable_face_part()->Assign(mesh.face_part.begin(), mesh.face_part.end());
  out.mutable_face_material()->Assign(mesh.face_material.begin(), mesh.face_material.end());
  out.mutable_face_thickness()->Assign(mesh.face_thickness.begin(), mesh.face_thickness.end());
  out.mutable_face_bulk_modulus()->Assign(mesh.face_bulk_modulus.begin(), mesh.face_bulk_modulus.end());
  out.mutable_face_element_volume()->Assign(mesh.face_element_volume.begin(), mesh.face_element_volume.end());
  for (const auto& name : mesh.part_name) out.add_part_name(name);
  out.mutable_node_mass()->Assign(mesh.node_mass.begin(), mesh.node_mass.end());
}

bool arrays_consistent(const sabo::v1::SurfaceTopology& topology) {
  return topology.node_position_size() == 3 * topology.node_id_size() && topology.triangle_size() % 3 == 0 &&
         topology.face_part_size() * 3 == topology.triangle_size() &&
         (topology.node_mass_size() == 0 || topology.node_mass_size() == topology.node_id_size());
}

geometry::SurfaceMesh surface_from_message(const sabo::v1::SurfaceTopology& topology, const std::string& sender) {
  if (!arrays_consistent(topology)) {
    throw ProtocolError(
        fmt::format("the surface sent by {}: its arrays differ in length ({} node ids, {} node "
                    "coordinates, {} triangle corners, {} face parts, {} node masses)",
                    sender, topology.node_id_size(), topology.node_position_size(), topology.triangle_size(),
                    topology.face_part_size(), topology.node_mass_size()));
  }
  geometry::SurfaceMesh mesh;
  const auto nodes = static_cast<std::size_t>(topology.node_id_size());
  mesh.node_id.assign(topology.node_id().begin(), topology.node_id().end());
  mesh.node_position.resize(nodes);
  for (std::size_t i = 0; i < nodes; ++i) {
    const int k = static_cast<int>(3 * i);
    mesh.node_position[i] =
        Vec3(topology.node_position(k), topology.node_position(k + 1), topology.node_position(k + 2));
  }
  const auto faces = static_cast<std::size_t>(topology.face_part_size());
  mesh.triangle.resize(faces);
  for (std::size_t f = 0; f < faces; ++f) {
    const int k = static_cast<int>(3 * f);
    mesh.triangle[f] = {topology.triangle(k), topology.triangle(k + 1), topology.triangle(k + 2)};
  }
  mesh.face_part.assign(topology.face_part().begin(), topology.face_part().end());
  mesh.face_material.assign(topology.face_material().begin(), topology.face_material().end());
  mesh.face_thickness.assign(topology.face_thickness().begin(), topology.face_thickness().end());
  mesh.face_bulk_modulus.assign(topology.face_bulk_modulus().begin(), topology.face_bulk_modulus().end());
  mesh.face_element_volume.assign(topology.face_element_volume().begin(), topology.face_element_volume().end());
  mesh.part_name.assign(topology.part_name().begin(), topology.part_name().end());
  mesh.node_mass.assign(topology.node_mass().begin(), topology.node_mass().end());
  mesh.validate("the surface sent by " + sender);
  return mesh;
}

}  // namespace sabo::protocol
