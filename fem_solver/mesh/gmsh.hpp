#pragma once
// Gmsh .msh version 4 (ASCII) reader for deformable structures: 8-node
// hexahedra (element type 5, Gmsh's node order is ours) become solid
// elements, 4-node quadrangles (type 3) shell elements; points and lines
// (types 15, 1) are skipped; any other element type is an error. Nodes are
// renumbered in file order; only nodes used by kept elements stay.
#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "fem_solver/mesh/hex_mesh.hpp"

namespace sabo::fem {

struct GmshMesh {
  HexMesh hexahedra;                                // nodes shared with quads
  std::vector<std::array<std::uint32_t, 4>> quads;  // indices into hexahedra.node
};

// Throws FileError (unreadable file) or SceneError naming file:line, what is
// wrong and the fix (not version 4, binary, truncated sections, unknown node
// tags, unsupported element types, inverted hexahedra).
[[nodiscard]] GmshMesh read_gmsh(const std::filesystem::path& file);

}  // namespace sabo::fem
