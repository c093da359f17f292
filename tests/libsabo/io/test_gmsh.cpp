// Gmsh msh 4.1 ASCII reader (libsabo/io/gmsh.hpp): hexahedra and quadrangles
// in Gmsh's node order, and every malformed file refused with a FileError that
// names file:line, the problem and the fix, before anything is sized by it.
#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/io/gmsh.hpp"

namespace {

std::filesystem::path data(const std::string& name) {
  return std::filesystem::path(SABO_SOURCE_DIR) / "tests/libsabo/io/data" / name;
}
std::filesystem::path bad_mesh(const std::string& name) {
  return std::filesystem::path(SABO_SOURCE_DIR) / "tests/scenes/bad/meshes" / name;
}

// The reader's message for `file`, or "" when it was read.
std::string refusal(const std::filesystem::path& file) {
  try {
    (void)sabo::io::read_gmsh(file);
  } catch (const sabo::FileError& error) {
    return error.what();
  }
  return "";
}

TEST(GmshReader, ReadsHexahedraAndSkipsPoints) {
  const sabo::io::GmshMesh mesh = sabo::io::read_gmsh(data("two_hexes.msh"));
  EXPECT_EQ(mesh.node.size(), 12u);
  ASSERT_EQ(mesh.hexahedra.size(), 2u);
  EXPECT_TRUE(mesh.quads.empty());
  EXPECT_EQ(mesh.hexahedra[0][0], 0u);  // tag 1, the first node of the file
  EXPECT_EQ(mesh.node[11], sabo::Vec3(2, 1, 1));
}

TEST(GmshReader, ReadsQuadrangles) {
  const sabo::io::GmshMesh mesh = sabo::io::read_gmsh(data("shell_strip.msh"));
  EXPECT_TRUE(mesh.hexahedra.empty());
  EXPECT_EQ(mesh.quads.size(), 40u);
  EXPECT_EQ(mesh.node.size(), 63u);
}

TEST(GmshReader, UnknownNodeTagNamesFileAndLine) {
  const std::string text = refusal(data("broken_node_tag.msh"));
  std::cout << text << "\n";
  EXPECT_NE(text.find("broken_node_tag.msh:42: element 3 uses node tag 13"), std::string::npos) << text;
  EXPECT_NE(text.find("Fix:"), std::string::npos) << text;
}

TEST(GmshReader, MissingFileIsAFileError) {
  const std::string text = refusal(data("no_such.msh"));
  EXPECT_NE(text.find("cannot open the Gmsh mesh file"), std::string::npos) << text;
}

// The bad meshes of the scene check (tests/scenes/bad/meshes): each is refused here, with the line and
// the problem (a declared count of 4e9 nodes used to be reserved: std::bad_alloc; a quadrangle of zero
// area used to be accepted).
TEST(GmshReader, BadMeshesAreRefusedWithLineAndProblem) {
  struct Bad {
    const char* file;
    const char* expected;
  };
  const std::vector<Bad> cases{
      {"garbage.msh", "garbage.msh:2: missing $MeshFormat, $Nodes or $Elements"},
      {"empty.msh", "empty.msh: not a Gmsh mesh: the file is empty (0 bytes)"},
      {"truncated.msh", "truncated.msh:26: the file ends where node coordinates was expected"},
      {"huge_count.msh", "huge_count.msh:9: the header declares 4000000000 nodes, more than a file of"},
      {"nan_node.msh", "nan_node.msh:27: node coordinates x y z: 'nan 1 0' is not a finite number"},
      {"inverted_hex.msh", "inverted_hex.msh:41: hexahedron 2 is inverted or flat (volume -1 m^3)"},
      {"degenerate_quad.msh", "degenerate_quad.msh:24: quadrangle 2 has zero area"},
  };
  for (const Bad& bad : cases) {
    const std::string text = refusal(bad_mesh(bad.file));
    std::cout << bad.file << ": " << (text.empty() ? "(read without error)" : text) << "\n";
    EXPECT_NE(text.find(bad.expected), std::string::npos) << "expected: " << bad.expected << "\nmeasured: " << text;
    EXPECT_NE(text.find(". Fix: "), std::string::npos) << text;
  }
}

}  // namespace
