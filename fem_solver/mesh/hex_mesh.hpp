#pragma once
// Hexahedral meshes of deformable solids: structured generators and the
// exterior surface (the faces the coupler contacts against).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::fem {

// Nodes and 8-node hexahedra (node order of elements/hex8.hpp, positive volume).
struct HexMesh {
  std::vector<Vec3> node;  // m
  std::vector<std::array<std::uint32_t, 8>> element;
};

// The box [min, max] cut into divisions[0] x divisions[1] x divisions[2] equal hexahedra (each >= 1).
[[nodiscard]] HexMesh structured_box(const Aabb& box, const std::array<std::size_t, 3>& divisions);

// A circular cylinder along z: base centre `base`, `radius`, `length`; the
// section is an n x n grid mapped onto the disc (elliptical grid mapping),
// `axial` layers along z.
[[nodiscard]] HexMesh structured_cylinder(const Vec3& base, double radius, double length, std::size_t section,
                                          std::size_t axial);

// One face of an element on the exterior of the active elements: its nodes
// counter-clockwise seen from outside.
struct BoundaryFace {
  std::array<std::uint32_t, 4> node{};
  std::uint32_t element = 0;
};

// Faces of active elements (active[e] != 0; empty span: all) not shared with
// another active element, sorted by (element, local face): deterministic.
[[nodiscard]] std::vector<BoundaryFace> exterior_faces(const HexMesh& mesh, std::span<const std::uint8_t> active = {});

// Local faces of a hexahedron, outward (node indices 0..7).
[[nodiscard]] const std::array<std::array<int, 4>, 6>& hex_faces();

}  // namespace sabo::fem
