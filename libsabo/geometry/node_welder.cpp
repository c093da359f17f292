#include "libsabo/geometry/node_welder.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

namespace sabo::geometry {

NodeWelder::NodeWelder(double tolerance) : tolerance_(tolerance > 0 ? tolerance : 0), cell_(tolerance_) {}

std::size_t NodeWelder::KeyHash::operator()(const Key& key) const {
  std::uint64_t h = static_cast<std::uint64_t>(key.x) * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<std::uint64_t>(key.y) + 0x7F4A7C159E3779B9ull + (h << 6) + (h >> 2);
  h ^= static_cast<std::uint64_t>(key.z) + 0x94D049BB133111EBull + (h << 6) + (h >> 2);
  return static_cast<std::size_t>(h);
}

NodeWelder::Key NodeWelder::key_of(const Vec3& point) const {
  if (cell_ == 0) {
    // Exact matching: the bit patterns are the key (-0 and +0 are one point).
    auto bits = [](double value) { return std::bit_cast<std::int64_t>(value == 0 ? 0.0 : value); };
    return {bits(point.x()), bits(point.y()), bits(point.z())};
  }
  auto cell = [&](double value) {
    const double index = std::floor(value / cell_);
    constexpr double limit = 4.0e18;  // far beyond any model; keeps the cast defined
    return static_cast<std::int64_t>(std::clamp(index, -limit, limit));
  };
  return {cell(point.x()), cell(point.y()), cell(point.z())};
}

std::uint32_t NodeWelder::add(const Vec3& point) {
  const Key key = key_of(point);
  if (cell_ == 0) {
    auto& bucket = cells_[key];
    if (!bucket.empty()) return bucket.front();
    bucket.push_back(static_cast<std::uint32_t>(positions_.size()));
    positions_.push_back(point);
    return bucket.front();
  }
  // Any node within the tolerance lies in this cell or a neighbouring one.
  std::uint32_t best = std::numeric_limits<std::uint32_t>::max();
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        auto found = cells_.find(Key{key.x + dx, key.y + dy, key.z + dz});
        if (found == cells_.end()) continue;
        for (std::uint32_t node : found->second) {
          if (node < best && (positions_[node] - point).norm() <= tolerance_) best = node;
        }
      }
    }
  }
  if (best != std::numeric_limits<std::uint32_t>::max()) return best;
  const auto node = static_cast<std::uint32_t>(positions_.size());
  positions_.push_back(point);
  cells_[key].push_back(node);
  return node;
}

}  // namespace sabo::geometry
