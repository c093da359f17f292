#pragma once
// A triangulated contact surface: what the FEM solver exposes and the coupler
// contacts against. Mirrors the protocol's SurfaceTopology.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::geometry {

struct SurfaceMesh {
  std::vector<std::uint64_t> node_id;  // stable id per node
  std::vector<Vec3> node_position;     // m
  // kg: lumped mass of each node of a deformable part, 0 for rigid parts
  // (infinitely heavy); empty: every node is rigid.
  std::vector<double> node_mass;
  std::vector<std::array<std::uint32_t, 3>> triangle;  // counter-clockwise seen from the outward normal
  std::vector<std::uint32_t> face_part;                // index into part_name
  std::vector<std::uint32_t> face_material;            // scene material index
  std::vector<double> face_thickness;                  // m: shell thickness, 0 for solid faces
  std::vector<double> face_bulk_modulus;               // Pa
  std::vector<double> face_element_volume;             // m^3: owning solid element, 0 for shells
  std::vector<std::string> part_name;

  [[nodiscard]] std::size_t node_count() const { return node_position.size(); }
  [[nodiscard]] std::size_t face_count() const { return triangle.size(); }
  [[nodiscard]] Vec3 face_normal(std::size_t face) const;  // unit, outward
  [[nodiscard]] double face_area(std::size_t face) const;  // m^2
  [[nodiscard]] Aabb bounds() const;
  // Mass of node i, kg; infinity for a rigid node.
  [[nodiscard]] double mass_of(std::size_t node) const;
  // Given nodes and triangles: node ids 0..n-1, every face in one part named
  // `name`, material 0, no thickness, bulk modulus and volume 0, no node
  // masses (rigid; the FEM model sets the physical attributes).
  void make_single_part(const std::string& name);
  // Appends `other`, offsetting node and part indices (node masses: 0 for the
  // rigid nodes of the side that has none).
  void append(const SurfaceMesh& other);
  // Throws sabo::Error naming `what` if sizes disagree, an index is out of
  // range or a value is not finite.
  void validate(const std::string& what) const;
};

}  // namespace sabo::geometry
