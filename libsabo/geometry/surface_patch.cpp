#include "libsabo/geometry/surface_patch.hpp"

#include <Eigen/Geometry>
#include <vector>

namespace sabo::geometry {

double clipped_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c, const Aabb& box) {
  std::vector<Vec3> polygon{a, b, c}, next;
  for (int axis = 0; axis < 3 && !polygon.empty(); ++axis) {
    for (const double side : {-1.0, 1.0}) {
      // Keep side * (x[axis] - bound) <= 0.
      const double bound = side < 0 ? box.min[axis] : box.max[axis];
      const auto outside = [&](const Vec3& p) { return side * (p[axis] - bound); };
      next.clear();
      for (std::size_t k = 0; k < polygon.size(); ++k) {
        const Vec3& p = polygon[k];
        const Vec3& q = polygon[(k + 1) % polygon.size()];
        const double dp = outside(p), dq = outside(q);
        if (dp <= 0) next.push_back(p);
        if ((dp < 0 && dq > 0) || (dp > 0 && dq < 0)) next.push_back(p + (q - p) * (dp / (dp - dq)));
      }
      polygon.swap(next);
      if (polygon.empty()) break;
    }
  }
  if (polygon.size() < 3) return 0;
  Vec3 twice_area = Vec3::Zero();
  for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
    twice_area += (polygon[k] - polygon[0]).cross(polygon[k + 1] - polygon[0]);
  }
  return 0.5 * twice_area.norm();
}

SurfacePatch surface_patch(const SurfaceMesh& surface, std::uint32_t part, const std::optional<Aabb>& box) {
  SurfacePatch patch;
  for (std::size_t f = 0; f < surface.face_count(); ++f) {
    if (surface.face_part[f] != part) continue;
    const auto& t = surface.triangle[f];
    const Vec3 &a = surface.node_position[t[0]], &b = surface.node_position[t[1]], &c = surface.node_position[t[2]];
    for (const Vec3* p : {&a, &b, &c}) patch.part_bounds.extend(*p);
    const double area = box ? clipped_triangle_area(a, b, c, *box) : surface.face_area(f);
    if (area <= 0) continue;
    patch.area += area;
    patch.area_normal += area * surface.face_normal(f);
  }
  return patch;
}

}  // namespace sabo::geometry
