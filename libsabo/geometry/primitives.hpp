#pragma once
// Triangulated surfaces of the scene's structure shapes (scene::Shape).
// Each result is one part: node ids 0..n-1, nodes shared along every edge
// inside the part, per-face attributes zero (the caller fills material,
// thickness and so on).
#include <string>
#include <vector>

#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::geometry {

// Levels 0 = l_0 < l_1 < ... < l_n = length in n equal steps, n the smallest
// count with steps no longer than element_size (n = 1 for element_size 0).
[[nodiscard]] std::vector<double> grid_levels(double length, double element_size);

// plane: a length x width rectangle, normal `shape.normal`;
// box: its closed surface, normals outward;
// chute: floor and side walls (and end wall), normals into the channel;
// channel: floor along the profile, vertical side and end walls, normals into the channel;
// mesh: the STL file, scaled about the origin, then translated;
// terrain: the raster's ground (a strip, a clipped polygon or all of it) on a grid of element_size,
// translated, triangles facing up.
// Throws SceneError (naming `origin` when given) for shapes that cannot be
// built, FileError for unreadable mesh and raster files.
[[nodiscard]] SurfaceMesh triangulate(const scene::Shape& shape, const std::string& part_name,
                                      const scene::Origin& origin = {});

// The centre line of a terrain's strip, sampled at its element size (the raster's cell without one), each
// point at the ground's elevation, translated: the path of a terrain front. Throws as triangulate().
[[nodiscard]] std::vector<Vec3> terrain_centre_line(const scene::Shape& shape, const std::string& part_name,
                                                    const scene::Origin& origin = {});

// The floor's unit vectors of a chute: down-slope direction, lateral
// direction (to the left looking down-slope) and the normal into the channel.
struct ChuteFrame {
  Vec3 down_slope;
  Vec3 lateral;
  Vec3 normal;
};
[[nodiscard]] ChuteFrame chute_frame(const scene::Shape& shape);

}  // namespace sabo::geometry
