#include "libsabo/geometry/covering_boxes.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <map>

namespace sabo::geometry {

namespace {

using TileKey = std::array<std::int64_t, 3>;  // z, y, x: std::map orders tiles as documented

Aabb box_of(const Aabb& piece) {
  return piece;
}
Aabb box_of(const Vec3& point) {
  return Aabb{point, point};
}

template <class Piece>
std::map<TileKey, Aabb> bin(std::span<const Piece> pieces, const Aabb& bounds, double tile_size,
                            std::size_t give_up_above) {
  std::map<TileKey, Aabb> tiles;
  for (const Piece& piece : pieces) {
    const Aabb box = box_of(piece);
    if (box.empty()) continue;
    const Vec3 cell = ((0.5 * (box.min + box.max) - bounds.min) / tile_size).array().floor();
    tiles[TileKey{static_cast<std::int64_t>(cell.z()), static_cast<std::int64_t>(cell.y()),
                  static_cast<std::int64_t>(cell.x())}]
        .extend(box);
    if (tiles.size() > give_up_above) break;
  }
  return tiles;
}

template <class Piece>
std::vector<Aabb> cover(std::span<const Piece> pieces, std::size_t max_boxes) {
  assert(max_boxes >= 1);
  Aabb bounds;
  for (const Piece& piece : pieces) bounds.extend(box_of(piece));
  if (bounds.empty()) return {};
  const double longest = (bounds.max - bounds.min).maxCoeff();
  std::vector<Aabb> boxes;
  if (longest > 0) {
    for (int divisions = 16; divisions > 1; divisions /= 2) {
      const auto tiles = bin(pieces, bounds, longest / divisions, max_boxes);
      if (tiles.size() > max_boxes) continue;
      boxes.reserve(tiles.size());
      for (const auto& [key, box] : tiles) boxes.push_back(box);
      return boxes;
    }
  }
  boxes.push_back(bounds);
  return boxes;
}

}  // namespace

std::vector<Aabb> covering_boxes(std::span<const Aabb> pieces, std::size_t max_boxes) {
  return cover(pieces, max_boxes);
}

std::vector<Aabb> covering_boxes(std::span<const Vec3> points, std::size_t max_boxes) {
  return cover(points, max_boxes);
}

double total_volume(std::span<const Aabb> boxes) {
  double volume = 0;
  for (const Aabb& box : boxes) {
    if (!box.empty()) volume += (box.max - box.min).prod();
  }
  return volume;
}

}  // namespace sabo::geometry
