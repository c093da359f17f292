#include "libsabo/contact/sphere_triangle.hpp"

#include <algorithm>
#include <cmath>

namespace sabo::contact {

const char* feature_name(Feature feature) {
  switch (feature) {
    case Feature::face: return "face";
    case Feature::edge: return "edge";
    case Feature::vertex: return "vertex";
  }
  return "unknown";
}

namespace {

struct SegmentPoint {
  Vec3 point;
  double along;  // parameter in [0, 1] from the start
  double squared_distance;
};

SegmentPoint closest_point_on_segment(const Vec3& p, const Vec3& start, const Vec3& end) {
  const Vec3 direction = end - start;
  const double length_squared = direction.squaredNorm();
  double along = length_squared > 0 ? (p - start).dot(direction) / length_squared : 0.0;
  along = std::clamp(along, 0.0, 1.0);
  const Vec3 point = along == 0.0 ? start : along == 1.0 ? end : Vec3(start + along * direction);
  return {point, along, (p - point).squaredNorm()};
}

}  // namespace

TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Barycentric coordinates of p's projection, scaled by |ab x ac|^2 (Ericson,
  // Real-Time Collision Detection, 5.1.5).
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 ap = p - a;
  const Vec3 bp = p - b;
  const Vec3 cp = p - c;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  const double va = d3 * d6 - d5 * d4;
  const double vb = d5 * d2 - d1 * d6;
  const double vc = d1 * d4 - d3 * d2;
  const double sum = va + vb + vc;

  TrianglePoint result;
  const double tolerance = kFaceTolerance * sum;
  if (sum > 0 && va >= -tolerance && vb >= -tolerance && vc >= -tolerance) {
    const double wa = std::max(va, 0.0), wb = std::max(vb, 0.0), wc = std::max(vc, 0.0);
    const double total = wa + wb + wc;
    double w0 = wa / total;
    double w1 = wb / total;
    double w2 = 1.0 - w0 - w1;
    if (w2 < 0) {
      w2 = 0;
      w1 = 1.0 - w0;
    }
    result.weight = {w0, w1, w2};
    result.point = a + w1 * ab + w2 * ac;
    result.feature = Feature::face;
    result.index = 0;
    return result;
  }

  // Outside the face: the nearest of the three edges (first one on ties).
  const std::array<Vec3, 3> corner{a, b, c};
  int best_edge = 0;
  SegmentPoint best = closest_point_on_segment(p, a, b);
  for (int edge = 1; edge < 3; ++edge) {
    const SegmentPoint candidate = closest_point_on_segment(p, corner[edge], corner[(edge + 1) % 3]);
    if (candidate.squared_distance < best.squared_distance) {
      best = candidate;
      best_edge = edge;
    }
  }
  const int start = best_edge;
  const int end = (best_edge + 1) % 3;
  result.point = best.point;
  if (best.along == 0.0 || best.along == 1.0) {
    const int vertex = best.along == 0.0 ? start : end;
    result.feature = Feature::vertex;
    result.index = vertex;
    result.weight = {0.0, 0.0, 0.0};
    result.weight[static_cast<std::size_t>(vertex)] = 1.0;
    return result;
  }
  result.feature = Feature::edge;
  result.index = best_edge;
  result.weight = {0.0, 0.0, 0.0};
  result.weight[static_cast<std::size_t>(start)] = 1.0 - best.along;
  result.weight[static_cast<std::size_t>(end)] = best.along;
  return result;
}

SphereTriangleGap sphere_triangle_gap(const Vec3& centre, double radius, double thickness, const Vec3& a,
                                      const Vec3& unit_normal, const TrianglePoint& closest, double depth) {
  SphereTriangleGap gap;
  const double reach = radius + 0.5 * thickness;
  if (closest.feature == Feature::face) {
    const double height = (centre - a).dot(unit_normal);  // signed, > 0 on the outward side
    gap.distance = std::abs(height);
    if (thickness > 0) {
      gap.normal = height >= 0 ? unit_normal : Vec3(-unit_normal);
      gap.overlap = reach - gap.distance;
    } else {
      gap.normal = unit_normal;
      gap.overlap = reach - height;
      gap.behind = height < 0;
      gap.reachable = height > -(depth + 0.5 * thickness);
    }
    return gap;
  }
  const Vec3 offset = centre - closest.point;
  gap.distance = offset.norm();
  gap.normal = gap.distance > 0 ? Vec3(offset / gap.distance) : unit_normal;
  gap.overlap = reach - gap.distance;
  return gap;
}

}  // namespace sabo::contact
