#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <limits>

namespace sabo {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// Axis-aligned box, m.
struct Aabb {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 max = Vec3::Constant(-std::numeric_limits<double>::infinity());

  [[nodiscard]] bool empty() const { return (min.array() > max.array()).any(); }
  void extend(const Vec3& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void extend(const Aabb& b) {
    if (b.empty()) return;
    min = min.cwiseMin(b.min);
    max = max.cwiseMax(b.max);
  }
  [[nodiscard]] Aabb inflated(double margin) const {
    if (empty()) return *this;
    return {min.array() - margin, max.array() + margin};
  }
  [[nodiscard]] bool contains(const Vec3& p) const {
    return (p.array() >= min.array()).all() && (p.array() <= max.array()).all();
  }
  [[nodiscard]] bool overlaps(const Aabb& b) const {
    return !empty() && !b.empty() && (min.array() <= b.max.array()).all() && (b.min.array() <= max.array()).all();
  }
};

}  // namespace sabo
