#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <numbers>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/polygon.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "tests/support/scratch.hpp"

using sabo::Vec3;
using sabo::geometry::SurfaceMesh;
using sabo::scene::Shape;

namespace {

// How many faces use each undirected edge.
std::map<std::pair<std::uint32_t, std::uint32_t>, int> edge_use(const SurfaceMesh& mesh) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> use;
  for (const auto& t : mesh.triangle) {
    for (int k = 0; k < 3; ++k) {
      const auto a = t[k];
      const auto b = t[(k + 1) % 3];
      ++use[{std::min(a, b), std::max(a, b)}];
    }
  }
  return use;
}

double total_area(const SurfaceMesh& mesh) {
  double area = 0;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) area += mesh.face_area(f);
  return area;
}

Vec3 area_vector(const SurfaceMesh& mesh) {
  Vec3 sum = Vec3::Zero();
  for (std::size_t f = 0; f < mesh.face_count(); ++f) sum += mesh.face_area(f) * mesh.face_normal(f);
  return sum;
}

Vec3 centroid(const SurfaceMesh& mesh, std::size_t face) {
  const auto& t = mesh.triangle[face];
  return (mesh.node_position[t[0]] + mesh.node_position[t[1]] + mesh.node_position[t[2]]) / 3.0;
}

// No two nodes at the same place: every shared edge shares its nodes.
std::size_t duplicate_positions(const SurfaceMesh& mesh, double tolerance) {
  std::size_t duplicates = 0;
  for (std::size_t i = 0; i < mesh.node_count(); ++i) {
    for (std::size_t j = i + 1; j < mesh.node_count(); ++j) {
      if ((mesh.node_position[i] - mesh.node_position[j]).norm() <= tolerance) ++duplicates;
    }
  }
  return duplicates;
}

double longest_edge(const SurfaceMesh& mesh) {
  double longest = 0;
  for (const auto& t : mesh.triangle) {
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (mesh.node_position[t[k]] - mesh.node_position[t[(k + 1) % 3]]).norm());
    }
  }
  return longest;
}

Shape chute_shape(double element_size, double end_wall) {
  Shape shape;
  shape.type = Shape::Type::chute;
  shape.origin = Vec3(1, 2, 10);
  shape.direction = Vec3(0, 1, 0);  // runs along +y
  shape.length = 8;
  shape.width = 2;
  shape.slope_deg = 30;
  shape.wall_height = 1;
  shape.end_wall_height = end_wall;
  shape.element_size = element_size;
  return shape;
}

}  // namespace

TEST(GridLevels, CountAndEnds) {
  EXPECT_EQ(sabo::geometry::grid_levels(2.0, 0).size(), 2u);
  EXPECT_EQ(sabo::geometry::grid_levels(1.0, 0.1).size(), 11u);  // 10 cells despite 1.0 / 0.1 rounding
  EXPECT_EQ(sabo::geometry::grid_levels(1.0, 0.3).size(), 5u);
  EXPECT_EQ(sabo::geometry::grid_levels(0.2, 0.5).size(), 2u);
  EXPECT_EQ(sabo::geometry::grid_levels(1.0, 0.3).back(), 1.0);
}

TEST(Primitives, PlaneAreaNormalAndElementSize) {
  Shape shape;
  shape.type = Shape::Type::plane;
  shape.origin = Vec3(1, 1, 1);
  shape.normal = Vec3(0, 0, 2);
  shape.direction = Vec3(1, 0, 1);  // projected onto the plane: +x
  shape.length = 3;
  shape.width = 2;
  const SurfaceMesh coarse = sabo::geometry::triangulate(shape, "floor");
  EXPECT_EQ(coarse.node_count(), 4u);
  EXPECT_EQ(coarse.face_count(), 2u);
  EXPECT_NEAR(total_area(coarse), 6.0, 1e-12);
  for (std::size_t f = 0; f < coarse.face_count(); ++f) EXPECT_NEAR(coarse.face_normal(f).z(), 1.0, 1e-12);
  EXPECT_NEAR(coarse.bounds().min.x(), -0.5, 1e-12);
  EXPECT_NEAR(coarse.bounds().max.y(), 2.0, 1e-12);
  EXPECT_NO_THROW(coarse.validate("plane"));

  shape.element_size = 0.25;
  const SurfaceMesh fine = sabo::geometry::triangulate(shape, "floor");
  EXPECT_EQ(fine.node_count(), 13u * 9u);
  EXPECT_EQ(fine.face_count(), 2u * 12u * 8u);
  EXPECT_NEAR(total_area(fine), 6.0, 1e-12);
  const double longest = longest_edge(fine);
  std::cout << "plane, element size 0.25: longest edge " << longest << " (the quad diagonal, expected "
            << 0.25 * std::sqrt(2.0) << ")\n";
  EXPECT_LE(longest, 0.25 * std::sqrt(2.0) * (1 + 1e-12));
  EXPECT_EQ(duplicate_positions(fine, 1e-9), 0u);
}

TEST(Primitives, ClosedBoxOutwardNormals) {
  Shape shape;
  shape.type = Shape::Type::box;
  shape.box.min = Vec3(-1, 0, 2);
  shape.box.max = Vec3(1, 3, 2.5);
  shape.element_size = 0.4;
  const SurfaceMesh mesh = sabo::geometry::triangulate(shape, "house");
  EXPECT_NO_THROW(mesh.validate("box"));
  const double expected_area = 2 * (2 * 3 + 3 * 0.5 + 2 * 0.5);
  std::cout << "box area: measured " << total_area(mesh) << " expected " << expected_area << "\n";
  EXPECT_NEAR(total_area(mesh), expected_area, 1e-10);
  EXPECT_LT(area_vector(mesh).norm(), 1e-12);
  const Vec3 center(0, 1.5, 2.25);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    EXPECT_GT((centroid(mesh, f) - center).dot(mesh.face_normal(f)), 0) << "face " << f << " points inward";
  }
  // Closed and conforming: every edge is used by exactly two faces.
  for (const auto& [edge, count] : edge_use(mesh)) ASSERT_EQ(count, 2) << edge.first << "-" << edge.second;
  EXPECT_EQ(duplicate_positions(mesh, 1e-9), 0u);
  EXPECT_LE(longest_edge(mesh), 0.4 * std::sqrt(2.0) * (1 + 1e-12));
  // Divergence theorem: the enclosed volume from the surface.
  double volume = 0;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    volume += centroid(mesh, f).dot(mesh.face_normal(f)) * mesh.face_area(f) / 3.0;
  }
  EXPECT_NEAR(volume, 2 * 3 * 0.5, 1e-10);
}

TEST(Primitives, ChuteAreaAndInwardNormals) {
  for (double end_wall : {0.0, 0.6, 1.5}) {
    for (double element_size : {0.0, 0.35}) {
      const Shape shape = chute_shape(element_size, end_wall);
      const SurfaceMesh mesh = sabo::geometry::triangulate(shape, "channel");
      EXPECT_NO_THROW(mesh.validate("chute"));
      const double expected = 8 * 2 + 2 * 8 * 1 + 2 * end_wall;
      std::cout << "chute (end wall " << end_wall << ", element size " << element_size << "): area measured "
                << total_area(mesh) << " expected " << expected << ", " << mesh.face_count() << " faces\n";
      EXPECT_NEAR(total_area(mesh), expected, 1e-10);
      EXPECT_EQ(duplicate_positions(mesh, 1e-9), 0u);
      // Conforming: no edge is used by more than two faces, and edges used
      // once lie on the open rim (top of walls, upper end, or floor ends).
      for (const auto& [edge, count] : edge_use(mesh)) ASSERT_LE(count, 2);
      if (element_size > 0) {
        EXPECT_LE(longest_edge(mesh), element_size * std::sqrt(2.0) * (1 + 1e-12));
      }

      // Normals point into the channel: toward the middle of the cross
      // section, above the floor and upstream of the end wall.
      const auto frame = sabo::geometry::chute_frame(shape);
      const double slope = 30 * std::numbers::pi / 180;
      EXPECT_NEAR(frame.normal.dot(Vec3(0, std::sin(slope), std::cos(slope))), 1.0, 1e-12);
      for (std::size_t f = 0; f < mesh.face_count(); ++f) {
        const double along = (centroid(mesh, f) - shape.origin).dot(frame.down_slope);
        const Vec3 inside = shape.origin + std::clamp(along, 0.5, 7.5) * frame.down_slope + 0.5 * frame.normal;
        EXPECT_GT((inside - centroid(mesh, f)).dot(mesh.face_normal(f)), 0) << "face " << f;
      }
    }
  }
}

TEST(Primitives, ChuteWallsShareNodesWithTheFloor) {
  // Side walls 1 m, end wall 0.6 m, element size 0.35: the walls' nodes along
  // their common edge must coincide, so no edge is used by three faces and no
  // T-junction leaves an edge used once inside the surface.
  const Shape shape = chute_shape(0.35, 0.6);
  const SurfaceMesh mesh = sabo::geometry::triangulate(shape, "channel");
  const auto frame = sabo::geometry::chute_frame(shape);
  int open_inside = 0;
  for (const auto& [edge, count] : edge_use(mesh)) {
    if (count != 1) continue;
    const Vec3 middle = 0.5 * (mesh.node_position[edge.first] + mesh.node_position[edge.second]) - shape.origin;
    const double along = middle.dot(frame.down_slope);
    const double up = middle.dot(frame.normal);
    const double lateral = std::abs(middle.dot(frame.lateral));
    const bool on_rim = std::abs(along) < 1e-9 ||                                               // upper end
                        (std::abs(up - 1.0) < 1e-9 && lateral > 1 - 1e-9) ||                    // side wall tops
                        (std::abs(up - 0.6) < 1e-9 && std::abs(along - 8) < 1e-9) ||            // end wall top
                        (std::abs(along - 8) < 1e-9 && lateral > 1 - 1e-9 && up > 0.6 - 1e-9);  // side walls' ends
                                                                                                // above the end wall
    if (!on_rim) ++open_inside;
  }
  EXPECT_EQ(open_inside, 0);
}

// A profile with a steep piece, a flat piece and a gentle one along -x (lateral: -y), walls of three heights.
Shape channel_shape(double element_size) {
  Shape shape;
  shape.type = Shape::Type::channel;
  shape.origin = Vec3(3, 1, -50);  // its z is ignored
  shape.direction = Vec3(-1, 0, 0);
  shape.profile = {{0, 10}, {4, 7}, {6, 7}, {10, 6}};
  shape.width = 2;
  shape.wall_height = 1.5;
  shape.start_wall_height = 2;
  shape.end_wall_height = 1;
  shape.element_size = element_size;
  return shape;
}

// The bed's elevation at distance s of the channel_shape's profile.
double channel_bed(const Shape& shape, double s) {
  const auto& p = shape.profile;
  for (std::size_t k = 0; k + 1 < p.size(); ++k) {
    if (s <= p[k + 1][0]) return p[k][1] + (p[k + 1][1] - p[k][1]) * (s - p[k][0]) / (p[k + 1][0] - p[k][0]);
  }
  return p.back()[1];
}

TEST(Primitives, ChannelFollowsItsProfileWithInwardNormals) {
  for (double element_size : {0.0, 0.4}) {
    const Shape shape = channel_shape(element_size);
    const SurfaceMesh mesh = sabo::geometry::triangulate(shape, "gully");
    EXPECT_NO_THROW(mesh.validate("channel"));
    // The floor: the width times the profile's length; each side wall a parallelogram of the piece's
    // horizontal run times the wall's height; the end walls.
    const double profile_length = 5 + 2 + std::sqrt(17.0);
    const double expected = 2 * profile_length + 2 * 1.5 * 10 + 2 * 2 + 2 * 1;
    std::cout << "channel (element size " << element_size << "): area measured " << total_area(mesh) << " expected "
              << expected << ", " << mesh.face_count() << " faces\n";
    EXPECT_NEAR(total_area(mesh), expected, 1e-10);
    EXPECT_EQ(duplicate_positions(mesh, 1e-9), 0u);
    if (element_size > 0) {
      EXPECT_LE(longest_edge(mesh), 2 * element_size);
    }
    const Vec3 downstream(-1, 0, 0), lateral(0, -1, 0);
    int open_inside = 0;
    for (const auto& [edge, count] : edge_use(mesh)) {
      ASSERT_LE(count, 2);
      if (count != 1) continue;
      // Edges used once lie on the rim: the walls' tops, and the side walls' ends above the lower end wall.
      const Vec3 middle = 0.5 * (mesh.node_position[edge.first] + mesh.node_position[edge.second]);
      const double s = (middle - shape.origin).dot(downstream);
      const double up = middle.z() - channel_bed(shape, s);
      const bool side = std::abs(std::abs((middle - shape.origin).dot(lateral)) - 1) < 1e-9;
      const bool on_rim = (side && std::abs(up - 1.5) < 1e-9) || (std::abs(s) < 1e-9 && std::abs(up - 2) < 1e-9) ||
                          (std::abs(s - 10) < 1e-9 && std::abs(up - 1) < 1e-9) ||
                          (side && std::abs(s) < 1e-9 && up > 1.5 - 1e-9) ||
                          (side && std::abs(s - 10) < 1e-9 && up > 1 - 1e-9);
      if (!on_rim) ++open_inside;
    }
    EXPECT_EQ(open_inside, 0) << "edges used once inside the surface (T-junctions or gaps)";
    // Every face looks into the channel: toward a point of the centre line half a metre above the bed.
    for (std::size_t f = 0; f < mesh.face_count(); ++f) {
      const Vec3 c = centroid(mesh, f);
      const double s = std::clamp((c - shape.origin).dot(downstream), 0.1, 9.9);
      const Vec3 inside =
          Vec3(shape.origin.x(), shape.origin.y(), 0) + s * downstream + (channel_bed(shape, s) + 0.5) * Vec3::UnitZ();
      EXPECT_GT((inside - c).dot(mesh.face_normal(f)), 0) << "face " << f;
    }
    // Every point of the profile is a row of nodes across the floor.
    for (const auto& [s, z] : shape.profile) {
      const Vec3 centre = Vec3(3, 1, 0) + s * downstream + z * Vec3::UnitZ();
      int on_row = 0;
      for (const Vec3& x : mesh.node_position) {
        if (std::abs((x - centre).dot(downstream)) < 1e-9 && std::abs(x.z() - z) < 1e-9) ++on_row;
      }
      EXPECT_GE(on_row, 2) << "profile point " << s;
    }
  }
}

TEST(Primitives, ChannelRefusesAProfileThatIsNotMonotone) {
  Shape shape = channel_shape(0);
  shape.profile = {{0, 10}, {4, 7}, {4, 6}};
  const sabo::scene::Origin origin{"/scenes/w.toml", 30, "structures[2]"};
  try {
    (void)sabo::geometry::triangulate(shape, "gully", origin);
    ADD_FAILURE() << "no exception";
  } catch (const sabo::SceneError& error) {
    const std::string text = error.what();
    EXPECT_NE(text.find("/scenes/w.toml:30"), std::string::npos) << text;
    EXPECT_NE(text.find("distance 4 at point 2 after 4"), std::string::npos) << text;
  }
  shape.profile = {{0, 10}};
  EXPECT_THROW((void)sabo::geometry::triangulate(shape, "gully"), sabo::SceneError);
}

TEST(Primitives, AChannelWithoutItsFloorIsItsWalls) {
  Shape walls = channel_shape(0.4);
  walls.floor = false;
  const SurfaceMesh mesh = sabo::geometry::triangulate(walls, "walls");
  const double expected = 2 * 1.5 * 10 + 2 * 2 + 2 * 1;  // side walls and end walls, no floor
  std::cout << "channel walls: area measured " << total_area(mesh) << " expected " << expected << "\n";
  EXPECT_NEAR(total_area(mesh), expected, 1e-10);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) EXPECT_NEAR(mesh.face_normal(f).z(), 0.0, 1e-12);
  walls.wall_height = walls.start_wall_height = walls.end_wall_height = 0;
  EXPECT_THROW((void)sabo::geometry::triangulate(walls, "walls"), sabo::SceneError);
}

TEST(Primitives, RejectsImpossibleShapes) {
  Shape shape = chute_shape(0, 0);
  shape.slope_deg = 95;
  sabo::scene::Origin origin{"/scenes/a.toml", 12, "structures[0].shape"};
  try {
    (void)sabo::geometry::triangulate(shape, "channel", origin);
    ADD_FAILURE() << "no exception";
  } catch (const sabo::SceneError& error) {
    const std::string text = error.what();
    EXPECT_NE(text.find("/scenes/a.toml:12"), std::string::npos) << text;
    EXPECT_NE(text.find("Fix:"), std::string::npos) << text;
  }
  Shape flat;
  flat.type = Shape::Type::box;
  flat.box.min = Vec3(0, 0, 0);
  flat.box.max = Vec3(1, 1, 0);
  EXPECT_THROW((void)sabo::geometry::triangulate(flat, "b"), sabo::SceneError);
  Shape plane;
  plane.length = 1;
  plane.width = 1;
  plane.direction = Vec3(0, 0, 1);  // parallel to the default normal
  EXPECT_THROW((void)sabo::geometry::triangulate(plane, "p"), sabo::SceneError);
}

namespace {

// An ESRI ASCII grid of z = 50 + 0.2 x - 0.1 y at its cell centres, 30 x 20 cells of 2 m from (0, 0).
std::filesystem::path incline_grid() {
  const auto path = sabo::testing::scratch("terrain_plane.asc");
  std::ofstream out(path);
  out << "ncols 30\nnrows 20\nxllcorner 0\nyllcorner 0\ncellsize 2\nNODATA_value -9999\n";
  for (int r = 0; r < 20; ++r) {
    for (int c = 0; c < 30; ++c) out << 50.0 + 0.2 * (2 * c + 1) - 0.1 * (40 - 2 * r - 1) << (c < 29 ? " " : "\n");
  }
  return path;
}

Shape terrain_shape() {
  Shape shape;
  shape.type = Shape::Type::terrain;
  shape.file = incline_grid();
  shape.translate = Vec3(-10.0, -20.0, -50.0);
  return shape;
}

double projected_area(const SurfaceMesh& mesh) {
  double area = 0;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) area += mesh.face_area(f) * mesh.face_normal(f).z();
  return area;
}

// Distance in (x, y) from p to the polyline.
double distance_to_polyline(const std::vector<std::array<double, 2>>& line, double x, double y) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 1 < line.size(); ++k) {
    const Eigen::Vector2d a(line[k][0], line[k][1]), b(line[k + 1][0], line[k + 1][1]), p(x, y);
    const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + t * (b - a))).norm());
  }
  return best;
}

}  // namespace

TEST(Primitives, TerrainStripFollowsItsPolylineOnTheRastersGround) {
  Shape shape = terrain_shape();
  shape.strip = {{4.0, 10.0}, {30.0, 10.0}, {50.0, 30.0}};  // a 45 degree bend
  shape.strip_width = 6.0;
  shape.element_size = 1.5;
  const SurfaceMesh mesh = sabo::geometry::triangulate(shape, "gully");
  EXPECT_NO_THROW(mesh.validate("gully"));
  EXPECT_EQ(duplicate_positions(mesh, 1e-9), 0u);
  for (const auto& [edge, count] : edge_use(mesh)) ASSERT_LE(count, 2);
  double worst_z = 0, widest = 0;
  for (const Vec3& p : mesh.node_position) {
    const double x = p.x() + 10.0, y = p.y() + 20.0;  // back in the raster's coordinates
    worst_z = std::max(worst_z, std::abs(p.z() + 50.0 - (50.0 + 0.2 * x - 0.1 * y)));
    widest = std::max(widest, distance_to_polyline(shape.strip, x, y));
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) ASSERT_GT(mesh.face_normal(f).z(), 0.9) << "face " << f;
  // A mitred strip covers its width times its centre line's length.
  const double length = 26.0 + std::hypot(20.0, 20.0);
  std::cout << "terrain strip: projected area " << projected_area(mesh) << " m^2, expected " << 6.0 * length
            << "; largest elevation error " << worst_z << " m; farthest node " << widest
            << " m from the centre line (half width 3, 3.247 at the bend's outer corner)\n";
  EXPECT_NEAR(projected_area(mesh), 6.0 * length, 1e-6 * 6.0 * length);
  EXPECT_LT(worst_z, 1e-5);  // the raster holds floats
  // The outer corner of the mitre at the bend is the farthest: half the width over cos(22.5 degrees).
  EXPECT_NEAR(widest, 3.0 / std::cos(std::numbers::pi / 8), 1e-9);
  EXPECT_LE(longest_edge(mesh), 2 * 1.5);
}

TEST(Primitives, TerrainClippedToAPolygonOrWhole) {
  Shape shape = terrain_shape();
  shape.element_size = 1.0;
  const SurfaceMesh whole = sabo::geometry::triangulate(shape, "valley");
  std::cout << "whole terrain: projected area " << projected_area(whole) << " m^2, expected " << 58.0 * 38.0 << "\n";
  EXPECT_NEAR(projected_area(whole), 58.0 * 38.0, 1e-6);  // the cell centres' extent

  shape.clip_polygon = {{10.0, 5.0}, {40.0, 8.0}, {25.0, 30.0}};
  const SurfaceMesh clipped = sabo::geometry::triangulate(shape, "valley");
  const double polygon = sabo::geometry::polygon_area(shape.clip_polygon);
  std::cout << "clipped terrain: projected area " << projected_area(clipped) << " m^2 of the polygon's " << polygon
            << "\n";
  for (const Vec3& p : clipped.node_position) {
    ASSERT_TRUE(sabo::geometry::polygon_contains(shape.clip_polygon, p.x() + 10.0, p.y() + 20.0)) << p.transpose();
  }
  EXPECT_LT(projected_area(clipped), polygon);
  EXPECT_GT(projected_area(clipped), 0.8 * polygon);  // the staircase along its edges loses less than 20 %
}

TEST(Primitives, TerrainOutsideItsRasterIsRefusedNamingThePoint) {
  Shape shape = terrain_shape();
  shape.strip = {{4.0, 10.0}, {70.0, 10.0}};  // the raster's centres end at x = 59
  shape.strip_width = 4.0;
  try {
    (void)sabo::geometry::triangulate(shape, "gully");
    FAIL() << "a strip beyond its raster was built";
  } catch (const sabo::SceneError& error) {
    const std::string message = error.what();
    std::cout << message << "\n";
    EXPECT_NE(message.find("outside the cell centres"), std::string::npos);
    EXPECT_NE(message.find("structure 'gully'"), std::string::npos);
    EXPECT_NE(message.find("Fix:"), std::string::npos);
  }
  shape.strip = {{4.0, 10.0}, {30.0, 10.0}, {5.0, 11.0}};  // turns back on itself
  EXPECT_THROW((void)sabo::geometry::triangulate(shape, "gully"), sabo::SceneError);
}
