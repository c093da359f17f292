// Gmsh msh 4.1 ASCII reader: hexahedra in Gmsh's node order, and errors that
// name file:line, the problem and the fix.
#include <gtest/gtest.h>

#include <iostream>

#include "fem_solver/fem_model.hpp"
#include "fem_solver/mesh/gmsh.hpp"
#include "libsabo/core/error.hpp"

namespace {
std::filesystem::path data(const char* name) {
  return std::filesystem::path(SABO_SOURCE_DIR) / "tests/fem_solver/data" / name;
}
}  // namespace

TEST(Gmsh, ReadsHexahedraAndSkipsPoints) {
  const sabo::fem::GmshMesh mesh = sabo::fem::read_gmsh(data("two_hexes.msh"));
  EXPECT_EQ(mesh.hexahedra.node.size(), 12u);
  ASSERT_EQ(mesh.hexahedra.element.size(), 2u);
  EXPECT_TRUE(mesh.quads.empty());
  EXPECT_EQ(sabo::fem::exterior_faces(mesh.hexahedra).size(), 10u);
}

TEST(Gmsh, UnknownNodeTagNamesFileAndLine) {
  try {
    (void)sabo::fem::read_gmsh(data("broken_node_tag.msh"));
    ADD_FAILURE() << "no exception";
  } catch (const sabo::SceneError& error) {
    const std::string text = error.what();
    std::cout << text << "\n";
    EXPECT_NE(text.find("broken_node_tag.msh:42: element 3 uses node tag 13"), std::string::npos) << text;
    EXPECT_NE(text.find("Fix:"), std::string::npos) << text;
  }
}

TEST(Gmsh, MissingFileIsAFileError) {
  EXPECT_THROW((void)sabo::fem::read_gmsh(data("no_such.msh")), sabo::FileError);
}

TEST(Gmsh, DeformableStructureFromAMshFile) {
  sabo::scene::Scene scene;
  sabo::scene::Material steel;
  steel.name = "steel";
  steel.density = 7850;
  steel.youngs_modulus = 210e9;
  steel.poisson_ratio = 0.3;
  scene.materials.push_back(steel);
  sabo::scene::Structure block;
  block.name = "block";
  block.material = "steel";
  block.rigid = false;
  block.shape.type = sabo::scene::Shape::Type::mesh;
  block.shape.file = data("two_hexes.msh");
  block.shape.scale = 2.0;
  block.fixed_faces = {"z-"};
  scene.structures.push_back(block);
  sabo::fem::FemModel model(scene);
  EXPECT_EQ(model.surface().face_count(), 20u);  // 10 exterior quads
  EXPECT_FALSE(model.deformable(0)->is_shell());
  EXPECT_NEAR(model.deformable(0)->solid()->total_mass(), 7850 * 2 * 8.0, 1e-6);
  scene.structures[0].shape.file = data("broken_node_tag.msh");
  EXPECT_THROW(sabo::fem::FemModel broken(scene), sabo::SceneError);
}
