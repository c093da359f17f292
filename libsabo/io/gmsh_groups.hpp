#pragma once
// The physical groups of a Gmsh .msh version 4 (ASCII) file: what a scene's
// constraint `tag` names (docs/scene.md, [[structures]] constraints). A group
// is a named set of entities of one dimension ($PhysicalNames, $Entities); its
// nodes are those of every element ($Elements, any type) that lies on one of
// its entities. The scene check and the fem_solver read groups through this
// one reader; the element mesh itself is read by the fem_solver's reader.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::io {

struct GmshGroup {
  std::string name;                 // as in $PhysicalNames
  int dimension = 0;                // 0 points, 1 curves, 2 surfaces, 3 volumes
  int tag = 0;                      // physical tag
  std::vector<std::uint32_t> node;  // indices into GmshGroups::node, ascending, each once
};

struct GmshGroups {
  std::vector<Vec3> node;        // m, every node of $Nodes in file order, as in the file
  std::vector<GmshGroup> group;  // named groups in $PhysicalNames order
  [[nodiscard]] const GmshGroup* find(const std::string& name) const;
  [[nodiscard]] std::vector<std::string> names() const;
};

// Throws FileError when the file cannot be opened, SceneError naming file:line,
// the problem and the fix for a malformed file (not version 4, binary,
// truncated sections, elements on unknown nodes). A file without
// $PhysicalNames has no groups.
[[nodiscard]] GmshGroups read_gmsh_groups(const std::filesystem::path& file);

}  // namespace sabo::io
