#pragma once
// Merges points that coincide (exactly, or within a distance) into shared
// nodes, so that triangles built from separately computed corners share their
// edges. Deterministic: a point joins the earliest node within reach.
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::geometry {

class NodeWelder {
 public:
  // tolerance: m; 0 merges only bit-identical points.
  explicit NodeWelder(double tolerance);
  // Index of the earliest node within the tolerance of `point`, or of a new node.
  std::uint32_t add(const Vec3& point);
  [[nodiscard]] const std::vector<Vec3>& positions() const { return positions_; }
  [[nodiscard]] std::vector<Vec3> take_positions() { return std::move(positions_); }
  [[nodiscard]] double tolerance() const { return tolerance_; }

 private:
  struct Key {
    std::int64_t x, y, z;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& key) const;
  };
  [[nodiscard]] Key key_of(const Vec3& point) const;

  double tolerance_;
  double cell_;  // edge of the hash grid's cells, >= tolerance
  std::vector<Vec3> positions_;
  std::unordered_map<Key, std::vector<std::uint32_t>, KeyHash> cells_;
};

}  // namespace sabo::geometry
