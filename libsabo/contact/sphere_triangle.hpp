#pragma once
// Point-triangle geometry of the particle-surface penalty contact (docs/model.md
// "SPH-FEM", "DEM-FEM", paper eqs. 3-5): the closest point of a triangle with
// the feature it lies on, and the overlap and normal of a sphere against it.
#include <array>
#include <cstdint>

#include "libsabo/core/types.hpp"

namespace sabo::contact {

// Which part of a triangle the closest point lies on.
enum class Feature : std::uint8_t { face = 0, edge = 1, vertex = 2 };
[[nodiscard]] const char* feature_name(Feature feature);

// A projection that falls outside a triangle by less than this fraction of its
// size (barycentric coordinate >= -kFaceTolerance) still counts as a face
// contact, so that a point on a shared edge is a face point of both
// neighbours instead of flipping between face and edge with round-off.
inline constexpr double kFaceTolerance = 1e-9;

struct TrianglePoint {
  Vec3 point = Vec3::Zero();  // closest point of the triangle, m
  // Barycentric weights of `point` on (a, b, c): each in [0, 1], and
  // weight[2] = 1 - weight[0] - weight[1] so that they sum to 1 exactly.
  std::array<double, 3> weight{1.0, 0.0, 0.0};
  Feature feature = Feature::face;
  // Edge: 0 = ab, 1 = bc, 2 = ca. Vertex: 0 = a, 1 = b, 2 = c. Face: 0.
  int index = 0;
};

// Closest point of triangle (a, b, c) to p. A degenerate triangle (zero area)
// is handled as its edges. Deterministic: depends on the inputs' bits only.
[[nodiscard]] TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// How a sphere (or an SPH particle of contact radius h) meets one triangle.
//
// Faces with a thickness (shells, eq. 3) are two-sided: the shell's mid-surface
// carries half the thickness on either side, and a centre on the back side is
// pushed back out on the back side. Faces without thickness (solid faces,
// rigid surfaces) are one-sided: a centre behind the face's plane (the sphere
// has sunk in by more than its radius) is still pushed out along the outward
// normal, down to a depth of radius below the plane, past which the face is
// ignored. Edge and vertex contacts push along the line from the closest point
// to the centre (the edge of a shell is a cylinder of radius thickness / 2).
struct SphereTriangleGap {
  double overlap = 0;           // m: > 0 in contact (radius + thickness / 2 - distance)
  double distance = 0;          // m: from the centre to the closest point, unsigned
  Vec3 normal = Vec3::UnitZ();  // unit, from the surface towards the centre
  bool behind = false;          // one-sided face contact with the centre behind the plane
  bool reachable = true;        // false: behind a one-sided face by more than radius + thickness / 2
};

// unit_normal: the triangle's outward unit normal ((b - a) x (c - a), normalised). depth: how far
// behind a one-sided face's plane the centre is still pushed out (reachable), beyond thickness / 2; a
// sphere's is its radius, a point's (radius 0, a node of another structure) its own.
[[nodiscard]] SphereTriangleGap sphere_triangle_gap(const Vec3& centre, double radius, double thickness, const Vec3& a,
                                                    const Vec3& unit_normal, const TrianglePoint& closest,
                                                    double depth);
[[nodiscard]] inline SphereTriangleGap sphere_triangle_gap(const Vec3& centre, double radius, double thickness,
                                                           const Vec3& a, const Vec3& unit_normal,
                                                           const TrianglePoint& closest) {
  return sphere_triangle_gap(centre, radius, thickness, a, unit_normal, closest, radius);
}

}  // namespace sabo::contact
