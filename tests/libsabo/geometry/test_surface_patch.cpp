// surface_patch(): the area and normal of a part's surface inside a sensor box.
#include <gtest/gtest.h>

#include <iostream>

#include "libsabo/geometry/primitives.hpp"
#include "libsabo/geometry/surface_patch.hpp"

namespace sabo::geometry {
namespace {

// A 2 m x 1 m plane at z = 0, normal +z, centred at the origin, in 8 x 4 squares.
SurfaceMesh plate() {
  scene::Shape shape;
  shape.type = scene::Shape::Type::plane;
  shape.origin = Vec3::Zero();
  shape.normal = Vec3(0, 0, 1);
  shape.direction = Vec3(1, 0, 0);
  shape.length = 2.0;
  shape.width = 1.0;
  shape.element_size = 0.25;
  return triangulate(shape, "plate");
}

TEST(SurfacePatch, AreaOfTheSurfaceInsideABox) {
  const SurfaceMesh mesh = plate();
  const SurfacePatch whole = surface_patch(mesh, 0, std::nullopt);
  EXPECT_NEAR(whole.area, 2.0, 1e-12);
  EXPECT_NEAR((whole.mean_normal() - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);
  // A 10 mm transducer across element edges and a diagonal; a box over the edge of the plate.
  const struct {
    Aabb box;
    double area;
  } cases[] = {
      {Aabb{Vec3(0.245, -0.005, -0.001), Vec3(0.255, 0.005, 0.001)}, 1e-4},
      {Aabb{Vec3(0.1, 0.1, -0.1), Vec3(0.2, 0.15, 0.1)}, 0.005},
      {Aabb{Vec3(0.9, -1.0, -0.1), Vec3(1.5, 1.0, 0.1)}, 0.1},
  };
  for (const auto& c : cases) {
    const SurfacePatch patch = surface_patch(mesh, 0, c.box);
    std::cout << "box [" << c.box.min.transpose() << "] - [" << c.box.max.transpose() << "]: area measured "
              << patch.area << " expected " << c.area << "\n";
    EXPECT_NEAR(patch.area, c.area, 1e-12);
    EXPECT_NEAR((patch.mean_normal() - Vec3(0, 0, 1)).norm(), 0.0, 1e-12);
  }
  const SurfacePatch missed = surface_patch(mesh, 0, Aabb{Vec3(0, 0, 0.01), Vec3(0.1, 0.1, 0.02)});
  EXPECT_EQ(missed.area, 0.0);
  EXPECT_NEAR(missed.part_bounds.max.x(), 1.0, 1e-12);
}

TEST(SurfacePatch, ClippedTriangle) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_NEAR(clipped_triangle_area(a, b, c, Aabb{Vec3(-1, -1, -1), Vec3(2, 2, 1)}), 0.5, 1e-15);
  // The square [0, 0.5]^2 lies inside the triangle; [0.5, 1]^2 holds only its corner (0.5, 0.5): area 0.
  EXPECT_NEAR(clipped_triangle_area(a, b, c, Aabb{Vec3(0, 0, -1), Vec3(0.5, 0.5, 1)}), 0.25, 1e-15);
  EXPECT_NEAR(clipped_triangle_area(a, b, c, Aabb{Vec3(0.5, 0.5, -1), Vec3(1, 1, 1)}), 0.0, 1e-15);
  // The triangle's half x > 0.5: the corner triangle (0.5, 0), (1, 0), (0.5, 0.5).
  EXPECT_NEAR(clipped_triangle_area(a, b, c, Aabb{Vec3(0.5, -1, -1), Vec3(2, 2, 1)}), 0.125, 1e-15);
}

}  // namespace
}  // namespace sabo::geometry
