// Boundary particles sampled from structure surfaces (SPH walls).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <iostream>
#include <random>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "libsabo/geometry/surface_sampling.hpp"
#include "libsabo/physics/cell_list.hpp"

using sabo::Aabb;
using sabo::Vec3;
using sabo::geometry::SurfaceMesh;
using sabo::geometry::SurfaceSampling;
using sabo::scene::Shape;

namespace {

SurfaceMesh plane(Vec3 origin, Vec3 normal, Vec3 direction, double length, double width, double element_size) {
  Shape s;
  s.type = Shape::Type::plane;
  s.origin = origin;
  s.normal = normal;
  s.direction = direction;
  s.length = length;
  s.width = width;
  s.element_size = element_size;
  auto mesh = sabo::geometry::triangulate(s, "plane");
  mesh.face_thickness.assign(mesh.face_count(), 0.0);
  return mesh;
}

SurfaceMesh box(Vec3 lo, Vec3 hi, double element_size) {
  Shape s;
  s.type = Shape::Type::box;
  s.box = Aabb{lo, hi};
  s.element_size = element_size;
  return sabo::geometry::triangulate(s, "box");
}

// An open tank [0,1] x [0,1] x [0,1]: floor and four walls, normals into the tank.
SurfaceMesh tank(double element_size) {
  SurfaceMesh mesh = plane({0.5, 0.5, 0}, {0, 0, 1}, {1, 0, 0}, 1, 1, element_size);
  mesh.append(plane({0, 0.5, 0.5}, {1, 0, 0}, {0, 1, 0}, 1, 1, element_size));
  mesh.append(plane({1, 0.5, 0.5}, {-1, 0, 0}, {0, 1, 0}, 1, 1, element_size));
  mesh.append(plane({0.5, 0, 0.5}, {0, 1, 0}, {1, 0, 0}, 1, 1, element_size));
  mesh.append(plane({0.5, 1, 0.5}, {0, -1, 0}, {1, 0, 0}, 1, 1, element_size));
  for (std::size_t n = 0; n < mesh.node_count(); ++n) mesh.node_id[n] = n;
  return mesh;
}

std::vector<Vec3> positions(const SurfaceMesh& mesh, const SurfaceSampling& s) {
  std::vector<Vec3> out;
  for (std::size_t k = 0; k < s.size(); ++k) out.push_back(sabo::geometry::boundary_particle_position(mesh, s, k));
  return out;
}

// Smallest distance between two particles (cell list, exact).
double min_pair_distance(const std::vector<Vec3>& x, double cell) {
  sabo::physics::CellList grid;
  grid.build_points(x, cell);
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < x.size(); ++i) {
    grid.for_each_near(x[i], [&](std::uint32_t j) {
      if (j != i) best = std::min(best, (x[i] - x[j]).norm());
    });
  }
  return best;
}

double distance_to_box(const Vec3& p, const Aabb& b) {
  return (p - p.cwiseMax(b.min).cwiseMin(b.max)).norm();
}

}  // namespace

TEST(SurfaceSampling, FlatPlaneGivesLayersAtSpacingAndCoversTheArea) {
  const double dx = 0.1;
  const std::size_t layers = 3;                                                  // ceil(2 h / dx) with h = 1.3 dx
  const auto mesh = plane({0.5, 0.5, 0}, {0, 0, 1}, {1, 0, 0}, 1.0, 1.0, 0.25);  // 32 triangles
  const auto s = sabo::geometry::sample_surface(mesh, dx, layers);
  const auto x = positions(mesh, s);
  std::cout << "flat plane 1 m x 1 m, dx 0.1, 3 layers: " << s.size() << " particles, expected 300\n";
  EXPECT_EQ(s.size(), 300u);
  const double covered = static_cast<double>(s.size()) / static_cast<double>(layers) * dx * dx;
  std::cout << "area covered per layer: measured " << covered << " m^2 expected 1\n";
  EXPECT_NEAR(covered, 1.0, 1e-12);
  std::array<int, 3> per_layer{};
  for (std::size_t k = 0; k < s.size(); ++k) {
    const int layer = static_cast<int>(std::lround((s.depth[k] / dx) - 0.5));
    ASSERT_GE(layer, 0);
    ASSERT_LT(layer, 3);
    ++per_layer[static_cast<std::size_t>(layer)];
    EXPECT_NEAR(x[k].z(), -(layer + 0.5) * dx, 1e-12);
    EXPECT_TRUE(x[k].x() > 0 && x[k].x() < 1 && x[k].y() > 0 && x[k].y() < 1) << x[k].transpose();
    EXPECT_EQ(s.extension[k], 0);
  }
  for (int n : per_layer) EXPECT_EQ(n, 100);
  const double spacing = min_pair_distance(x, dx);
  std::cout << "nearest neighbour: measured " << spacing << " m expected " << dx << "\n";
  EXPECT_NEAR(spacing, dx, 1e-12);
  EXPECT_DOUBLE_EQ(s.particle_volume(), 1e-3);
}

TEST(SurfaceSampling, ShellLayersStartHalfASpacingBehindItsWettedFace) {
  // A shell 0.02 m thick on the plane z = 0: its front face at z = 0.01, the first layer at 0.01 - dx / 2.
  auto mesh = plane({0, 0, 0}, {0, 0, 1}, {1, 0, 0}, 0.4, 0.4, 0);
  mesh.face_thickness.assign(mesh.face_count(), 0.02);
  const auto s = sabo::geometry::sample_surface(mesh, 0.1, 2);
  EXPECT_EQ(s.size(), 4u * 4u * 2u);
  double shallowest = 1, highest = -1;
  for (double d : s.depth) shallowest = std::min(shallowest, d);
  for (const auto& x : positions(mesh, s)) highest = std::max(highest, x.z());
  std::cout << "shell first layer: depth behind the front face measured " << shallowest << " m expected 0.05; z "
            << highest << " m expected " << 0.01 - 0.05 << "\n";
  EXPECT_NEAR(shallowest, 0.05, 1e-12);
  EXPECT_NEAR(highest, -0.04, 1e-12);
}

TEST(SurfaceSampling, AWallStandingOnAShellsFrontFaceFillsTheCornerBetweenThem) {
  // A shell floor 0.05 m thick, its mid-surface at z = -0.025 (front face z = 0), and a solid wall x = 0 from z = 0
  // up: the corner behind both is filled as between a floor and a wall that meet (no gap for the fluid to leave by).
  const double dx = 0.1;
  SurfaceMesh mesh = plane({0.5, 0.2, -0.025}, {0, 0, 1}, {1, 0, 0}, 1.0, 0.4, 0);
  mesh.face_thickness.assign(mesh.face_count(), 0.05);
  mesh.append(plane({0, 0.2, 0.5}, {1, 0, 0}, {0, 0, 1}, 1.0, 0.4, 0));
  for (std::size_t n = 0; n < mesh.node_count(); ++n) mesh.node_id[n] = n;
  const auto s = sabo::geometry::sample_surface(mesh, dx, 3);
  const auto x = positions(mesh, s);
  std::size_t corner = 0;
  for (const auto& p : x) {
    if (p.x() < 0 && p.z() < 0 && p.y() > 0 && p.y() < 0.4) ++corner;
  }
  // The wedge x in (-0.3, 0), z in (-0.3, 0) behind both faces: 3 x 3 lattice points a row, 4 rows across the
  // faces' width (the corner's ends beyond it are filled too).
  std::cout << "corner fill behind a shell floor and a wall: measured " << corner << " particles expected " << 36
            << "\n";
  EXPECT_EQ(corner, 36u);
  EXPECT_GE(min_pair_distance(x, dx), 0.5 * dx - 1e-12);
}

TEST(SurfaceSampling, SolidBoxHasNoDoubleLayersAtEdgesAndCorners) {
  const double dx = 0.1;
  const auto mesh = box({0, 0, 0}, {1, 1, 1}, 0.5);
  const auto s = sabo::geometry::sample_surface(mesh, dx, 3);
  const auto x = positions(mesh, s);
  // The lattice of every face coincides: the 0.3 m shell inside the box holds 10^3 - 4^3 points.
  std::cout << "box shell: " << s.size() << " particles, expected " << 1000 - 64 << "\n";
  EXPECT_EQ(s.size(), 936u);
  const double spacing = min_pair_distance(x, dx);
  std::cout << "box nearest neighbour: measured " << spacing << " m expected " << dx << "\n";
  EXPECT_NEAR(spacing, dx, 1e-9);
  for (const auto& p : x) EXPECT_TRUE(Aabb({Vec3::Zero(), Vec3::Ones()}).contains(p)) << p.transpose();

  // Not aligned with the lattice (0.95 m sides): still no two particles closer than dx / 2.
  const auto odd = box({0, 0, 0}, {0.95, 0.95, 0.95}, 0);
  const auto so = sabo::geometry::sample_surface(odd, dx, 3);
  const double odd_spacing = min_pair_distance(positions(odd, so), dx);
  const double volume = 0.95 * 0.95 * 0.95 - 0.35 * 0.35 * 0.35;
  std::cout << "0.95 m box: nearest neighbour " << odd_spacing << " m (>= dx/2); particles " << so.size()
            << ", shell volume / dx^3 = " << volume / 1e-3 << "\n";
  EXPECT_GE(odd_spacing, 0.5 * dx - 1e-12);
  EXPECT_NEAR(static_cast<double>(so.size()) * 1e-3, volume, 0.1 * volume);
}

TEST(SurfaceSampling, TankCornersHaveNoGapWithinTheKernelSupportAndNoDoubles) {
  const double dx = 0.1, support = 2.6 * dx;
  const std::size_t layers = 3;
  const auto mesh = tank(0.5);
  const auto s = sabo::geometry::sample_surface(mesh, dx, layers);
  const auto x = positions(mesh, s);
  const Aabb inside{Vec3::Zero(), Vec3::Ones()};
  for (const auto& p : x) EXPECT_FALSE(inside.contains(p)) << "a wall particle inside the tank at " << p.transpose();
  const double spacing = min_pair_distance(x, dx);
  std::cout << "tank nearest neighbour: measured " << spacing << " m expected " << dx << "\n";
  EXPECT_NEAR(spacing, dx, 1e-9);
  // Every lattice point outside the tank, below its rim and within the kernel
  // support of the fluid inside must be a wall particle.
  sabo::physics::CellList grid;
  grid.build_points(x, dx);
  std::size_t missing = 0, expected = 0;
  for (int i = -4; i < 14; ++i) {
    for (int j = -4; j < 14; ++j) {
      for (int k = -4; k < 10; ++k) {
        const Vec3 p((i + 0.5) * dx, (j + 0.5) * dx, (k + 0.5) * dx);
        if (inside.contains(p) || distance_to_box(p, inside) > support) continue;
        ++expected;
        bool found = false;
        grid.for_each_near(p, [&](std::uint32_t q) { found = found || (x[q] - p).norm() < 1e-9; });
        if (!found) ++missing;
      }
    }
  }
  std::cout << "tank: " << s.size() << " particles; lattice points within the support: " << expected << ", missing "
            << missing << " (expected 0)\n";
  EXPECT_EQ(missing, 0u);
}

TEST(SurfaceSampling, ThinSolidLayersDoNotComeOutOfItsFarSide) {
  const auto mesh = box({0, 0, 0}, {1, 1, 0.1}, 0);
  const auto s = sabo::geometry::sample_surface(mesh, 0.05, 3);
  const Aabb solid{Vec3::Zero(), Vec3(1, 1, 0.1)};
  for (const auto& p : positions(mesh, s)) EXPECT_TRUE(solid.contains(p)) << p.transpose();
  EXPECT_GT(s.size(), 0u);
}

TEST(SurfaceSampling, ParticlesFollowTheNodesRigidly) {
  auto mesh = tank(0.5);
  const auto s = sabo::geometry::sample_surface(mesh, 0.1, 3);
  const auto before = positions(mesh, s);
  const Eigen::AngleAxisd rotation(0.3, Vec3(1, 2, 3).normalized());
  const Vec3 shift(0.5, -1.0, 2.0);
  for (auto& node : mesh.node_position) node = rotation * node + shift;
  const auto after = positions(mesh, s);
  double worst = 0;
  for (std::size_t k = 0; k < s.size(); ++k)
    worst = std::max(worst, (after[k] - (rotation * before[k] + shift)).norm());
  std::cout << "rigid motion: worst position error " << worst << " m (expected < 1e-12)\n";
  EXPECT_LT(worst, 1e-12);

  std::vector<Vec3> velocity(mesh.node_count(), Vec3(1, 2, 3)), acceleration(mesh.node_count(), Vec3(0, 0, -2));
  std::vector<std::uint32_t> selection{0, 5, static_cast<std::uint32_t>(s.size() - 1)};
  sabo::physics::BoundaryParticles out;
  sabo::geometry::place_boundary_particles(mesh, s, velocity, acceleration, selection, out);
  ASSERT_EQ(out.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_LT((out.position[i] - after[selection[i]]).norm(), 1e-14);
    EXPECT_LT((out.velocity[i] - Vec3(1, 2, 3)).norm(), 1e-14);
    EXPECT_LT((out.acceleration[i] - Vec3(0, 0, -2)).norm(), 1e-14);
    EXPECT_NEAR(out.normal[i].norm(), 1.0, 1e-14);
    EXPECT_DOUBLE_EQ(out.volume[i], 1e-3);
  }
  // A node velocity that varies over a face is interpolated at the anchor.
  for (std::size_t n = 0; n < mesh.node_count(); ++n) velocity[n] = Vec3(mesh.node_position[n].x(), 0, 0);
  sabo::geometry::place_boundary_particles(mesh, s, velocity, {}, selection, out);
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& t = mesh.triangle[s.face[selection[i]]];
    const auto& w = s.weight[selection[i]];
    const double anchor_x =
        w[0] * mesh.node_position[t[0]].x() + w[1] * mesh.node_position[t[1]].x() + w[2] * mesh.node_position[t[2]].x();
    EXPECT_NEAR(out.velocity[i].x(), anchor_x, 1e-12);
    EXPECT_EQ(out.acceleration[i], Vec3::Zero());
  }
}

TEST(SurfaceSampling, SpreadForcesSumExactlyToTheBoundaryForces) {
  // The tank: corner fills split their force between two faces.
  const auto mesh = tank(0.25);
  const auto s = sabo::geometry::sample_surface(mesh, 0.1, 3);
  std::vector<std::uint32_t> selection;
  for (std::uint32_t k = 0; k < s.size(); k += 2) selection.push_back(k);
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> uniform(-100.0, 100.0);
  std::vector<double> force(3 * selection.size());
  for (double& f : force) f = uniform(random);
  std::vector<double> node_force(3 * mesh.node_count(), 0.0);
  sabo::geometry::spread_boundary_forces(mesh, s, selection, force, node_force);
  Vec3 sum_particles = Vec3::Zero(), sum_nodes = Vec3::Zero();
  double scale = 0;
  for (std::size_t i = 0; i < selection.size(); ++i) {
    sum_particles += Vec3(force[3 * i], force[3 * i + 1], force[3 * i + 2]);
    scale += std::abs(force[3 * i]) + std::abs(force[3 * i + 1]) + std::abs(force[3 * i + 2]);
  }
  for (std::size_t n = 0; n < mesh.node_count(); ++n) {
    sum_nodes += Vec3(node_force[3 * n], node_force[3 * n + 1], node_force[3 * n + 2]);
  }
  const double residual = (sum_nodes - sum_particles).norm() / scale;
  std::cout << "force spreading: sum over nodes " << sum_nodes.transpose() << ", over particles "
            << sum_particles.transpose() << ", relative residual " << residual << " (expected < 1e-14)\n";
  EXPECT_LT(residual, 1e-14);
  // A particle's force stays on its own triangle's nodes.
  std::vector<double> one(3 * mesh.node_count(), 0.0);
  // (A particle that is no corner fill.)
  std::uint32_t plain = 0;
  while (s.extension[plain] != 0) ++plain;
  const std::vector<std::uint32_t> first{plain};
  const std::vector<double> f{1.0, 2.0, 3.0};
  sabo::geometry::spread_boundary_forces(mesh, s, first, f, one);
  const auto& t = mesh.triangle[s.face[first[0]]];
  for (std::size_t n = 0; n < mesh.node_count(); ++n) {
    const bool on_face = n == t[0] || n == t[1] || n == t[2];
    if (!on_face) {
      EXPECT_EQ(Vec3(one[3 * n], one[3 * n + 1], one[3 * n + 2]), Vec3::Zero());
    }
  }
}

TEST(SurfaceSampling, CornerFillsShareTheirForceWithTheFaceTheyFillTheCornerWith) {
  const auto mesh = tank(0.5);
  const auto s = sabo::geometry::sample_surface(mesh, 0.1, 3);
  std::size_t fills = 0, checked = 0;
  for (std::size_t k = 0; k < s.size(); ++k) {
    if (s.extension[k] == 0) {
      EXPECT_EQ(s.partner_face[k], sabo::geometry::kNoFace);
      continue;
    }
    ++fills;
    ASSERT_NE(s.partner_face[k], sabo::geometry::kNoFace);
    const Vec3 na = mesh.face_normal(s.face[k]), nb = mesh.face_normal(s.partner_face[k]);
    // Tank faces meet at right angles: each takes the force along its own normal, and half the rest.
    ASSERT_NEAR(na.dot(nb), 0.0, 1e-12);
    const Vec3 force(-1.0, 0.5, -2.0);
    const auto shares = sabo::geometry::split_boundary_force(mesh, s, k, force);
    const Vec3 edge = na.cross(nb);
    const Vec3 expected_a = force.dot(na) * na + 0.5 * force.dot(edge) * edge;
    EXPECT_LT((shares[0] - expected_a).norm(), 1e-12);
    EXPECT_EQ(shares[0] + shares[1], force);
    ++checked;
  }
  std::cout << "tank: " << fills << " corner fills, each sharing its force with its partner face\n";
  EXPECT_GT(fills, 0u);
  EXPECT_EQ(checked, fills);
  // The floor-wall corner under the x = 0 wall: a push (-1, 0, -1) N loads the floor with
  // (0, 0, -1) and the wall with (-1, 0, 0).
  std::vector<std::uint32_t> selection;
  for (std::uint32_t k = 0; k < s.size(); ++k) {
    const Vec3 x = sabo::geometry::boundary_particle_position(mesh, s, k);
    if (x.x() < 0 && x.z() < 0 && x.y() > 0.2 && x.y() < 0.8) selection.push_back(k);
  }
  ASSERT_FALSE(selection.empty());
  std::vector<double> force;
  for (std::size_t i = 0; i < selection.size(); ++i) force.insert(force.end(), {-1.0, 0.0, -1.0});
  std::vector<double> node_force(3 * mesh.node_count(), 0.0);
  sabo::geometry::spread_boundary_forces(mesh, s, selection, force, node_force);
  Vec3 on_floor = Vec3::Zero(), on_wall = Vec3::Zero();
  for (std::size_t n = 0; n < mesh.node_count(); ++n) {
    const Vec3 f(node_force[3 * n], node_force[3 * n + 1], node_force[3 * n + 2]);
    // tank(): the floor's nodes come first (9 for element size 0.5), then the x = 0 wall's.
    (n < 9 ? on_floor : on_wall) += f;
  }
  const double count = static_cast<double>(selection.size());
  std::cout << "corner under the x = 0 wall: floor gets " << on_floor.transpose() / count << " N, wall "
            << on_wall.transpose() / count << " N per particle (expected 0 0 -1 and -1 0 0)\n";
  EXPECT_LT((on_floor - Vec3(0, 0, -count)).norm(), 1e-9);
  EXPECT_LT((on_wall - Vec3(-count, 0, 0)).norm(), 1e-9);
}

TEST(SurfaceSampling, SlopedChuteWithEndWallIsSampledBehindItsFacesWithoutDoubles) {
  Shape shape;
  shape.type = Shape::Type::chute;
  shape.origin = Vec3(0, 0, 2);
  shape.direction = Vec3(1, 0, 0);
  shape.length = 2;
  shape.width = 0.6;
  shape.slope_deg = 25;
  shape.wall_height = 0.4;
  shape.end_wall_height = 0.4;
  shape.element_size = 0.5;
  const auto mesh = sabo::geometry::triangulate(shape, "chute");
  const double dx = 0.05;
  const auto s = sabo::geometry::sample_surface(mesh, dx, 3);
  const auto x = positions(mesh, s);
  // Inside the channel: in front of the floor, between the side walls, before the end wall.
  const auto frame = sabo::geometry::chute_frame(shape);
  std::size_t inside = 0;
  for (const auto& p : x) {
    const Vec3 d = p - shape.origin;
    const double along = d.dot(frame.down_slope), across = d.dot(frame.lateral), up = d.dot(frame.normal);
    if (up > 1e-9 && std::abs(across) < 0.5 * shape.width - 1e-9 && along < shape.length - 1e-9 && along > 0 &&
        up < shape.wall_height) {
      ++inside;
    }
  }
  const double spacing = min_pair_distance(x, dx);
  std::cout << "chute: " << s.size() << " particles, " << inside << " inside the channel (expected 0), nearest "
            << spacing << " m (dx " << dx << ")\n";
  EXPECT_EQ(inside, 0u);
  EXPECT_GE(spacing, 0.5 * dx - 1e-12);
}

TEST(SurfaceSampling, RefusesBadArguments) {
  const auto mesh = box({0, 0, 0}, {1, 1, 1}, 0);
  EXPECT_THROW((void)sabo::geometry::sample_surface(mesh, 0.0, 3), sabo::Error);
  EXPECT_THROW((void)sabo::geometry::sample_surface(mesh, 0.1, 0), sabo::Error);
}
