#pragma once
// Gmsh .msh version 4 (ASCII) reader for deformable structures: 8-node
// hexahedra (element type 5, Gmsh's node order is geometry/hexahedron.hpp's)
// for solids, 4-node quadrangles (type 3) for shells; points and lines (types
// 15, 1) are skipped; any other element type is an error. Nodes are
// renumbered in file order; only nodes used by kept elements stay. The scene
// check (scene/loader.hpp) and the fem_solver read meshes through this one
// reader.
#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::io {

struct GmshMesh {
  std::vector<Vec3> node;                               // m, as in the file
  std::vector<std::array<std::uint32_t, 8>> hexahedra;  // indices into node, positive volume
  std::vector<std::array<std::uint32_t, 4>> quads;      // indices into node, non-zero area
};

// Throws sabo::FileError naming file:line, what is wrong and the fix: a file
// that cannot be opened, is not version 4 or is binary, truncated sections,
// counts the file is too short to hold, non-finite coordinates, unknown node
// tags, unsupported element types, inverted or flat hexahedra, quadrangles of
// zero area, no elements at all.
[[nodiscard]] GmshMesh read_gmsh(const std::filesystem::path& file);

}  // namespace sabo::io
