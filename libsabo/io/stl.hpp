#pragma once
// STL reader (ASCII and binary) producing a welded triangle surface.
#include <cstddef>
#include <filesystem>
#include <string>

#include "libsabo/geometry/surface_mesh.hpp"

namespace sabo::io {

struct StlOptions {
  // Corners closer than this fraction of the model's bounding-box diagonal
  // become one node, so that neighbouring triangles share their edges.
  // 0: only bit-identical corners are merged.
  double merge_tolerance = 1e-9;
};

struct StlMesh {
  // One part named after the file's stem; node ids 0..n-1; vertex order as in
  // the file (counter-clockwise seen from outside); per-face attributes zero.
  geometry::SurfaceMesh mesh;
  bool binary = false;
  std::size_t triangles_in_file = 0;
  std::size_t degenerate_dropped = 0;  // triangles of zero area after merging
};

// Throws sabo::FileError naming the file, the line (ASCII) or triangle
// (binary), what was expected and how to fix it.
[[nodiscard]] StlMesh read_stl(const std::filesystem::path& file, const StlOptions& options = {});

}  // namespace sabo::io
