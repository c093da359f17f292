#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <limits>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/node_welder.hpp"
#include "libsabo/geometry/surface_mesh.hpp"

using sabo::Vec3;
using sabo::geometry::SurfaceMesh;

namespace {

SurfaceMesh triangle_mesh(const std::string& part, double z) {
  SurfaceMesh mesh;
  mesh.node_id = {0, 1, 2};
  mesh.node_position = {{0, 0, z}, {2, 0, z}, {0, 1, z}};
  mesh.triangle = {{0, 1, 2}};
  mesh.face_part = {0};
  mesh.face_material = {3};
  mesh.face_thickness = {0.1};
  mesh.face_bulk_modulus = {1e9};
  mesh.face_element_volume = {0};
  mesh.part_name = {part};
  return mesh;
}

std::string error_of(const SurfaceMesh& mesh) {
  try {
    mesh.validate("test mesh");
  } catch (const sabo::Error& error) {
    return error.what();
  }
  return {};
}

}  // namespace

TEST(SurfaceMesh, NormalAreaBounds) {
  const SurfaceMesh mesh = triangle_mesh("a", 1.0);
  EXPECT_EQ(mesh.face_normal(0), Vec3(0, 0, 1));
  EXPECT_DOUBLE_EQ(mesh.face_area(0), 1.0);
  EXPECT_EQ(mesh.bounds().min, Vec3(0, 0, 1));
  EXPECT_EQ(mesh.bounds().max, Vec3(2, 1, 1));
  EXPECT_TRUE(SurfaceMesh{}.bounds().empty());
}

TEST(SurfaceMesh, AppendOffsetsNodesAndParts) {
  SurfaceMesh mesh = triangle_mesh("a", 0.0);
  SurfaceMesh other = triangle_mesh("b", 5.0);
  other.node_id = {10, 11, 12};
  mesh.append(other);
  EXPECT_EQ(mesh.node_count(), 6u);
  EXPECT_EQ(mesh.face_count(), 2u);
  EXPECT_EQ(mesh.triangle[1], (std::array<std::uint32_t, 3>{3, 4, 5}));
  EXPECT_EQ(mesh.face_part, (std::vector<std::uint32_t>{0, 1}));
  EXPECT_EQ(mesh.part_name, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(mesh.face_material, (std::vector<std::uint32_t>{3, 3}));
  EXPECT_EQ(mesh.node_position[4], Vec3(2, 0, 5));
  EXPECT_NO_THROW(mesh.validate("appended"));
  // Appending a second copy with the same node ids makes them ambiguous.
  mesh.append(other);
  EXPECT_NE(error_of(mesh).find("node id 10 is used twice"), std::string::npos) << error_of(mesh);
}

TEST(SurfaceMesh, ValidateNamesTheProblem) {
  SurfaceMesh mesh = triangle_mesh("a", 0.0);
  mesh.face_thickness.push_back(0.0);
  EXPECT_NE(error_of(mesh).find("test mesh: invalid surface mesh: face_thickness has 2 entries for 1 faces"),
            std::string::npos)
      << error_of(mesh);
  mesh = triangle_mesh("a", 0.0);
  mesh.triangle[0][2] = 7;
  EXPECT_NE(error_of(mesh).find("face 0 refers to node 7 but there are 3 nodes"), std::string::npos);
  mesh = triangle_mesh("a", 0.0);
  mesh.node_position[1].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(error_of(mesh).find("node 1 (id 1) has a non-finite position"), std::string::npos);
  mesh = triangle_mesh("a", 0.0);
  mesh.node_position[2] = Vec3(1, 0, 0);  // collinear
  EXPECT_NE(error_of(mesh).find("zero area"), std::string::npos);
  mesh = triangle_mesh("a", 0.0);
  mesh.face_part[0] = 1;
  EXPECT_NE(error_of(mesh).find("belongs to part 1 but there are 1 parts"), std::string::npos);
  mesh = triangle_mesh("a", 0.0);
  mesh.face_bulk_modulus[0] = -1;
  EXPECT_NE(error_of(mesh).find("face_bulk_modulus = -1"), std::string::npos);
}

TEST(NodeWelder, MergesWithinTolerance) {
  sabo::geometry::NodeWelder exact(0);
  EXPECT_EQ(exact.add(Vec3(1, 2, 3)), 0u);
  EXPECT_EQ(exact.add(Vec3(1, 2, 3 + 1e-15)), 1u);
  EXPECT_EQ(exact.add(Vec3(1, 2, 3)), 0u);
  EXPECT_EQ(exact.add(Vec3(0.0, 0, 0)), 2u);
  EXPECT_EQ(exact.add(Vec3(-0.0, 0, 0)), 2u);

  sabo::geometry::NodeWelder near(1e-6);
  EXPECT_EQ(near.add(Vec3(0, 0, 0)), 0u);
  EXPECT_EQ(near.add(Vec3(0.9e-6, 0, 0)), 0u);   // within, even across a cell boundary
  EXPECT_EQ(near.add(Vec3(-0.5e-6, 0, 0)), 0u);  // another cell
  EXPECT_EQ(near.add(Vec3(2e-6, 0, 0)), 1u);
  EXPECT_EQ(near.positions().size(), 2u);
}
