// BoundaryWalls on its own: moving nodes carry the wall particles, their
// velocity and acceleration; selection near the fluid; forces of the last two
// selections back onto the nodes.
#include <gtest/gtest.h>

#include <iostream>

#include "coupler/contact/boundary_walls.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/primitives.hpp"

using namespace sabo;

namespace {

geometry::SurfaceMesh floor_mesh() {
  scene::Shape shape;
  shape.type = scene::Shape::Type::plane;
  shape.length = 1;
  shape.width = 1;
  shape.element_size = 0.5;
  return geometry::triangulate(shape, "floor");
}

std::vector<double> flat(const std::vector<Vec3>& v) {
  std::vector<double> out;
  for (const auto& x : v) out.insert(out.end(), {x.x(), x.y(), x.z()});
  return out;
}

}  // namespace

TEST(BoundaryWalls, FollowMovingNodesWithTheirVelocityAndAcceleration) {
  const double dx = 0.1, support = 0.26;
  coupler::BoundaryWalls walls(dx, support);
  auto mesh = floor_mesh();
  walls.set_surface(mesh);
  EXPECT_EQ(walls.layers(), 3u);
  EXPECT_EQ(walls.sampling().size(), 300u);

  const std::vector<double> fluid{0.0, 0.0, 0.05};
  walls.select_near(fluid);
  const auto first = walls.selected().position;
  ASSERT_FALSE(first.empty());
  for (const auto& v : walls.selected().velocity) EXPECT_EQ(v, Vec3::Zero());

  // The floor rises by 0.1 m at 1 m/s, then its velocity becomes 2 m/s over dt = 0.5 s: 2 m/s^2.
  std::vector<Vec3> position = mesh.node_position;
  for (auto& p : position) p.z() += 0.1;
  const std::vector<Vec3> v1(mesh.node_count(), Vec3(0, 0, 1)), v2(mesh.node_count(), Vec3(0, 0, 2));
  walls.update_nodes(flat(position), flat(v1), 0.5);
  walls.update_nodes(flat(position), flat(v2), 0.5);
  walls.select_near(std::vector<double>{0.0, 0.0, 0.15});
  const auto& moved = walls.selected();
  ASSERT_EQ(moved.size(), first.size());
  for (std::size_t i = 0; i < moved.size(); ++i) {
    EXPECT_LT((moved.position[i] - (first[i] + Vec3(0, 0, 0.1))).norm(), 1e-14);
    EXPECT_LT((moved.velocity[i] - Vec3(0, 0, 2)).norm(), 1e-14);
    EXPECT_LT((moved.acceleration[i] - Vec3(0, 0, 2)).norm(), 1e-12);
  }
  std::cout << "wall acceleration: measured " << moved.acceleration[0].z() << " m/s^2 expected 2\n";
  const std::vector<Aabb> regions = walls.interest_regions();
  ASSERT_FALSE(regions.empty());
  for (const Aabb& box : regions) EXPECT_LT(box.max.z(), 0.1 + 2 * support + 1e-12);
}

TEST(BoundaryWalls, SpreadsTheForcesOfEitherOfTheLastTwoSelections) {
  coupler::BoundaryWalls walls(0.1, 0.26);
  walls.set_surface(floor_mesh());
  walls.select_near(std::vector<double>{-0.5, 0.0, 0.05});  // at the edge: fewer near
  const std::size_t before = walls.selection().size();
  walls.select_near(std::vector<double>{0.0, 0.0, 0.05});
  const std::size_t last = walls.selection().size();
  ASSERT_NE(before, last);
  EXPECT_EQ(walls.selection(2).size(), before);

  std::vector<double> node_force;
  std::vector<Vec3> part_force;
  const std::vector<double> on_before(3 * before, -1.0);
  walls.spread(on_before, 2, node_force, part_force);
  Vec3 sum = Vec3::Zero();
  for (std::size_t i = 0; i + 2 < node_force.size(); i += 3)
    sum += Vec3(node_force[i], node_force[i + 1], node_force[i + 2]);
  const double n = static_cast<double>(before);
  std::cout << "spread: node forces sum to " << sum.transpose() << " N, expected " << -n << " each\n";
  EXPECT_LT((sum - Vec3(-n, -n, -n)).norm(), 1e-12);
  ASSERT_EQ(part_force.size(), 1u);
  EXPECT_LT((part_force[0] - Vec3(-n, -n, -n)).norm(), 1e-12);
  // The count must match the selection it answers.
  EXPECT_THROW(walls.spread(on_before, 1, node_force, part_force), ProtocolError);
  // Empty: nothing, no error.
  walls.spread({}, 1, node_force, part_force);
  for (double f : node_force) EXPECT_EQ(f, 0.0);
}

// Issue 17, item 2: a channel periodic along y whose floor meets an end wall. The floor/wall corner's fill
// spilled past the seams (a wall particle at y = -0.015 m stopped the sph_solver at step 0); with the span
// given, every wall particle lies inside it, and the lattice inside is whole.
TEST(BoundaryWalls, PeriodicSpanKeepsTheCornerFillInsideTheSeams) {
  const double dx = 0.01, support = 0.03, width = 0.1;
  scene::Shape floor;
  floor.type = scene::Shape::Type::plane;
  floor.origin = Vec3(0.25, 0.5 * width, 0);
  floor.length = 0.5;
  floor.width = width;
  floor.element_size = 0.05;
  scene::Shape end = floor;
  end.origin = Vec3(0.5, 0.5 * width, 0.05);
  end.normal = Vec3(-1, 0, 0);
  end.direction = Vec3(0, 0, 1);
  end.length = 0.1;
  geometry::SurfaceMesh mesh = geometry::triangulate(floor, "floor");
  geometry::SurfaceMesh wall = geometry::triangulate(end, "end_wall");
  for (auto& id : wall.node_id) id += 1000;  // ids unique across the parts, as the fem_solver numbers them
  mesh.append(wall);
  const auto outside = [&](const coupler::BoundaryWalls& walls) {
    std::size_t count = 0;
    for (std::size_t k = 0; k < walls.sampling().size(); ++k) {
      const double y = geometry::boundary_particle_position(walls.surface(), walls.sampling(), k).y();
      count += (y < 0 || y >= width) ? 1 : 0;
    }
    return count;
  };
  coupler::BoundaryWalls open(dx, support);
  open.set_surface(mesh);
  coupler::BoundaryWalls periodic(dx, support, {{1, 0.0, width}});
  periodic.set_surface(mesh);
  std::cout << "wall particles outside y in [0, " << width << "): " << outside(open) << " of " << open.sampling().size()
            << " without the span, " << outside(periodic) << " of " << periodic.sampling().size() << " with it\n";
  EXPECT_GT(outside(open), 0u);  // the failure as reported
  EXPECT_EQ(outside(periodic), 0u);
  EXPECT_EQ(periodic.sampling().size(), open.sampling().size() - outside(open));
  // Inside the span every lattice column across y is there: 10 per row, as the fluid's.
  std::size_t floor_layer = 0;
  for (std::size_t k = 0; k < periodic.sampling().size(); ++k) {
    const Vec3 x = geometry::boundary_particle_position(periodic.surface(), periodic.sampling(), k);
    if (std::abs(x.z() + 0.5 * dx) < 1e-9 && std::abs(x.x() - 0.105) < 1e-9) ++floor_layer;
  }
  EXPECT_EQ(floor_layer, 10u);
}

TEST(BoundaryWalls, MarkTheParticlesOfFreeSlipPartsOnly) {
  // A floor and a raised plate of another name: only the floor's particles slip (sph.free_slip_walls).
  geometry::SurfaceMesh surface = floor_mesh();
  geometry::SurfaceMesh plate = floor_mesh();
  plate.make_single_part("plate");
  for (auto& p : plate.node_position) p.z() += 1.0;
  for (auto& id : plate.node_id) id += surface.node_count();  // ids unique over the surface
  surface.append(plate);
  coupler::BoundaryWalls walls(0.1, 0.26, {}, {"floor"});
  walls.set_surface(surface);
  walls.select_near(std::vector<double>{0.0, 0.0, 0.05, 0.0, 0.0, 0.95});
  const auto& selected = walls.selected();
  ASSERT_EQ(selected.free_slip.size(), selected.size());
  std::size_t slipping = 0, below = 0;
  for (std::size_t i = 0; i < selected.size(); ++i) {
    const bool on_floor = selected.position[i].z() < 0.5;
    below += on_floor ? 1 : 0;
    slipping += selected.free_slip[i];
    EXPECT_EQ(selected.free_slip[i], on_floor ? 1 : 0) << "particle " << i;
  }
  std::cout << "free-slip particles: measured " << slipping << ", expected " << below << " (the floor's of "
            << selected.size() << ")\n";
  EXPECT_GT(below, 0u);
  EXPECT_LT(below, selected.size());

  coupler::BoundaryWalls no_slip(0.1, 0.26);
  no_slip.set_surface(surface);
  no_slip.select_near(std::vector<double>{0.0, 0.0, 0.05});
  EXPECT_TRUE(no_slip.selected().free_slip.empty()) << "no free-slip part: the flags stay empty (all no-slip)";
}
