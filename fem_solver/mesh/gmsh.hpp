#pragma once
// The fem_solver's view of a Gmsh mesh file: hexahedra as a HexMesh (solids),
// quadrangles on the same nodes (shells). The reader itself is
// libsabo/io/gmsh.hpp (issue 18 moved it there, so that the scene check reads
// every mesh file through the same reader); this keeps the fem_solver's
// interface of before.
#include <array>
#include <cstdint>
#include <filesystem>
#include <utility>
#include <vector>

#include "fem_solver/mesh/hex_mesh.hpp"
#include "libsabo/io/gmsh.hpp"

namespace sabo::fem {

struct GmshMesh {
  HexMesh hexahedra;                                // nodes shared with quads
  std::vector<std::array<std::uint32_t, 4>> quads;  // indices into hexahedra.node
};

// Throws FileError naming file:line, what is wrong and the fix (io::read_gmsh).
[[nodiscard]] inline GmshMesh read_gmsh(const std::filesystem::path& file) {
  io::GmshMesh mesh = io::read_gmsh(file);
  return {HexMesh{std::move(mesh.node), std::move(mesh.hexahedra)}, std::move(mesh.quads)};
}

}  // namespace sabo::fem
