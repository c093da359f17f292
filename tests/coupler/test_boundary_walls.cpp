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
