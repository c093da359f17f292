#include "libsabo/io/gmsh_groups.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <unordered_map>
#include <utility>

#include "libsabo/core/error.hpp"

namespace sabo::io {
namespace {

class Lines {
 public:
  explicit Lines(const std::filesystem::path& file) : file_(file), in_(file) {
    if (!in_) throw FileError(fmt::format("{}: cannot open the Gmsh mesh file", file.string()));
  }
  bool next(std::string& line) {
    if (!std::getline(in_, line)) return false;
    ++line_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  std::string expect(const char* what) {
    std::string line;
    if (!next(line)) fail(fmt::format("the file ends where {} was expected", what), "export the mesh again");
    return line;
  }
  [[noreturn]] void fail(const std::string& problem, const std::string& fix) const {
    throw SceneError(fmt::format("{}:{}: {}. Fix: {}", file_.string(), line_, problem, fix));
  }
  template <class T>
  std::vector<T> numbers(const std::string& line, const char* what) const {
    std::istringstream stream(line);
    std::vector<T> values;
    T value{};
    while (stream >> value) values.push_back(value);
    if (!stream.eof() || values.empty()) {
      fail(fmt::format("expected {}, read '{}'", what, line), "export the mesh again in Gmsh's msh 4.1 ASCII format");
    }
    return values;
  }
  // The numbers of the next line, at least `count` of them.
  template <class T>
  std::vector<T> row(std::size_t count, const char* what) {
    const std::string line = expect(what);
    auto values = numbers<T>(line, what);
    if (values.size() < count) {
      fail(fmt::format("expected {} ({} numbers), read '{}'", what, count, line),
           "export the mesh again in Gmsh's msh 4.1 ASCII format");
    }
    return values;
  }

 private:
  std::filesystem::path file_;
  std::ifstream in_;
  int line_ = 0;
};

}  // namespace

const GmshGroup* GmshGroups::find(const std::string& name) const {
  for (const GmshGroup& g : group) {
    if (g.name == name) return &g;
  }
  return nullptr;
}

std::vector<std::string> GmshGroups::names() const {
  std::vector<std::string> out;
  for (const GmshGroup& g : group) out.push_back(g.name);
  return out;
}

GmshGroups read_gmsh_groups(const std::filesystem::path& file) {
  Lines lines(file);
  GmshGroups out;
  double version = 4.1;
  // (dimension, physical tag) -> group index; (dimension, entity tag) -> its physical tags.
  std::map<std::pair<int, int>, std::size_t> group_of;
  std::map<std::pair<int, int>, std::vector<int>> entity_physicals;
  std::unordered_map<std::size_t, std::uint32_t> node_index;
  std::vector<std::set<std::uint32_t>> members;
  std::string line;
  while (lines.next(line)) {
    if (line == "$MeshFormat") {
      std::istringstream header(lines.expect("the format line"));
      int binary = -1;
      header >> version >> binary;
      if (!header || version < 4.0 || version >= 5.0) {
        lines.fail("the Gmsh format is not version 4", "export with Gmsh's msh 4.1 format ('Version 4 ASCII')");
      }
      if (binary != 0) lines.fail("the mesh is binary", "export it as ASCII (Gmsh: -format msh41, without -bin)");
    } else if (line == "$PhysicalNames") {
      const auto count = lines.row<std::size_t>(1, "the number of physical names")[0];
      for (std::size_t k = 0; k < count; ++k) {
        const std::string entry = lines.expect("a physical name");
        std::istringstream stream(entry);
        int dimension = -1, tag = -1;
        const bool numbers_read = static_cast<bool>(stream >> dimension >> tag);
        std::string rest;
        std::getline(stream, rest);
        const auto open = rest.find('"'), close = rest.rfind('"');
        if (!numbers_read || dimension < 0 || dimension > 3 || open == std::string::npos || close <= open) {
          lines.fail(fmt::format("expected a physical name 'DIMENSION TAG \"NAME\"', read '{}'", entry),
                     "export the mesh again");
        }
        GmshGroup group;
        group.name = rest.substr(open + 1, close - open - 1);
        group.dimension = dimension;
        group.tag = tag;
        group_of[{dimension, tag}] = out.group.size();
        out.group.push_back(std::move(group));
      }
    } else if (line == "$Entities") {
      const auto head = lines.row<std::size_t>(4, "the $Entities header");
      for (int dimension = 0; dimension < 4; ++dimension) {
        // Points of version 4.1 give X Y Z; everything else a bounding box.
        const std::size_t coordinates = dimension == 0 && version >= 4.1 ? 3 : 6;
        for (std::size_t k = 0; k < head[static_cast<std::size_t>(dimension)]; ++k) {
          const auto values = lines.row<double>(coordinates + 2, "an entity");
          const auto physicals = static_cast<std::size_t>(values[coordinates + 1]);
          if (values.size() < coordinates + 2 + physicals) {
            lines.fail("an entity's physical tags are cut short", "export the mesh again");
          }
          std::vector<int>& tags = entity_physicals[{dimension, static_cast<int>(values[0])}];
          for (std::size_t p = 0; p < physicals; ++p) tags.push_back(static_cast<int>(values[coordinates + 2 + p]));
        }
      }
    } else if (line == "$Nodes") {
      const auto head = lines.row<std::size_t>(4, "the $Nodes header");
      for (std::size_t block = 0; block < head[0]; ++block) {
        const auto entity = lines.row<std::size_t>(4, "a node block header");
        if (entity[2] != 0) lines.fail("parametric nodes", "export without parametric coordinates");
        std::vector<std::size_t> tags;
        for (std::size_t k = 0; k < entity[3]; ++k) tags.push_back(lines.row<std::size_t>(1, "a node tag")[0]);
        for (std::size_t k = 0; k < entity[3]; ++k) {
          const auto xyz = lines.row<double>(3, "node coordinates x y z");
          node_index.emplace(tags[k], static_cast<std::uint32_t>(out.node.size()));
          out.node.emplace_back(xyz[0], xyz[1], xyz[2]);
        }
      }
    } else if (line == "$Elements") {
      members.assign(out.group.size(), {});
      const auto head = lines.row<std::size_t>(4, "the $Elements header");
      for (std::size_t block = 0; block < head[0]; ++block) {
        const auto entity = lines.row<std::size_t>(4, "an element block header");
        std::vector<std::size_t> groups;
        const auto physicals = entity_physicals.find({static_cast<int>(entity[0]), static_cast<int>(entity[1])});
        if (physicals != entity_physicals.end()) {
          for (int tag : physicals->second) {
            const auto found = group_of.find({static_cast<int>(entity[0]), tag});
            if (found != group_of.end()) groups.push_back(found->second);
          }
        }
        for (std::size_t k = 0; k < entity[3]; ++k) {
          const auto values = lines.row<std::size_t>(2, "an element: tag and nodes");
          if (groups.empty()) continue;
          for (std::size_t a = 1; a < values.size(); ++a) {
            const auto it = node_index.find(values[a]);
            if (it == node_index.end()) {
              lines.fail(fmt::format("element {} uses node tag {}, which $Nodes does not define", values[0], values[a]),
                         "export the mesh again with all its nodes");
            }
            for (std::size_t g : groups) members[g].insert(it->second);
          }
        }
      }
    }
  }
  for (std::size_t g = 0; g < members.size(); ++g) out.group[g].node.assign(members[g].begin(), members[g].end());
  return out;
}

}  // namespace sabo::io
