#pragma once
// The part of a structure's surface inside a box: what a force sensor
// ([[sensors]], docs/scene.md) covers, its area and mean normal.
#include <cstdint>
#include <optional>

#include "libsabo/core/types.hpp"
#include "libsabo/geometry/surface_mesh.hpp"

namespace sabo::geometry {

struct SurfacePatch {
  double area = 0;                  // m^2
  Vec3 area_normal = Vec3::Zero();  // m^2: sum of each clipped piece's area times its outward unit normal
  Aabb part_bounds;                 // m: the box around the whole part
  // Unit, area-weighted mean outward normal; zero when the pieces' normals cancel (a closed part without box).
  [[nodiscard]] Vec3 mean_normal() const {
    const double norm = area_normal.norm();
    return norm > 1e-12 * area ? Vec3(area_normal / norm) : Vec3::Zero();
  }
};

// The faces of part `part` of `surface` clipped to `box` (the whole part when absent): area and normal.
[[nodiscard]] SurfacePatch surface_patch(const SurfaceMesh& surface, std::uint32_t part,
                                         const std::optional<Aabb>& box);

// Area of triangle (a, b, c) clipped to `box`, m^2 (Sutherland-Hodgman against its six planes).
[[nodiscard]] double clipped_triangle_area(const Vec3& a, const Vec3& b, const Vec3& c, const Aabb& box);

}  // namespace sabo::geometry
