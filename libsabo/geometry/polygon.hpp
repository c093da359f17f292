#pragma once
// Plane polygons given by their corners in order: the profiles that regions
// and fluid bodies extrude (fill polygon_xz, fluid profile).
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

namespace sabo::geometry {

using Point2 = std::array<double, 2>;
using Polygon2 = std::vector<Point2>;

// Even-odd rule: whether (s, z) lies inside.
[[nodiscard]] inline bool polygon_contains(const Polygon2& polygon, double s, double z) {
  bool inside = false;
  const std::size_t n = polygon.size();
  for (std::size_t a = 0, b = n - 1; a < n; b = a++) {
    const Point2& pa = polygon[a];
    const Point2& pb = polygon[b];
    if ((pa[1] > z) != (pb[1] > z)) {
      const double s_cross = pa[0] + (z - pa[1]) * (pb[0] - pa[0]) / (pb[1] - pa[1]);
      if (s < s_cross) inside = !inside;
    }
  }
  return inside;
}

// Enclosed area (shoelace), whatever the orientation.
[[nodiscard]] inline double polygon_area(const Polygon2& polygon) {
  double twice_area = 0;
  for (std::size_t k = 0; k < polygon.size(); ++k) {
    const Point2& a = polygon[k];
    const Point2& b = polygon[(k + 1) % polygon.size()];
    twice_area += a[0] * b[1] - b[0] * a[1];
  }
  return 0.5 * std::abs(twice_area);
}

namespace detail {
// Twice the signed area of the triangle o, p, q (> 0: counter-clockwise).
[[nodiscard]] inline double orientation(const Point2& o, const Point2& p, const Point2& q) {
  return (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0]);
}
[[nodiscard]] inline bool opposite_sides(double d1, double d2) {
  return (d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0);
}
}  // namespace detail

// Whether segments [a, b] and [c, d] cross at a point inside both (touching does not count).
[[nodiscard]] inline bool segments_cross(const Point2& a, const Point2& b, const Point2& c, const Point2& d) {
  return detail::opposite_sides(detail::orientation(c, d, a), detail::orientation(c, d, b)) &&
         detail::opposite_sides(detail::orientation(a, b, c), detail::orientation(a, b, d));
}

// Whether segments [a, b] and [c, d] meet (touching counts).
[[nodiscard]] inline bool segments_meet(const Point2& a, const Point2& b, const Point2& c, const Point2& d) {
  const auto within = [](const Point2& p, const Point2& q, const Point2& r) {  // r on the line pq: in the segment?
    return std::min(p[0], q[0]) <= r[0] && r[0] <= std::max(p[0], q[0]) && std::min(p[1], q[1]) <= r[1] &&
           r[1] <= std::max(p[1], q[1]);
  };
  const double d1 = detail::orientation(c, d, a), d2 = detail::orientation(c, d, b);
  const double d3 = detail::orientation(a, b, c), d4 = detail::orientation(a, b, d);
  if (detail::opposite_sides(d1, d2) && detail::opposite_sides(d3, d4)) return true;  // segments_cross
  return (d1 == 0 && within(c, d, a)) || (d2 == 0 && within(c, d, b)) || (d3 == 0 && within(a, b, c)) ||
         (d4 == 0 && within(a, b, d));
}

// The first two edges that are not neighbours (edge k joins corners k and k + 1 mod n)
// and cross, or with `touching` also touch, in the order (0, 2), (0, 3), ..., (1, 3),
// ...; none: the outline is simple.
[[nodiscard]] inline std::optional<std::array<std::size_t, 2>> first_crossing_edges(const Polygon2& polygon,
                                                                                    bool touching) {
  const std::size_t n = polygon.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // neighbours through corner 0
      const Point2 &a = polygon[i], &b = polygon[(i + 1) % n], &c = polygon[j], &d = polygon[(j + 1) % n];
      if (touching ? segments_meet(a, b, c, d) : segments_cross(a, b, c, d)) return std::array<std::size_t, 2>{i, j};
    }
  }
  return std::nullopt;
}

}  // namespace sabo::geometry
