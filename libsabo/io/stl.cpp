#include "libsabo/io/stl.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/node_welder.hpp"

namespace sabo::io {
namespace {

using Triangle = std::array<Vec3, 3>;

constexpr std::size_t kHeaderBytes = 84;    // 80-byte header and a uint32 triangle count
constexpr std::size_t kTriangleBytes = 50;  // normal, three corners (12 float32) and a uint16

std::string read_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw FileError(fmt::format("{}: cannot open the STL file: {}. Fix: check the mesh path in the scene",
                                file.string(), std::strerror(errno)));
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return std::move(buffer).str();
}

bool starts_with_solid(const std::string& data) {
  std::size_t i = 0;
  while (i < data.size() && std::isspace(static_cast<unsigned char>(data[i]))) ++i;
  if (data.size() - i < 5) return false;
  for (std::size_t k = 0; k < 5; ++k) {
    if (std::tolower(static_cast<unsigned char>(data[i + k])) != "solid"[k]) return false;
  }
  return true;
}

// Text holds no control characters other than white space; binary floats
// almost always do.
bool looks_like_text(const std::string& data) {
  return std::none_of(data.begin(), data.end(), [](char c) {
    const auto byte = static_cast<unsigned char>(c);
    return byte < 32 && byte != '\n' && byte != '\r' && byte != '\t' && byte != '\f' && byte != '\v';
  });
}

std::vector<Triangle> parse_binary(const std::filesystem::path& file, const std::string& data, std::uint32_t count) {
  std::vector<Triangle> triangles(count);
  for (std::uint32_t t = 0; t < count; ++t) {
    const char* record = data.data() + kHeaderBytes + std::size_t{t} * kTriangleBytes;
    for (int corner = 0; corner < 3; ++corner) {
      std::array<float, 3> xyz{};
      std::memcpy(xyz.data(), record + 12 * (corner + 1), sizeof xyz);
      triangles[t][corner] = Vec3(xyz[0], xyz[1], xyz[2]);
      if (!triangles[t][corner].allFinite()) {
        throw FileError(
            fmt::format("{}: binary STL triangle {} (of {}) corner {} has a non-finite coordinate "
                        "({}, {}, {}). Fix: repair the mesh and export it again",
                        file.string(), t, count, corner, xyz[0], xyz[1], xyz[2]));
      }
    }
  }
  return triangles;
}

// Tokens of an ASCII STL with their line numbers.
class Tokens {
 public:
  Tokens(const std::filesystem::path& file, const std::string& data) : file_(file), data_(data) {}

  // The next token, or an empty view at the end of the file.
  std::string_view next() {
    skip_space();
    const std::size_t begin = at_;
    while (at_ < data_.size() && !std::isspace(static_cast<unsigned char>(data_[at_]))) ++at_;
    return std::string_view(data_).substr(begin, at_ - begin);
  }
  bool at_end() {
    skip_space();
    return at_ >= data_.size();
  }
  void skip_line() {
    while (at_ < data_.size() && data_[at_] != '\n') ++at_;
  }
  [[nodiscard]] int line() const { return line_; }

  void expect(const char* keyword, const char* context) {
    const std::string_view token = next();
    if (!equal_ignoring_case(token, keyword)) fail_expected(fmt::format("'{}'", keyword), token, context);
  }

  double number(const char* what, bool must_be_finite) {
    const std::string_view token = next();
    double value = 0;
    const char* begin = token.data();
    const char* end = token.data() + token.size();
    if (!token.empty() && *begin == '+') ++begin;  // from_chars does not take a leading '+'
    const auto [stop, error] = std::from_chars(begin, end, value);
    if (token.empty() || error != std::errc() || stop != end)
      fail_expected(fmt::format("a number ({})", what), token, "");
    if (must_be_finite && !std::isfinite(value)) {
      throw FileError(fmt::format("{}:{}: {} is '{}', not a finite number. Fix: repair the mesh and export it again",
                                  file_.string(), line_, what, excerpt(token, 40)));
    }
    return value;
  }

  [[noreturn]] void fail_expected(const std::string& expected, std::string_view found, const char* context) const {
    const std::string found_text =
        found.empty() ? std::string("the end of the file") : fmt::format("'{}'", excerpt(found, 40));
    throw FileError(fmt::format("{}:{}: ASCII STL: expected {}{} but found {}. Fix: {}", file_.string(), line_,
                                expected, context, found_text,
                                found.empty() ? "the file is truncated: export it again"
                                              : "check the file is a valid STL (solid / facet normal / outer loop / "
                                                "vertex x y z ×3 / endloop / endfacet / endsolid)"));
  }

  static bool equal_ignoring_case(std::string_view a, std::string_view b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
             return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
           });
  }

 private:
  void skip_space() {
    while (at_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[at_]))) {
      if (data_[at_] == '\n') ++line_;
      ++at_;
    }
  }

  const std::filesystem::path& file_;
  const std::string& data_;
  std::size_t at_ = 0;
  int line_ = 1;
};

std::vector<Triangle> parse_ascii(const std::filesystem::path& file, const std::string& data) {
  std::vector<Triangle> triangles;
  Tokens tokens(file, data);
  tokens.expect("solid", " at the start of an ASCII STL");
  tokens.skip_line();  // the solid's name
  while (true) {
    const int line = tokens.line();
    const std::string_view keyword = tokens.next();
    if (Tokens::equal_ignoring_case(keyword, "endsolid")) {
      tokens.skip_line();
      if (tokens.at_end()) break;
      tokens.expect("solid", " after 'endsolid' (another solid) or the end of the file");
      tokens.skip_line();
      continue;
    }
    if (!Tokens::equal_ignoring_case(keyword, "facet")) {
      tokens.fail_expected("'facet' or 'endsolid'", keyword,
                           fmt::format(" (after {} triangles, line {})", triangles.size(), line).c_str());
    }
    tokens.expect("normal", " after 'facet'");
    for (int i = 0; i < 3; ++i) (void)tokens.number("a normal component", false);  // the corners decide
    tokens.expect("outer", " after the facet normal");
    tokens.expect("loop", " after 'outer'");
    Triangle triangle;
    for (int corner = 0; corner < 3; ++corner) {
      tokens.expect("vertex", corner == 0 ? " after 'outer loop'" : " (a facet has three vertices)");
      for (int axis = 0; axis < 3; ++axis) triangle[corner][axis] = tokens.number("a vertex coordinate", true);
    }
    tokens.expect("endloop", " after three vertices");
    tokens.expect("endfacet", " after 'endloop'");
    triangles.push_back(triangle);
  }
  return triangles;
}

}  // namespace

StlMesh read_stl(const std::filesystem::path& file, const StlOptions& options) {
  const std::string data = read_file(file);
  StlMesh result;
  std::vector<Triangle> triangles;
  const bool solid = starts_with_solid(data);
  std::uint32_t declared = 0;
  if (data.size() >= kHeaderBytes) std::memcpy(&declared, data.data() + 80, sizeof declared);
  const bool binary_size_matches =
      data.size() >= kHeaderBytes && data.size() == kHeaderBytes + std::size_t{declared} * kTriangleBytes;
  // Binary files may start with "solid" too: the size decides, then the content.
  if (binary_size_matches && !(solid && looks_like_text(data))) {
    result.binary = true;
    triangles = parse_binary(file, data, declared);
  } else if (solid) {
    triangles = parse_ascii(file, data);
  } else if (!data.empty() && looks_like_text(data)) {
    throw FileError(
        fmt::format("{}: not an STL file: {} bytes of text that does not start with 'solid' (an ASCII STL does; a "
                    "binary STL holds binary numbers). Fix: export the mesh as STL",
                    file.string(), data.size()));
  } else if (data.size() < kHeaderBytes) {
    throw FileError(
        fmt::format("{}: not an STL file: {} bytes, but a binary STL has at least 84 and an ASCII STL "
                    "starts with 'solid'. Fix: export the mesh as STL",
                    file.string(), data.size()));
  } else {
    throw FileError(fmt::format(
        "{}: binary STL declares {} triangles but the file holds {:g}: truncated file? "
        "({} bytes; 84 + 50 per triangle expected). Fix: export the mesh again",
        file.string(), declared, static_cast<double>(data.size() - kHeaderBytes) / kTriangleBytes, data.size()));
  }
  result.triangles_in_file = triangles.size();
  if (triangles.empty()) {
    throw FileError(fmt::format("{}: the STL file holds no triangles. Fix: export the mesh again", file.string()));
  }

  Aabb box;
  for (const auto& triangle : triangles) {
    for (const Vec3& corner : triangle) box.extend(corner);
  }
  geometry::NodeWelder welder(options.merge_tolerance * (box.max - box.min).norm());
  auto& mesh = result.mesh;
  for (const auto& triangle : triangles) {
    const std::array<std::uint32_t, 3> nodes{welder.add(triangle[0]), welder.add(triangle[1]), welder.add(triangle[2])};
    const auto& p = welder.positions();
    const bool collapsed = nodes[0] == nodes[1] || nodes[1] == nodes[2] || nodes[0] == nodes[2];
    if (collapsed || !((p[nodes[1]] - p[nodes[0]]).cross(p[nodes[2]] - p[nodes[0]]).norm() > 0)) {
      ++result.degenerate_dropped;
      continue;
    }
    mesh.triangle.push_back(nodes);
  }
  if (mesh.triangle.empty()) {
    throw FileError(fmt::format("{}: all {} triangles have zero area. Fix: export the mesh again", file.string(),
                                triangles.size()));
  }
  // Keep only nodes that a kept triangle uses, in their order.
  const std::vector<Vec3> welded = welder.take_positions();
  std::vector<std::uint32_t> renumber(welded.size(), UINT32_MAX);
  for (const auto& triangle : mesh.triangle) {
    for (std::uint32_t node : triangle) renumber[node] = 0;
  }
  for (std::size_t node = 0; node < welded.size(); ++node) {
    if (renumber[node] == 0) {
      renumber[node] = static_cast<std::uint32_t>(mesh.node_position.size());
      mesh.node_position.push_back(welded[node]);
    }
  }
  for (auto& triangle : mesh.triangle) {
    for (std::uint32_t& node : triangle) node = renumber[node];
  }
  mesh.make_single_part(file.stem().string());
  return result;
}

}  // namespace sabo::io
