#include "libsabo/geometry/primitives.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <numbers>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/node_welder.hpp"
#include "libsabo/geometry/polygon.hpp"
#include "libsabo/io/raster.hpp"
#include "libsabo/io/stl.hpp"

namespace sabo::geometry {
namespace {

// Nodes closer than this fraction of the shape's size are one node.
constexpr double kWeldFraction = 1e-9;

[[noreturn]] void shape_error(const scene::Origin& origin, const std::string& part, const std::string& problem,
                              const std::string& fix) {
  const std::string where = origin.file.empty() ? fmt::format("structure '{}'", part)
                                                : fmt::format("{}:{}: structure '{}' (key '{}')", origin.file.string(),
                                                              origin.line, part, origin.key);
  throw SceneError(fmt::format("{}: {}. Fix: {}", where, problem, fix));
}

// Builds one part from rectangular patches of quads split into triangles.
class PatchBuilder {
 public:
  explicit PatchBuilder(double size) : welder_(kWeldFraction * size) {}

  // The grid corner + u * u_levels[i] + v * v_levels[j]; triangles face `outward`.
  void grid(const Vec3& corner, const Vec3& u, const std::vector<double>& u_levels, const Vec3& v,
            const std::vector<double>& v_levels, const Vec3& outward) {
    const bool flip = u.cross(v).dot(outward) < 0;
    std::vector<std::uint32_t> nodes(u_levels.size() * v_levels.size());
    for (std::size_t j = 0; j < v_levels.size(); ++j) {
      for (std::size_t i = 0; i < u_levels.size(); ++i) {
        nodes[j * u_levels.size() + i] = welder_.add(corner + u_levels[i] * u + v_levels[j] * v);
      }
    }
    for (std::size_t j = 0; j + 1 < v_levels.size(); ++j) {
      for (std::size_t i = 0; i + 1 < u_levels.size(); ++i) {
        const std::uint32_t a = nodes[j * u_levels.size() + i];
        const std::uint32_t b = nodes[j * u_levels.size() + i + 1];
        const std::uint32_t c = nodes[(j + 1) * u_levels.size() + i + 1];
        const std::uint32_t d = nodes[(j + 1) * u_levels.size() + i];
        if (flip) {
          triangles_.push_back({a, c, b});
          triangles_.push_back({a, d, c});
        } else {
          triangles_.push_back({a, b, c});
          triangles_.push_back({a, c, d});
        }
      }
    }
  }

  SurfaceMesh finish(const std::string& part_name) {
    SurfaceMesh mesh;
    mesh.node_position = welder_.take_positions();
    mesh.triangle = std::move(triangles_);
    mesh.make_single_part(part_name);
    return mesh;
  }

 private:
  NodeWelder welder_;
  std::vector<std::array<std::uint32_t, 3>> triangles_;
};

// Levels of `grid_levels(height, element_size)` plus `other_levels` below `height`: two walls meeting
// along an edge get the same nodes there.
std::vector<double> levels_with(double height, const std::vector<double>& other_levels, double element_size) {
  std::vector<double> levels = grid_levels(height, element_size);
  double highest = height;
  for (double level : other_levels) {
    highest = std::max(highest, level);
    if (level < height) levels.push_back(level);
  }
  std::sort(levels.begin(), levels.end());
  const double tolerance = 1e-12 * highest;
  levels.erase(std::unique(levels.begin(), levels.end(),
                           [tolerance](double a, double b) { return std::abs(a - b) <= tolerance; }),
               levels.end());
  return levels;
}

// Levels of a wall `height` high meeting walls of `other_heights` (0: none) along its vertical edges.
std::vector<double> wall_levels(double height, std::initializer_list<double> other_heights, double element_size) {
  std::vector<double> others;
  for (double other_height : other_heights) {
    if (other_height > 0) {
      const auto levels = grid_levels(other_height, element_size);
      others.insert(others.end(), levels.begin(), levels.end());
    }
  }
  return levels_with(height, others, element_size);
}

SurfaceMesh plane(const scene::Shape& shape, const std::string& part, const scene::Origin& origin) {
  if (!(shape.length > 0) || !(shape.width > 0)) {
    shape_error(origin, part, fmt::format("plane of length {} and width {}", shape.length, shape.width),
                "give both a positive value (m)");
  }
  if (!(shape.normal.norm() > 0)) shape_error(origin, part, "plane normal is zero", "give a nonzero normal");
  const Vec3 normal = shape.normal.normalized();
  const Vec3 along = shape.direction - shape.direction.dot(normal) * normal;
  if (!(along.norm() > 1e-9 * shape.direction.norm())) {
    shape_error(origin, part, "plane direction is parallel to its normal",
                "give a direction that lies in the plane (it orients the length)");
  }
  const Vec3 u = along.normalized();
  const Vec3 v = normal.cross(u);
  PatchBuilder builder(shape.length + shape.width);
  builder.grid(shape.origin - 0.5 * shape.length * u - 0.5 * shape.width * v, u,
               grid_levels(shape.length, shape.element_size), v, grid_levels(shape.width, shape.element_size), normal);
  return builder.finish(part);
}

SurfaceMesh box(const scene::Shape& shape, const std::string& part, const scene::Origin& origin) {
  const Vec3 extent = shape.box.max - shape.box.min;
  if (!(extent.minCoeff() > 0)) {
    shape_error(origin, part,
                fmt::format("box from ({}, {}, {}) to ({}, {}, {}) has no volume", shape.box.min.x(), shape.box.min.y(),
                            shape.box.min.z(), shape.box.max.x(), shape.box.max.y(), shape.box.max.z()),
                "give max > min on every axis");
  }
  std::array<std::vector<double>, 3> levels;
  for (int axis = 0; axis < 3; ++axis) levels[axis] = grid_levels(extent[axis], shape.element_size);
  PatchBuilder builder(extent.norm());
  for (int axis = 0; axis < 3; ++axis) {
    const int a = (axis + 1) % 3;
    const int b = (axis + 2) % 3;
    const Vec3 u = Vec3::Unit(a);
    const Vec3 v = Vec3::Unit(b);
    Vec3 low = shape.box.min;
    Vec3 high = shape.box.min;
    high[axis] = shape.box.max[axis];
    builder.grid(low, u, levels[a], v, levels[b], -Vec3::Unit(axis));
    builder.grid(high, u, levels[a], v, levels[b], Vec3::Unit(axis));
  }
  return builder.finish(part);
}

SurfaceMesh chute(const scene::Shape& shape, const std::string& part, const scene::Origin& origin) {
  if (!(shape.length > 0) || !(shape.width > 0)) {
    shape_error(origin, part, fmt::format("chute of length {} and width {}", shape.length, shape.width),
                "give both a positive value (m)");
  }
  if (!(shape.slope_deg >= 0 && shape.slope_deg < 90)) {
    shape_error(origin, part, fmt::format("chute slope {} degrees", shape.slope_deg), "give a slope in [0, 90)");
  }
  if (!(shape.wall_height >= 0) || !(shape.end_wall_height >= 0)) {
    shape_error(origin, part, fmt::format("chute wall heights {} and {}", shape.wall_height, shape.end_wall_height),
                "give heights >= 0 (0: no wall)");
  }
  if (!(Vec3(shape.direction.x(), shape.direction.y(), 0).norm() > 0)) {
    shape_error(origin, part, "chute direction has no horizontal component",
                "give the horizontal direction the chute runs in, e.g. [1, 0, 0]");
  }
  const ChuteFrame frame = chute_frame(shape);
  const double length = shape.length;
  const double half_width = 0.5 * shape.width;
  const double es = shape.element_size;
  const auto along = grid_levels(length, es);
  const auto across = grid_levels(shape.width, es);
  PatchBuilder builder(length + shape.width + shape.wall_height + shape.end_wall_height);
  const Vec3 right_top = shape.origin - half_width * frame.lateral;  // upper edge, right side (looking down-slope)
  builder.grid(right_top, frame.down_slope, along, frame.lateral, across, frame.normal);
  if (shape.wall_height > 0) {
    const auto up = wall_levels(shape.wall_height, {shape.end_wall_height}, es);
    builder.grid(right_top, frame.down_slope, along, frame.normal, up, frame.lateral);
    builder.grid(shape.origin + half_width * frame.lateral, frame.down_slope, along, frame.normal, up, -frame.lateral);
  }
  if (shape.end_wall_height > 0) {
    const auto up = wall_levels(shape.end_wall_height, {shape.wall_height}, es);
    builder.grid(right_top + length * frame.down_slope, frame.lateral, across, frame.normal, up, -frame.down_slope);
  }
  return builder.finish(part);
}

SurfaceMesh channel(const scene::Shape& shape, const std::string& part, const scene::Origin& origin) {
  const auto& profile = shape.profile;
  if (!(shape.width > 0)) {
    shape_error(origin, part, fmt::format("channel of width {}", shape.width), "give a positive width (m)");
  }
  if (profile.size() < 2) {
    shape_error(origin, part, fmt::format("channel profile of {} points", profile.size()),
                "give at least two points (distance, elevation)");
  }
  for (std::size_t k = 1; k < profile.size(); ++k) {
    if (!(profile[k][0] > profile[k - 1][0])) {
      shape_error(origin, part,
                  fmt::format("channel profile: distance {} at point {} after {}", profile[k][0], k, profile[k - 1][0]),
                  "sort the points by distance and drop repeated ones");
    }
  }
  if (!shape.floor && !(shape.wall_height > 0) && !(shape.start_wall_height > 0) && !(shape.end_wall_height > 0)) {
    shape_error(origin, part, "a channel without its floor and without walls", "give a wall height, or floor = true");
  }
  if (!(shape.wall_height >= 0) || !(shape.start_wall_height >= 0) || !(shape.end_wall_height >= 0)) {
    shape_error(origin, part,
                fmt::format("channel wall heights {}, {} and {}", shape.wall_height, shape.start_wall_height,
                            shape.end_wall_height),
                "give heights >= 0 (0: no wall)");
  }
  const Vec3 along(shape.direction.x(), shape.direction.y(), 0);
  if (!(along.norm() > 0)) {
    shape_error(origin, part, "channel direction has no horizontal component",
                "give the horizontal direction of increasing distance, e.g. [1, 0, 0]");
  }
  const Vec3 downstream = along.normalized();
  const Vec3 lateral = Vec3::UnitZ().cross(downstream);  // to the left looking downstream
  const auto bed = [&](std::size_t k) -> Vec3 {
    return Vec3(shape.origin.x(), shape.origin.y(), 0) + profile[k][0] * downstream + profile[k][1] * Vec3::UnitZ();
  };
  const double half_width = 0.5 * shape.width;
  const double es = shape.element_size;
  double size = shape.width + shape.wall_height + shape.start_wall_height + shape.end_wall_height;
  for (std::size_t k = 0; k + 1 < profile.size(); ++k) size += (bed(k + 1) - bed(k)).norm();
  const auto across = grid_levels(shape.width, es);
  const auto side_up = wall_levels(shape.wall_height, {shape.start_wall_height, shape.end_wall_height}, es);
  PatchBuilder builder(size);
  for (std::size_t k = 0; k + 1 < profile.size(); ++k) {
    const Vec3 piece = bed(k + 1) - bed(k);
    const double length = piece.norm();
    const Vec3 u = piece / length;
    const auto levels = grid_levels(length, es);
    const Vec3 right = bed(k) - half_width * lateral;
    if (shape.floor) builder.grid(right, u, levels, lateral, across, Vec3::UnitZ());
    if (shape.wall_height > 0) {
      builder.grid(right, u, levels, Vec3::UnitZ(), side_up, lateral);
      builder.grid(bed(k) + half_width * lateral, u, levels, Vec3::UnitZ(), side_up, -lateral);
    }
  }
  if (shape.start_wall_height > 0) {
    builder.grid(bed(0) - half_width * lateral, lateral, across, Vec3::UnitZ(),
                 levels_with(shape.start_wall_height, side_up, es), downstream);
  }
  if (shape.end_wall_height > 0) {
    builder.grid(bed(profile.size() - 1) - half_width * lateral, lateral, across, Vec3::UnitZ(),
                 levels_with(shape.end_wall_height, side_up, es), -downstream);
  }
  return builder.finish(part);
}

SurfaceMesh mesh(const scene::Shape& shape, const std::string& part, const scene::Origin& origin) {
  if (!(shape.scale > 0)) {
    shape_error(origin, part, fmt::format("mesh scale {}", shape.scale), "give a positive scale factor");
  }
  io::StlMesh stl = io::read_stl(shape.file);
  SurfaceMesh result = std::move(stl.mesh);
  for (Vec3& p : result.node_position) p = shape.scale * p + shape.translate;
  result.part_name = {part};
  return result;
}

// A terrain's mesh and centre-line spacing: its element size, or the raster's cell without one.
double terrain_element_size(const scene::Shape& shape, const io::Raster& raster) {
  return shape.element_size > 0 ? shape.element_size : std::min(raster.cell_x, raster.cell_y);
}

// The ground of an elevation raster: a strip along a polyline, the inside of a polygon, or the whole
// raster, on a grid of about element_size (the raster's cell without one), each node at the raster's
// bilinear elevation, triangles facing up.
SurfaceMesh terrain(const scene::Shape& shape, const std::string& part, const scene::Origin& origin) {
  // A strip's cross-sections: at a bend along the bisector, lengthened so that the strip keeps its width.
  std::vector<Eigen::Vector2d> mitre;
  if (!shape.strip.empty()) {
    const auto& p = shape.strip;
    const std::size_t m = p.size() - 1;
    std::vector<Eigen::Vector2d> left(m);  // unit normals of the segments, to their left
    for (std::size_t k = 0; k < m; ++k) {
      const Eigen::Vector2d d = Eigen::Vector2d(p[k + 1][0] - p[k][0], p[k + 1][1] - p[k][1]).normalized();
      left[k] = Eigen::Vector2d(-d.y(), d.x());
    }
    mitre.resize(m + 1);
    mitre[0] = left[0];
    mitre[m] = left[m - 1];
    for (std::size_t k = 1; k < m; ++k) {
      const Eigen::Vector2d bisector = left[k - 1] + left[k];
      const double along = bisector.norm() > 1e-12 ? bisector.normalized().dot(left[k]) : 0.0;
      if (along < 0.2) {
        shape_error(origin, part, fmt::format("the strip turns by more than 157 degrees at its point {}", k),
                    "smooth the polyline (add points along the bend)");
      }
      mitre[k] = bisector.normalized() / along;
    }
  }
  // Only the cells under the region are read: the corners of the strip's cross-sections, or the polygon
  // (empty for the whole raster).
  io::RasterWindow region;
  for (std::size_t k = 0; k < mitre.size(); ++k) {
    for (const double side : {-0.5, 0.5}) {
      const Eigen::Vector2d corner =
          Eigen::Vector2d(shape.strip[k][0], shape.strip[k][1]) + side * shape.strip_width * mitre[k];
      region.extend(corner.x(), corner.y());
    }
  }
  for (const auto& v : shape.clip_polygon) region.extend(v[0], v[1]);
  const io::Raster raster = io::read_raster(shape.file, region);
  const double es = terrain_element_size(shape, raster);
  NodeWelder welder(kWeldFraction * std::hypot(raster.x_max() - raster.x_min(), raster.y_max() - raster.y_min()));
  std::vector<std::array<std::uint32_t, 3>> triangles;
  const auto node = [&](double x, double y) {
    const auto z = raster.elevation_at(x, y);
    if (!z) {
      shape_error(
          origin, part,
          fmt::format("the ground at (x, y) = ({:.9g}, {:.9g}) m is {} of {}", x, y,
                      raster.covers(x, y) ? "next to a no-data cell" : "outside the cell centres", raster.describe()),
          raster.covers(x, y) ? "keep the strip or the polygon off the raster's no-data cells (fill them, "
                                "e.g. gdal_fillnodata)"
                              : "keep the strip or the polygon inside the raster");
    }
    return welder.add(Vec3(x, y, *z) + shape.translate);
  };
  // Two triangles of the quad a b c d, counter-clockwise seen from above: they face up.
  const auto quad = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    triangles.push_back({a, b, c});
    triangles.push_back({a, c, d});
  };
  if (!shape.strip.empty()) {
    const auto& p = shape.strip;
    const std::size_t m = p.size() - 1;
    std::vector<double> across = grid_levels(shape.strip_width, es);
    for (double& t : across) t -= 0.5 * shape.strip_width;
    for (std::size_t k = 0; k < m; ++k) {
      const Eigen::Vector2d a(p[k][0], p[k][1]), b(p[k + 1][0], p[k + 1][1]);
      const auto along = grid_levels((b - a).norm(), es);
      const double length = (b - a).norm();
      std::vector<std::uint32_t> ids(along.size() * across.size());
      for (std::size_t i = 0; i < along.size(); ++i) {
        const double f = along[i] / length;
        for (std::size_t j = 0; j < across.size(); ++j) {
          const Eigen::Vector2d q = (1 - f) * (a + across[j] * mitre[k]) + f * (b + across[j] * mitre[k + 1]);
          ids[i * across.size() + j] = node(q.x(), q.y());
        }
      }
      // i runs along the segment, j to its left: (i, j), (i+1, j), (i+1, j+1), (i, j+1) turn counter-clockwise.
      for (std::size_t i = 0; i + 1 < along.size(); ++i) {
        for (std::size_t j = 0; j + 1 < across.size(); ++j) {
          const std::size_t n = across.size();
          quad(ids[i * n + j], ids[(i + 1) * n + j], ids[(i + 1) * n + j + 1], ids[i * n + j + 1]);
        }
      }
    }
  } else {
    // The polygon's bounds, or the cell centres' extent of the whole raster.
    const bool clipped = !shape.clip_polygon.empty();
    const double x0 = clipped ? region.x_min : raster.x_min(), x1 = clipped ? region.x_max : raster.x_max();
    const double y0 = clipped ? region.y_min : raster.y_min(), y1 = clipped ? region.y_max : raster.y_max();
    const auto xs = grid_levels(x1 - x0, es), ys = grid_levels(y1 - y0, es);
    const auto kept = [&](double x, double y) {
      return shape.clip_polygon.empty() || polygon_contains(shape.clip_polygon, x, y);
    };
    std::vector<std::int64_t> ids(xs.size() * ys.size(), -1);
    const auto id = [&](std::size_t i, std::size_t j) {
      auto& slot = ids[j * xs.size() + i];
      if (slot < 0) slot = node(x0 + xs[i], y0 + ys[j]);
      return static_cast<std::uint32_t>(slot);
    };
    for (std::size_t j = 0; j + 1 < ys.size(); ++j) {
      for (std::size_t i = 0; i + 1 < xs.size(); ++i) {
        const bool all_in = kept(x0 + xs[i], y0 + ys[j]) && kept(x0 + xs[i + 1], y0 + ys[j]) &&
                            kept(x0 + xs[i + 1], y0 + ys[j + 1]) && kept(x0 + xs[i], y0 + ys[j + 1]);
        if (all_in) quad(id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
      }
    }
    if (triangles.empty()) {
      shape_error(origin, part, fmt::format("clip_polygon holds no whole element of element_size {} m", es),
                  "give a larger polygon or a smaller element_size");
    }
  }
  SurfaceMesh mesh;
  mesh.node_position = welder.take_positions();
  mesh.triangle = std::move(triangles);
  mesh.make_single_part(part);
  return mesh;
}

}  // namespace

std::vector<double> grid_levels(double length, double element_size) {
  std::size_t count = 1;
  if (element_size > 0 && length > element_size) {
    // The small allowance keeps 1.0 / 0.1 at 10 cells despite rounding.
    count = static_cast<std::size_t>(std::ceil(length / element_size * (1 - 1e-12)));
  }
  std::vector<double> levels(count + 1);
  for (std::size_t i = 0; i <= count; ++i) levels[i] = length * static_cast<double>(i) / static_cast<double>(count);
  levels.back() = length;
  return levels;
}

std::vector<Vec3> terrain_centre_line(const scene::Shape& shape, const std::string& part_name,
                                      const scene::Origin& origin) {
  const auto& p = shape.strip;
  if (shape.type != scene::Shape::Type::terrain || p.size() < 2) {
    shape_error(origin, part_name, "a terrain front follows a strip, and this structure keeps none",
                "give the terrain a strip (a polyline and strip_width), or track the front along an axis");
  }
  io::RasterWindow window;
  for (const auto& v : p) window.extend(v[0], v[1]);
  const io::Raster raster = io::read_raster(shape.file, window);
  const double es = terrain_element_size(shape, raster);
  std::vector<Vec3> line;
  for (std::size_t k = 0; k + 1 < p.size(); ++k) {
    const Eigen::Vector2d a(p[k][0], p[k][1]), b(p[k + 1][0], p[k + 1][1]);
    const auto levels = grid_levels((b - a).norm(), es);
    for (std::size_t i = k == 0 ? 0 : 1; i < levels.size(); ++i) {
      const Eigen::Vector2d q = a + levels[i] / (b - a).norm() * (b - a);
      const auto z = raster.elevation_at(q.x(), q.y());
      if (!z) {
        shape_error(origin, part_name,
                    fmt::format("the strip's centre line at (x, y) = ({:.9g}, {:.9g}) m has no ground in {}", q.x(),
                                q.y(), raster.describe()),
                    "keep the strip inside the raster and off its no-data cells");
      }
      line.push_back(Vec3(q.x(), q.y(), *z) + shape.translate);
    }
  }
  return line;
}

ChuteFrame chute_frame(const scene::Shape& shape) {
  const double slope = shape.slope_deg * std::numbers::pi / 180.0;
  const Vec3 horizontal = Vec3(shape.direction.x(), shape.direction.y(), 0).normalized();
  ChuteFrame frame;
  frame.down_slope = std::cos(slope) * horizontal - std::sin(slope) * Vec3::UnitZ();
  frame.lateral = Vec3::UnitZ().cross(horizontal);
  frame.normal = frame.down_slope.cross(frame.lateral);
  return frame;
}

SurfaceMesh triangulate(const scene::Shape& shape, const std::string& part_name, const scene::Origin& origin) {
  switch (shape.type) {
    case scene::Shape::Type::plane: return plane(shape, part_name, origin);
    case scene::Shape::Type::box: return box(shape, part_name, origin);
    case scene::Shape::Type::chute: return chute(shape, part_name, origin);
    case scene::Shape::Type::channel: return channel(shape, part_name, origin);
    case scene::Shape::Type::mesh: return mesh(shape, part_name, origin);
    case scene::Shape::Type::terrain: return terrain(shape, part_name, origin);
  }
  shape_error(origin, part_name, "unknown shape type", "use plane, box, chute, channel, mesh or terrain");
}

}  // namespace sabo::geometry
