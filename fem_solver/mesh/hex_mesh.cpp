#include "fem_solver/mesh/hex_mesh.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace sabo::fem {

const std::array<std::array<int, 4>, 6>& hex_faces() {
  static constexpr std::array<std::array<int, 4>, 6> faces{
      {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}}};
  return faces;
}

std::size_t element_divisions(double length, double element_size) {
  return element_size > 0 ? static_cast<std::size_t>(std::max(1.0, std::round(length / element_size))) : std::size_t{1};
}

namespace {

// Structured grid topology over (n0 + 1) (n1 + 1) (n2 + 1) nodes indexed i + (n0 + 1) (j + (n1 + 1) k).
std::vector<std::array<std::uint32_t, 8>> grid_elements(const std::array<std::size_t, 3>& n) {
  const auto id = [&](std::size_t i, std::size_t j, std::size_t k) {
    return static_cast<std::uint32_t>(i + (n[0] + 1) * (j + (n[1] + 1) * k));
  };
  std::vector<std::array<std::uint32_t, 8>> elements;
  elements.reserve(n[0] * n[1] * n[2]);
  for (std::size_t k = 0; k < n[2]; ++k) {
    for (std::size_t j = 0; j < n[1]; ++j) {
      for (std::size_t i = 0; i < n[0]; ++i) {
        elements.push_back({id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
                            id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)});
      }
    }
  }
  return elements;
}

}  // namespace

HexMesh structured_box(const Aabb& box, const std::array<std::size_t, 3>& divisions) {
  assert(divisions[0] > 0 && divisions[1] > 0 && divisions[2] > 0);
  HexMesh mesh;
  const Vec3 size = box.max - box.min;
  mesh.node.reserve((divisions[0] + 1) * (divisions[1] + 1) * (divisions[2] + 1));
  for (std::size_t k = 0; k <= divisions[2]; ++k) {
    for (std::size_t j = 0; j <= divisions[1]; ++j) {
      for (std::size_t i = 0; i <= divisions[0]; ++i) {
        mesh.node.push_back(box.min + Vec3(size.x() * static_cast<double>(i) / static_cast<double>(divisions[0]),
                                           size.y() * static_cast<double>(j) / static_cast<double>(divisions[1]),
                                           size.z() * static_cast<double>(k) / static_cast<double>(divisions[2])));
      }
    }
  }
  mesh.element = grid_elements(divisions);
  return mesh;
}

HexMesh structured_grid(const std::array<std::vector<double>, 3>& lines) {
  std::array<std::size_t, 3> divisions{};
  for (std::size_t d = 0; d < 3; ++d) {
    assert(lines[d].size() >= 2);
    divisions[d] = lines[d].size() - 1;
  }
  HexMesh mesh;
  mesh.node.reserve(lines[0].size() * lines[1].size() * lines[2].size());
  for (double z : lines[2]) {
    for (double y : lines[1]) {
      for (double x : lines[0]) mesh.node.emplace_back(x, y, z);
    }
  }
  mesh.element = grid_elements(divisions);
  return mesh;
}

namespace {

// Node lines over [from, to] in about `element_size` steps (at least one), `from` excluded.
void append_lines(std::vector<double>& lines, double from, double to, double element_size) {
  const double length = to - from;
  const std::size_t n = element_divisions(length, element_size);
  for (std::size_t k = 1; k < n; ++k) lines.push_back(from + length * static_cast<double>(k) / static_cast<double>(n));
  lines.push_back(to);
}

}  // namespace

HexMesh slit_dam(const Aabb& box, std::size_t slit_count, double slit_width, double slit_depth, int slit_axis,
                 double element_size) {
  assert(slit_axis == 0 || slit_axis == 1);
  const auto through = static_cast<std::size_t>(slit_axis);
  const std::size_t across = 1 - through;
  const double length = box.max(static_cast<Eigen::Index>(across)) - box.min(static_cast<Eigen::Index>(across));
  const double pier = (length - static_cast<double>(slit_count) * slit_width) / static_cast<double>(slit_count + 1);
  assert(pier > 0 && slit_depth > 0 && slit_depth <= box.max.z() - box.min.z());

  std::array<std::vector<double>, 3> lines;
  lines[through] = {box.min(static_cast<Eigen::Index>(through))};
  append_lines(lines[through], box.min(static_cast<Eigen::Index>(through)), box.max(static_cast<Eigen::Index>(through)),
               element_size);
  std::vector<Aabb> slits;
  double position = box.min(static_cast<Eigen::Index>(across));
  lines[across] = {position};
  for (std::size_t k = 0; k <= slit_count; ++k) {
    const double pier_end = k == slit_count ? box.max(static_cast<Eigen::Index>(across)) : position + pier;
    append_lines(lines[across], position, pier_end, element_size);
    position = pier_end;
    if (k == slit_count) break;
    Aabb slit{box.min, box.max};
    slit.min(static_cast<Eigen::Index>(across)) = position;
    slit.max(static_cast<Eigen::Index>(across)) = position + slit_width;
    slit.min.z() = box.max.z() - slit_depth - 1e-9 * (box.max.z() - box.min.z());
    slits.push_back(slit);
    append_lines(lines[across], position, position + slit_width, element_size);
    position += slit_width;
  }
  lines[2] = {box.min.z()};
  const double height = box.max.z() - box.min.z();
  // Slits as deep as the box (up to rounding) reach the ground: no sliver layer below them.
  const double slit_bottom = slit_depth < height * (1 - 1e-9) ? box.max.z() - slit_depth : box.min.z();
  if (slit_bottom > box.min.z()) append_lines(lines[2], box.min.z(), slit_bottom, element_size);
  append_lines(lines[2], slit_bottom, box.max.z(), element_size);

  const HexMesh grid = structured_grid(lines);
  HexMesh mesh;
  std::vector<std::uint32_t> renumber(grid.node.size(), std::numeric_limits<std::uint32_t>::max());
  for (const auto& element : grid.element) {
    Vec3 centre = Vec3::Zero();
    for (auto n : element) centre += grid.node[n] / 8.0;
    if (std::any_of(slits.begin(), slits.end(), [&](const Aabb& slit) { return slit.contains(centre); })) continue;
    std::array<std::uint32_t, 8> kept{};
    for (std::size_t a = 0; a < 8; ++a) {
      std::uint32_t& id = renumber[element[a]];
      if (id == std::numeric_limits<std::uint32_t>::max()) {
        id = static_cast<std::uint32_t>(mesh.node.size());
        mesh.node.push_back(grid.node[element[a]]);
      }
      kept[a] = id;
    }
    mesh.element.push_back(kept);
  }
  return mesh;
}

HexMesh structured_cylinder(const Vec3& base, double radius, double length, std::size_t section, std::size_t axial) {
  HexMesh mesh = structured_box(Aabb{Vec3(-1, -1, 0), Vec3(1, 1, length)}, {section, section, axial});
  for (Vec3& p : mesh.node) {
    const double u = p.x(), v = p.y();
    const double x = u * std::sqrt(1.0 - 0.5 * v * v);
    const double y = v * std::sqrt(1.0 - 0.5 * u * u);
    p = base + Vec3(radius * x, radius * y, p.z());
  }
  return mesh;
}

std::vector<BoundaryFace> exterior_faces(const HexMesh& mesh, std::span<const std::uint8_t> active) {
  struct Entry {
    std::array<std::uint32_t, 4> key;
    std::uint32_t element;
    std::uint32_t local;
  };
  std::vector<Entry> entries;
  entries.reserve(mesh.element.size() * 6);
  for (std::size_t e = 0; e < mesh.element.size(); ++e) {
    if (!active.empty() && active[e] == 0) continue;
    for (std::size_t f = 0; f < 6; ++f) {
      Entry entry{};
      for (std::size_t k = 0; k < 4; ++k) {
        entry.key[k] = mesh.element[e][static_cast<std::size_t>(hex_faces()[f][k])];
      }
      std::sort(entry.key.begin(), entry.key.end());
      entry.element = static_cast<std::uint32_t>(e);
      entry.local = static_cast<std::uint32_t>(f);
      entries.push_back(entry);
    }
  }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.key != b.key ? a.key < b.key : a.element < b.element; });
  std::vector<std::pair<std::uint32_t, std::uint32_t>> kept;  // (element, local face)
  for (std::size_t i = 0; i < entries.size();) {
    std::size_t j = i + 1;
    while (j < entries.size() && entries[j].key == entries[i].key) ++j;
    if (j - i == 1) kept.emplace_back(entries[i].element, entries[i].local);
    i = j;
  }
  std::sort(kept.begin(), kept.end());
  std::vector<BoundaryFace> faces;
  faces.reserve(kept.size());
  for (const auto& [element, local] : kept) {
    BoundaryFace face;
    face.element = element;
    for (std::size_t k = 0; k < 4; ++k)
      face.node[k] = mesh.element[element][static_cast<std::size_t>(hex_faces()[local][k])];
    faces.push_back(face);
  }
  return faces;
}

}  // namespace sabo::fem
