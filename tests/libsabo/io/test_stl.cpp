#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cstring>
#include <fstream>
#include <map>

#include "libsabo/core/error.hpp"
#include "libsabo/io/stl.hpp"
#include "tests/support/scratch.hpp"

namespace fs = std::filesystem;
using sabo::Vec3;

namespace {

using sabo::testing::scratch;

using Triangle = std::array<Vec3, 3>;

// The 12 triangles of the cube [0, size]^3, counter-clockwise seen from outside.
std::vector<Triangle> cube(double size) {
  std::vector<Triangle> triangles;
  auto corner = [size](int i, int j, int k) { return Vec3(i * size, j * size, k * size); };
  auto quad = [&](Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
    triangles.push_back({a, b, c});
    triangles.push_back({a, c, d});
  };
  quad(corner(0, 0, 0), corner(0, 1, 0), corner(1, 1, 0), corner(1, 0, 0));  // z = 0, normal -z
  quad(corner(0, 0, 1), corner(1, 0, 1), corner(1, 1, 1), corner(0, 1, 1));  // z = 1, +z
  quad(corner(0, 0, 0), corner(1, 0, 0), corner(1, 0, 1), corner(0, 0, 1));  // y = 0, -y
  quad(corner(0, 1, 0), corner(0, 1, 1), corner(1, 1, 1), corner(1, 1, 0));  // y = 1, +y
  quad(corner(0, 0, 0), corner(0, 0, 1), corner(0, 1, 1), corner(0, 1, 0));  // x = 0, -x
  quad(corner(1, 0, 0), corner(1, 1, 0), corner(1, 1, 1), corner(1, 0, 1));  // x = 1, +x
  return triangles;
}

std::string ascii_stl(const std::vector<Triangle>& triangles) {
  std::string text = "solid cube exported by the test\n";
  for (const auto& t : triangles) {
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
    text += "  facet normal " + std::to_string(n.x()) + " " + std::to_string(n.y()) + " " + std::to_string(n.z()) +
            "\n    outer loop\n";
    for (const auto& v : t) {
      char line[128];
      std::snprintf(line, sizeof line, "      vertex %.17g %.17g %.17g\n", v.x(), v.y(), v.z());
      text += line;
    }
    text += "    endloop\n  endfacet\n";
  }
  return text + "endsolid cube\n";
}

std::string binary_stl(const std::vector<Triangle>& triangles, const std::string& header) {
  std::string data(80, ' ');
  std::memcpy(data.data(), header.data(), std::min<std::size_t>(header.size(), 80));
  const auto count = static_cast<std::uint32_t>(triangles.size());
  data.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& t : triangles) {
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
    std::array<float, 12> values{};
    for (int k = 0; k < 3; ++k) values[k] = static_cast<float>(n[k]);
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) values[3 + 3 * c + k] = static_cast<float>(t[c][k]);
    }
    data.append(reinterpret_cast<const char*>(values.data()), sizeof values);
    data.append(2, '\0');
  }
  return data;
}

fs::path write(const std::string& name, const std::string& content) {
  const fs::path file = scratch(name);
  std::ofstream(file, std::ios::binary) << content;
  return file;
}

std::string error_of(const fs::path& file, const sabo::io::StlOptions& options = {}) {
  try {
    (void)sabo::io::read_stl(file, options);
  } catch (const sabo::FileError& error) {
    return error.what();
  }
  return "(no error)";
}

void expect_closed_unit_cube(const sabo::geometry::SurfaceMesh& mesh, double size) {
  EXPECT_EQ(mesh.node_count(), 8u);
  EXPECT_EQ(mesh.face_count(), 12u);
  EXPECT_NO_THROW(mesh.validate("cube"));
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (const auto& t : mesh.triangle) {
    for (int k = 0; k < 3; ++k) ++edges[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
  }
  for (const auto& [edge, count] : edges) EXPECT_EQ(count, 2);  // welded: every edge shared
  const Vec3 center = Vec3::Constant(size / 2);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto& t = mesh.triangle[f];
    const Vec3 c = (mesh.node_position[t[0]] + mesh.node_position[t[1]] + mesh.node_position[t[2]]) / 3;
    EXPECT_GT((c - center).dot(mesh.face_normal(f)), 0);
  }
}

}  // namespace

TEST(Stl, AsciiCube) {
  const auto result = sabo::io::read_stl(write("cube_ascii.stl", ascii_stl(cube(2.0))));
  EXPECT_FALSE(result.binary);
  EXPECT_EQ(result.triangles_in_file, 12u);
  EXPECT_EQ(result.degenerate_dropped, 0u);
  EXPECT_EQ(result.mesh.part_name, (std::vector<std::string>{"cube_ascii"}));
  expect_closed_unit_cube(result.mesh, 2.0);
}

TEST(Stl, BinaryCubeWhoseHeaderSaysSolid) {
  const auto result = sabo::io::read_stl(write("cube_binary.stl", binary_stl(cube(2.0), "solid cube (binary!)")));
  EXPECT_TRUE(result.binary);
  expect_closed_unit_cube(result.mesh, 2.0);
}

TEST(Stl, MergesWithinTheTolerance) {
  auto triangles = cube(1.0);
  triangles[1][2] += Vec3(1e-12, 0, 0);  // one corner a hair off: merged by default
  const fs::path file = write("nearly.stl", ascii_stl(triangles));
  EXPECT_EQ(sabo::io::read_stl(file).mesh.node_count(), 8u);
  EXPECT_EQ(sabo::io::read_stl(file, {.merge_tolerance = 0}).mesh.node_count(), 9u);
  // A triangle that collapses when its corners merge is dropped, with its unused node.
  triangles = cube(1.0);
  triangles.push_back({Vec3(0, 0, 0), Vec3(1e-13, 0, 0), Vec3(0, 1, 0)});
  const auto result = sabo::io::read_stl(write("sliver.stl", ascii_stl(triangles)));
  EXPECT_EQ(result.degenerate_dropped, 1u);
  EXPECT_EQ(result.mesh.face_count(), 12u);
  EXPECT_EQ(result.mesh.node_count(), 8u);
}

TEST(Stl, TruncatedBinary) {
  std::string data = binary_stl(cube(1.0), "binary");
  data.resize(84 + 50 * 7 + 25);  // seven and a half triangles
  const std::string text = error_of(write("truncated.stl", data));
  std::cout << text << "\n";
  EXPECT_NE(text.find("binary STL declares 12 triangles but the file holds 7.5: truncated file?"), std::string::npos);
  EXPECT_NE(text.find("truncated.stl"), std::string::npos);
}

TEST(Stl, TruncatedAscii) {
  std::string text = ascii_stl(cube(1.0));
  text.resize(text.find("vertex", text.size() / 2) + 10);
  const fs::path file = write("truncated_ascii.stl", text);
  const std::string message = error_of(file);
  std::cout << message << "\n";
  EXPECT_NE(message.find(file.string() + ":"), std::string::npos);  // names the line
  EXPECT_NE(message.find("the end of the file"), std::string::npos);
  // Complete facets but no endsolid: also a truncated file.
  text = ascii_stl(cube(1.0));
  text.resize(text.rfind("endsolid"));
  EXPECT_NE(error_of(write("no_endsolid.stl", text)).find("expected 'facet' or 'endsolid'"), std::string::npos);
}

TEST(Stl, GarbageAndBadNumbers) {
  EXPECT_NE(error_of(write("garbage.stl", "hello")).find("not an STL file: 5 bytes"), std::string::npos);
  std::string noise(300, '\x07');
  EXPECT_NE(error_of(write("noise.stl", noise)).find("binary STL declares"), std::string::npos);

  std::string text = ascii_stl(cube(1.0));
  const auto at = text.find("vertex", text.find("facet", 200));
  text.replace(at, 6, "vortex");
  const std::string typo = error_of(write("typo.stl", text));
  std::cout << typo << "\n";
  EXPECT_NE(typo.find("expected 'vertex'"), std::string::npos);
  EXPECT_NE(typo.find("found 'vortex'"), std::string::npos);

  text = ascii_stl(cube(1.0));
  const auto line_start = text.find("vertex", 300);
  text.replace(line_start, text.find('\n', line_start) - line_start, "vertex 1 nan 0");
  const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + line_start, '\n'));
  const std::string nan = error_of(write("nan.stl", text));
  std::cout << nan << "\n";
  EXPECT_NE(nan.find("nan.stl:" + std::to_string(line) + ": a vertex coordinate is 'nan'"), std::string::npos);

  auto triangles = cube(1.0);
  triangles[3][1].y() = std::numeric_limits<double>::infinity();
  EXPECT_NE(error_of(write("inf.stl", binary_stl(triangles, "x"))).find("binary STL triangle 3 (of 12) corner 1"),
            std::string::npos);

  EXPECT_NE(error_of(write("empty.stl", "solid empty\nendsolid empty\n")).find("holds no triangles"),
            std::string::npos);
  EXPECT_NE(error_of(scratch("missing.stl")).find("cannot open the STL file"), std::string::npos);
}
