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

// Elements along an edge of `length` (m) for a target `element_size` (m): the
// nearest whole number, at least one (one when element_size is 0).
[[nodiscard]] std::size_t element_divisions(double length, double element_size);

// The box [min, max] cut into divisions[0] x divisions[1] x divisions[2] equal hexahedra (each >= 1).
[[nodiscard]] HexMesh structured_box(const Aabb& box, const std::array<std::size_t, 3>& divisions);

// The box spanned by grid lines: lines[d] holds the increasing node
// coordinates along axis d (at least two each), m.
[[nodiscard]] HexMesh structured_grid(const std::array<std::vector<double>, 3>& lines);

// A slit dam: the box with `slit_count` vertical slits open at the top,
// `slit_width` wide and `slit_depth` deep (m), cut through the box along axis
// `slit_axis` (0: x, 1: y) and spaced along the other horizontal axis so that
// the slit_count + 1 piers are equally wide. The grid has node lines on every
// slit edge (the slits are exact) and elements of about `element_size` (m;
// 0: one element per pier, slit and height segment). Nodes of removed
// elements that no kept element uses are dropped.
[[nodiscard]] HexMesh slit_dam(const Aabb& box, std::size_t slit_count, double slit_width, double slit_depth,
                               int slit_axis, double element_size);

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
