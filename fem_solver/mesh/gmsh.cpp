#include "fem_solver/mesh/gmsh.hpp"

#include <fmt/format.h>

#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <unordered_map>

#include "fem_solver/elements/hex8.hpp"
#include "libsabo/core/error.hpp"

namespace sabo::fem {
namespace {

class LineReader {
 public:
  explicit LineReader(const std::filesystem::path& file) : file_(file), in_(file) {
    if (!in_) throw FileError(fmt::format("{}: cannot open the Gmsh mesh file", file.string()));
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
  [[noreturn]] void fail(const std::string& problem, const std::string& fix) const {
    throw SceneError(fmt::format("{}:{}: {}. Fix: {}", file_.string(), line_, problem, fix));
  }
  // Numbers of a line: exactly `count` of them (0: any number).
  template <class T>
  std::vector<T> numbers(const std::string& line, std::size_t count, const char* what) const {
    std::istringstream stream(line);
    std::vector<T> values;
    T value{};
    while (stream >> value) values.push_back(value);
    if (!stream.eof() || (count != 0 && values.size() != count)) {
      fail(fmt::format("expected {} ({} numbers), read '{}'", what, count, line),
           "repair or export the mesh again in Gmsh's msh 4.1 ASCII format");
    }
    return values;
  }

 private:
  std::filesystem::path file_;
  std::ifstream in_;
  int line_ = 0;
};

}  // namespace

GmshMesh read_gmsh(const std::filesystem::path& file) {
  LineReader reader(file);
  GmshMesh mesh;
  std::unordered_map<std::size_t, std::uint32_t> node_index;  // tag -> index
  std::vector<Vec3> nodes;
  bool format_seen = false, nodes_seen = false, elements_seen = false;
  std::string line;
  while (reader.next_if_any(line)) {
    if (line == "$MeshFormat") {
      const std::string header = reader.next("the format line");
      std::istringstream stream(header);
      double version = 0;
      int binary = -1, size = 0;
      stream >> version >> binary >> size;
      if (!stream || version < 4.0 || version >= 5.0) {
        reader.fail(fmt::format("Gmsh format '{}' is not version 4", header),
                    "export with Gmsh's msh 4.1 format (File > Export, 'Version 4 ASCII')");
      }
      if (binary != 0) reader.fail("the mesh is binary", "export it as ASCII (Gmsh: -format msh41, without -bin)");
      if (reader.next("$EndMeshFormat") != "$EndMeshFormat") reader.fail("expected $EndMeshFormat", "repair the file");
      format_seen = true;
    } else if (line == "$Nodes") {
      if (!format_seen) reader.fail("$Nodes before $MeshFormat", "the file must start with $MeshFormat");
      const auto head = reader.numbers<std::size_t>(reader.next("the $Nodes header"), 4, "the $Nodes header");
      nodes.reserve(head[1]);
      for (std::size_t block = 0; block < head[0]; ++block) {
        const auto entity = reader.numbers<std::size_t>(reader.next("a node block header"), 4, "a node block header");
        if (entity[2] != 0) reader.fail("parametric nodes", "export without parametric coordinates");
        std::vector<std::size_t> tags;
        for (std::size_t k = 0; k < entity[3]; ++k) {
          tags.push_back(reader.numbers<std::size_t>(reader.next("a node tag"), 1, "a node tag")[0]);
        }
        for (std::size_t k = 0; k < entity[3]; ++k) {
          const auto xyz = reader.numbers<double>(reader.next("node coordinates"), 3, "node coordinates x y z");
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
            HexNodes x;
            for (std::size_t a = 0; a < 8; ++a) x[a] = nodes[element[a]];
            if (!(hex8_volume(x) > 0)) {
              reader.fail(
                  fmt::format("hexahedron {} is inverted or flat (volume {:.3g} m^3)", values[0], hex8_volume(x)),
                  "fix the element's node order (Gmsh's: bottom face counter-clockwise seen from above, "
                  "then the top face)");
            }
            mesh.hexahedra.element.push_back(element);
          } else {
            mesh.quads.push_back({element[0], element[1], element[2], element[3]});
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
    reader.fail("missing $MeshFormat, $Nodes or $Elements", "give a complete Gmsh msh 4.1 ASCII file");
  }
  if (mesh.hexahedra.element.empty() && mesh.quads.empty()) {
    reader.fail("no hexahedra (type 5) or quadrangles (type 3)", "mesh the structure with hexahedra or quadrangles");
  }
  // Keep only the nodes the elements use, in file order.
  std::vector<std::uint32_t> renumber(nodes.size(), std::numeric_limits<std::uint32_t>::max());
  std::vector<char> used(nodes.size(), 0);
  for (const auto& e : mesh.hexahedra.element) {
    for (auto n : e) used[n] = 1;
  }
  for (const auto& q : mesh.quads) {
    for (auto n : q) used[n] = 1;
  }
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (used[i] == 0) continue;
    renumber[i] = static_cast<std::uint32_t>(mesh.hexahedra.node.size());
    mesh.hexahedra.node.push_back(nodes[i]);
  }
  for (auto& e : mesh.hexahedra.element) {
    for (auto& n : e) n = renumber[n];
  }
  for (auto& q : mesh.quads) {
    for (auto& n : q) n = renumber[n];
  }
  return mesh;
}

}  // namespace sabo::fem
