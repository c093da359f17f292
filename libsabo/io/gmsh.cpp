#include "libsabo/io/gmsh.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_map>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/hexahedron.hpp"

namespace sabo::io {
namespace {

// The fewest bytes a node ("1\n" and "0 0 0\n"), an element or a block ("1 1\n") takes: a count above the
// file's size over this cannot be held by the file, whatever its header says.
constexpr std::size_t kShortestNode = 8;
constexpr std::size_t kShortestEntry = 4;

class LineReader {
 public:
  explicit LineReader(const std::filesystem::path& file) : file_(file), in_(file, std::ios::binary) {
    if (!in_) {
      throw FileError(fmt::format("{}: cannot open the Gmsh mesh file: {}. Fix: check the mesh path in the scene",
                                  file.string(), std::strerror(errno)));
    }
    std::error_code ec;
    size_ = std::filesystem::file_size(file, ec);
    if (ec) size_ = 0;
  }
  // The next line; throws at the end of the file, naming what was expected.
  std::string next(const char* expected) {
    std::string line;
    if (!next_if_any(line)) {
      fail(fmt::format("the file ends where {} was expected", expected),
           "the file is truncated: export the mesh again");
    }
    return line;
  }
  bool next_if_any(std::string& line) {
    if (!std::getline(in_, line)) return false;
    ++line_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  [[nodiscard]] std::uintmax_t size() const { return size_; }
  [[noreturn]] void fail(const std::string& problem, const std::string& fix) const {
    throw FileError(fmt::format("{}:{}: {}. Fix: {}", file_.string(), line_, problem, fix));
  }
  // Exactly `count` numbers of a line (0: any number of them); doubles must be finite.
  template <class T>
  std::vector<T> numbers(const std::string& line, std::size_t count, const char* what) const {
    std::vector<T> values;
    const char* at = line.data();
    const char* end = line.data() + line.size();
    while (true) {
      while (at < end && (*at == ' ' || *at == '\t')) ++at;
      if (at == end) break;
      T value{};
      const auto [stop, error] = std::from_chars(at, end, value);
      if (error != std::errc() || (stop != end && *stop != ' ' && *stop != '\t')) {
        fail(fmt::format("expected {} ({} numbers), read '{}'", what, count, shortened(line)),
             "repair or export the mesh again in Gmsh's msh 4.1 ASCII format");
      }
      if constexpr (std::is_floating_point_v<T>) {
        if (!std::isfinite(value)) {
          fail(fmt::format("{}: '{}' is not a finite number", what, shortened(line)),
               "repair the mesh (a node has a non-finite coordinate) and export it again");
        }
      }
      values.push_back(value);
      at = stop;
    }
    if (count != 0 && values.size() != count) {
      fail(fmt::format("expected {} ({} numbers), read '{}'", what, count, shortened(line)),
           "repair or export the mesh again in Gmsh's msh 4.1 ASCII format");
    }
    return values;
  }
  // A declared count of entries that the rest of the file cannot hold is refused before anything is sized by it.
  void check_count(std::size_t count, const char* what, std::size_t shortest = kShortestEntry) const {
    if (count > size_ / shortest) {
      fail(fmt::format("the header declares {} {}, more than a file of {} bytes can hold", count, what, size_),
           "the file is truncated or its header is corrupt: export the mesh again");
    }
  }

 private:
  static std::string shortened(const std::string& line) { return excerpt(line, 60); }

  std::filesystem::path file_;
  std::ifstream in_;
  std::uintmax_t size_ = 0;
  int line_ = 0;
};

double quad_area(const std::vector<Vec3>& nodes, const std::array<std::uint32_t, 4>& q) {
  const Vec3& a = nodes[q[0]];
  const Vec3& b = nodes[q[1]];
  const Vec3& c = nodes[q[2]];
  const Vec3& d = nodes[q[3]];
  return 0.5 * ((b - a).cross(c - a).norm() + (c - a).cross(d - a).norm());
}

}  // namespace

GmshMesh read_gmsh(const std::filesystem::path& file) {
  LineReader reader(file);
  if (reader.size() == 0) {
    throw FileError(
        fmt::format("{}: not a Gmsh mesh: the file is empty (0 bytes). Fix: export the mesh from Gmsh as "
                    "msh 4.1 ASCII",
                    file.string()));
  }
  GmshMesh mesh;
  std::unordered_map<std::size_t, std::uint32_t> node_index;  // tag -> index
  std::vector<Vec3> nodes;
  bool format_seen = false, nodes_seen = false, elements_seen = false;
  std::string line;
  while (reader.next_if_any(line)) {
    if (line == "$MeshFormat") {
      const std::string header = reader.next("the format line");
      const auto values = reader.numbers<double>(header, 3, "the format line: version, file type, data size");
      if (values[0] < 4.0 || values[0] >= 5.0) {
        reader.fail(fmt::format("Gmsh format '{}' is not version 4", excerpt(header)),
                    "export with Gmsh's msh 4.1 format (File > Export, 'Version 4 ASCII')");
      }
      if (values[1] != 0) reader.fail("the mesh is binary", "export it as ASCII (Gmsh: -format msh41, without -bin)");
      if (reader.next("$EndMeshFormat") != "$EndMeshFormat") reader.fail("expected $EndMeshFormat", "repair the file");
      format_seen = true;
    } else if (line == "$Nodes") {
      if (!format_seen) reader.fail("$Nodes before $MeshFormat", "the file must start with $MeshFormat");
      const auto head = reader.numbers<std::size_t>(reader.next("the $Nodes header"), 4, "the $Nodes header");
      reader.check_count(head[0], "node blocks");
      reader.check_count(head[1], "nodes", kShortestNode);
      nodes.reserve(head[1]);
      std::vector<std::size_t> tags;
      for (std::size_t block = 0; block < head[0]; ++block) {
        const auto entity = reader.numbers<std::size_t>(reader.next("a node block header"), 4, "a node block header");
        if (entity[2] != 0) reader.fail("parametric nodes", "export without parametric coordinates");
        reader.check_count(entity[3], "nodes in a block", kShortestNode);
        tags.clear();
        for (std::size_t k = 0; k < entity[3]; ++k) {
          tags.push_back(reader.numbers<std::size_t>(reader.next("a node tag"), 1, "a node tag")[0]);
        }
        for (std::size_t k = 0; k < entity[3]; ++k) {
          const auto xyz = reader.numbers<double>(reader.next("node coordinates"), 3, "node coordinates x y z");
          if (nodes.size() >= std::numeric_limits<std::uint32_t>::max()) {
            reader.fail("more than 2^32 - 1 nodes", "split the structure into several meshes");
          }
          if (!node_index.emplace(tags[k], static_cast<std::uint32_t>(nodes.size())).second) {
            reader.fail(fmt::format("node tag {} appears twice", tags[k]), "renumber the nodes in Gmsh");
          }
          nodes.emplace_back(xyz[0], xyz[1], xyz[2]);
        }
      }
      if (reader.next("$EndNodes") != "$EndNodes") {
        reader.fail("expected $EndNodes (the node count of the header does not match the blocks)",
                    "export the mesh again");
      }
      nodes_seen = true;
    } else if (line == "$Elements") {
      if (!nodes_seen) reader.fail("$Elements before $Nodes", "export the mesh again");
      const auto head = reader.numbers<std::size_t>(reader.next("the $Elements header"), 4, "the $Elements header");
      reader.check_count(head[0], "element blocks");
      reader.check_count(head[1], "elements");
      for (std::size_t block = 0; block < head[0]; ++block) {
        const auto entity =
            reader.numbers<std::size_t>(reader.next("an element block header"), 4, "an element block header");
        const std::size_t type = entity[2];
        std::size_t node_count = 0;
        switch (type) {
          case 5: node_count = 8; break;
          case 3: node_count = 4; break;
          case 15: node_count = 1; break;
          case 1: node_count = 2; break;
          default:
            reader.fail(fmt::format("element type {} is not supported", type),
                        "mesh volumes with 8-node hexahedra (type 5; Gmsh: Recombine and transfinite volumes) "
                        "and shells with 4-node quadrangles (type 3)");
        }
        reader.check_count(entity[3], "elements in a block");
        for (std::size_t k = 0; k < entity[3]; ++k) {
          const auto values =
              reader.numbers<std::size_t>(reader.next("an element"), node_count + 1, "an element: tag and nodes");
          if (type == 15 || type == 1) continue;
          std::array<std::uint32_t, 8> element{};
          for (std::size_t a = 0; a < node_count; ++a) {
            const auto it = node_index.find(values[a + 1]);
            if (it == node_index.end()) {
              reader.fail(
                  fmt::format("element {} uses node tag {}, which $Nodes does not define", values[0], values[a + 1]),
                  "export the mesh again with all its nodes");
            }
            element[a] = it->second;
          }
          if (type == 5) {
            std::array<Vec3, 8> x;
            for (std::size_t a = 0; a < 8; ++a) x[a] = nodes[element[a]];
            const double volume = geometry::hexahedron_volume(x);
            if (!(volume > 0)) {
              reader.fail(fmt::format("hexahedron {} is inverted or flat (volume {:.3g} m^3)", values[0], volume),
                          "fix the element's node order (Gmsh's: bottom face counter-clockwise seen from above, "
                          "then the top face)");
            }
            mesh.hexahedra.push_back(element);
          } else {
            const std::array<std::uint32_t, 4> quad{element[0], element[1], element[2], element[3]};
            const double area = quad_area(nodes, quad);
            if (!(area > 0)) {
              reader.fail(fmt::format("quadrangle {} has zero area (its corners are on one line)", values[0]),
                          "remove the degenerate element or mesh the surface again");
            }
            mesh.quads.push_back(quad);
          }
        }
      }
      if (reader.next("$EndElements") != "$EndElements") {
        reader.fail("expected $EndElements (the element count does not match the blocks)", "export the mesh again");
      }
      elements_seen = true;
    }
  }
  if (!format_seen || !nodes_seen || !elements_seen) {
    reader.fail("missing $MeshFormat, $Nodes or $Elements: not a Gmsh mesh, or a truncated one",
                "give a complete Gmsh msh 4.1 ASCII file");
  }
  if (mesh.hexahedra.empty() && mesh.quads.empty()) {
    reader.fail("no hexahedra (type 5) or quadrangles (type 3)", "mesh the structure with hexahedra or quadrangles");
  }
  // Keep only the nodes the elements use, in file order.
  std::vector<std::uint32_t> renumber(nodes.size(), std::numeric_limits<std::uint32_t>::max());
  std::vector<char> used(nodes.size(), 0);
  for (const auto& e : mesh.hexahedra) {
    for (auto n : e) used[n] = 1;
  }
  for (const auto& q : mesh.quads) {
    for (auto n : q) used[n] = 1;
  }
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (used[i] == 0) continue;
    renumber[i] = static_cast<std::uint32_t>(mesh.node.size());
    mesh.node.push_back(nodes[i]);
  }
  for (auto& e : mesh.hexahedra) {
    for (auto& n : e) n = renumber[n];
  }
  for (auto& q : mesh.quads) {
    for (auto& n : q) n = renumber[n];
  }
  return mesh;
}

}  // namespace sabo::io
