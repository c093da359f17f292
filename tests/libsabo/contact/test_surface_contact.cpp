// Particle-surface penalty contact (paper eqs. 3-6): hand-computed forces for
// face, edge and vertex contacts, eq. 6 stiffness, friction, one contact per
// smooth surface, Newton's third law, search and determinism. Over 800 lines as
// one concept: each case is computed by hand beside the contact's result.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <iostream>
#include <numbers>
#include <random>

#include "contact_fixtures.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/covering_boxes.hpp"
#include "tests/support/measure.hpp"

namespace sabo::contact {
namespace {

using test::Cloud;
using test::explicit_stiffness;
using test::MeshBuilder;
using test::uniform;
using test::vec_at;

using sabo::testing::expect_vec_absolute;

// ------------------------------------------------------------ geometry ------

TEST(ClosestPoint, FaceEdgeVertexRegions) {
  const Vec3 a(0, 0, 0), b(4, 0, 0), c(0, 4, 0);
  auto face = closest_point_on_triangle(Vec3(1, 1, 0.7), a, b, c);
  EXPECT_EQ(face.feature, Feature::face);
  expect_vec_absolute("face point", face.point, Vec3(1, 1, 0), 1e-15);
  EXPECT_NEAR(face.weight[0], 0.5, 1e-15);
  EXPECT_NEAR(face.weight[1], 0.25, 1e-15);
  EXPECT_NEAR(face.weight[2], 0.25, 1e-15);

  auto edge = closest_point_on_triangle(Vec3(2, -0.3, 0.3), a, b, c);
  EXPECT_EQ(edge.feature, Feature::edge);
  EXPECT_EQ(edge.index, 0);  // ab
  expect_vec_absolute("edge point", edge.point, Vec3(2, 0, 0), 1e-15);
  EXPECT_NEAR(edge.weight[0], 0.5, 1e-15);
  EXPECT_NEAR(edge.weight[1], 0.5, 1e-15);
  EXPECT_EQ(edge.weight[2], 0.0);

  auto hypotenuse = closest_point_on_triangle(Vec3(3, 3, 0), a, b, c);
  EXPECT_EQ(hypotenuse.feature, Feature::edge);
  EXPECT_EQ(hypotenuse.index, 1);  // bc
  expect_vec_absolute("hypotenuse point", hypotenuse.point, Vec3(2, 2, 0), 1e-14);

  auto vertex = closest_point_on_triangle(Vec3(-1, -0.5, 2), a, b, c);
  EXPECT_EQ(vertex.feature, Feature::vertex);
  EXPECT_EQ(vertex.index, 0);
  EXPECT_EQ(vertex.point, a);
  auto vertex_c = closest_point_on_triangle(Vec3(-0.1, 5, -1), a, b, c);
  EXPECT_EQ(vertex_c.feature, Feature::vertex);
  EXPECT_EQ(vertex_c.index, 2);

  // A point exactly over an edge is a face point (within kFaceTolerance).
  auto on_edge = closest_point_on_triangle(Vec3(2, 0, 1), a, b, c);
  EXPECT_EQ(on_edge.feature, Feature::face);
}

TEST(ClosestPoint, MatchesDenseSampling) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    const Vec3 p(u(rng), u(rng), u(rng));
    const auto cp = closest_point_on_triangle(p, a, b, c);
    double best = std::numeric_limits<double>::infinity();
    const int n = 200;
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        const double s = double(i) / n, t = double(j) / n;
        best = std::min(best, (p - (a + s * (b - a) + t * (c - a))).norm());
      }
    }
    const double measured = (p - cp.point).norm();
    EXPECT_LE(measured, best + 1e-12);
    EXPECT_GE(measured, best - 0.03);  // sampling resolution
    const Vec3 from_weights = cp.weight[0] * a + cp.weight[1] * b + cp.weight[2] * c;
    EXPECT_LE((from_weights - cp.point).norm(), 1e-12);
    EXPECT_NEAR(cp.weight[0] + cp.weight[1] + cp.weight[2], 1.0, 1e-15);
  }
}

// ------------------------------------------------- hand-computed forces ------

// Triangle (0,0,0), (4,0,0), (0,4,0): area 8 m^2, longest edge 4 sqrt 2 m.
MeshBuilder single_triangle(double thickness, double element_volume) {
  MeshBuilder b;
  const auto part = b.part("wall");
  const auto a = b.node({0, 0, 0});
  const auto bb = b.node({4, 0, 0});
  const auto c = b.node({0, 4, 0});
  b.triangle(a, bb, c, part, thickness, 1e9, element_volume);
  return b;
}

scene::SurfaceContact eq6_settings(double friction = 0.0, double zeta_n = 0.0, double zeta_t = 0.0) {
  scene::SurfaceContact s;
  s.penalty_scale = 0.1;
  s.friction = friction;
  s.normal_damping_ratio = zeta_n;
  s.tangential_damping_ratio = zeta_t;
  return s;
}

TEST(SurfaceContact, Eq6StiffnessShellAndSolid) {
  SurfaceContact shell({"boulders"}, uniform(eq6_settings()));
  shell.set_surface(single_triangle(0.0, 0.0).mesh());
  const double k_shell = 0.1 * 1e9 * 8.0 / (4.0 * std::sqrt(2.0));
  std::cout << "shell k_n: measured " << shell.face_stiffness(0, 0) << " expected " << k_shell << "\n";
  EXPECT_NEAR(shell.face_stiffness(0, 0), k_shell, 1e-6 * k_shell);

  SurfaceContact solid({"boulders"}, uniform(eq6_settings()));
  solid.set_surface(single_triangle(0.0, 16.0).mesh());
  const double k_solid = 0.1 * 1e9 * 64.0 / 16.0;
  std::cout << "solid k_n: measured " << solid.face_stiffness(0, 0) << " expected " << k_solid << "\n";
  EXPECT_NEAR(solid.face_stiffness(0, 0), k_solid, 1e-6 * k_solid);

  SurfaceContact fixed({"boulders"}, uniform(explicit_stiffness(3e7)));
  fixed.set_surface(single_triangle(0.0, 16.0).mesh());
  EXPECT_EQ(fixed.face_stiffness(0, 0), 3e7);
}

TEST(SurfaceContact, FaceContactSolidWithDamping) {
  SurfaceContact contact({"boulders"}, uniform(eq6_settings(0.3, 0.5, 0.0)));
  auto mesh = single_triangle(0.0, 16.0);
  contact.set_surface(mesh.mesh());
  Cloud cloud;
  const double mass = 500.0;
  cloud.add({1, 1, 0.45}, 0.5, mass, {0, 0, -2.0});
  ContactOutput out;
  contact.compute(cloud.view(), 1e-5, out);
  const double k = 4e8, overlap = 0.05;
  const double c_n = 2 * 0.5 * std::sqrt(k * mass);
  const double expected = k * overlap + c_n * 2.0;
  ASSERT_EQ(out.contact_count, 1u);
  EXPECT_EQ(contact.contacts()[0].feature, Feature::face);
  expect_vec_absolute("solid face force", vec_at(out.particle_force, 0), Vec3(0, 0, expected), 1e-6 * expected);
  expect_vec_absolute("solid face torque", vec_at(out.particle_torque, 0), Vec3::Zero(), 1e-6);
  // Reaction on the nodes by the weights (0.5, 0.25, 0.25) of (1, 1).
  expect_vec_absolute("node a", vec_at(out.node_force, 0), Vec3(0, 0, -0.5 * expected), 1e-6 * expected);
  expect_vec_absolute("node b", vec_at(out.node_force, 1), Vec3(0, 0, -0.25 * expected), 1e-6 * expected);
  expect_vec_absolute("node c", vec_at(out.node_force, 2), Vec3(0, 0, -0.25 * expected), 1e-6 * expected);
  EXPECT_NEAR(out.elastic_energy, 0.5 * k * overlap * overlap, 1e-9 * k);
  EXPECT_EQ(out.max_contact_stiffness, k);
  EXPECT_EQ(out.min_contact_mass, mass);
  expect_vec_absolute("part force", out.part_force[0], Vec3(0, 0, -expected), 1e-6 * expected);
  expect_vec_absolute("part force from boulders", out.force_on_part(0, 0), Vec3(0, 0, -expected), 1e-6 * expected);
}

TEST(SurfaceContact, FaceContactShellThicknessTwoSided) {
  SurfaceContact contact({"boulders"}, uniform(eq6_settings()));
  contact.set_surface(single_triangle(0.2, 0.0).mesh());
  const double k = 0.1 * 1e9 * 8.0 / (4.0 * std::sqrt(2.0));
  Cloud cloud;
  cloud.add({1, 1, 0.45}, 0.5);   // front: overlap 0.5 + 0.1 - 0.45
  cloud.add({2, 1, -0.45}, 0.5);  // back side of the shell: pushed to the back
  cloud.add({1, 2, 0.61}, 0.5);   // just out of reach (0.6)
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 2u);
  expect_vec_absolute("shell front", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.15), 1e-6 * k);
  expect_vec_absolute("shell back", vec_at(out.particle_force, 1), Vec3(0, 0, -k * 0.15), 1e-6 * k);
  expect_vec_absolute("shell out of reach", vec_at(out.particle_force, 2), Vec3::Zero(), 0);
}

TEST(SurfaceContact, FaceContactBehindOneSidedFace) {
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(1e6)));
  contact.set_surface(single_triangle(0.0, 0.0).mesh());
  Cloud cloud;
  cloud.add({1, 1, -0.1}, 0.5);   // sunk below the plane: still pushed up, overlap 0.6
  cloud.add({1, 2, -0.55}, 0.5);  // deeper than its radius: ignored
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 1u);
  expect_vec_absolute("behind the face", vec_at(out.particle_force, 0), Vec3(0, 0, 1e6 * 0.6), 1e-6);
  expect_vec_absolute("too deep behind", vec_at(out.particle_force, 1), Vec3::Zero(), 0);
}

TEST(SurfaceContact, EdgeAndVertexContacts) {
  for (const double thickness : {0.0, 0.2}) {
    SurfaceContact contact({"boulders"}, uniform(eq6_settings()));
    auto mesh = single_triangle(thickness, 0.0);
    contact.set_surface(mesh.mesh());
    const double k = 0.1 * 1e9 * 8.0 / (4.0 * std::sqrt(2.0));
    Cloud cloud;
    cloud.add({2, -0.3, 0.3}, 0.5);     // edge ab at (2, 0, 0)
    cloud.add({-0.3, -0.3, 0.3}, 0.6);  // vertex a
    ContactOutput out;
    contact.compute(cloud.view(), 0.0, out);
    ASSERT_EQ(out.contact_count, 2u);
    EXPECT_EQ(contact.contacts()[0].feature, Feature::edge);
    EXPECT_EQ(contact.contacts()[1].feature, Feature::vertex);
    const double d_edge = std::sqrt(0.18), d_vertex = std::sqrt(0.27);
    const Vec3 f_edge = k * (0.5 + thickness / 2 - d_edge) * Vec3(0, -0.3, 0.3) / d_edge;
    const Vec3 f_vertex = k * (0.6 + thickness / 2 - d_vertex) * Vec3(-0.3, -0.3, 0.3) / d_vertex;
    const std::string t = " (thickness " + std::to_string(thickness) + ")";
    expect_vec_absolute("edge force" + t, vec_at(out.particle_force, 0), f_edge, 1e-6 * k);
    expect_vec_absolute("vertex force" + t, vec_at(out.particle_force, 1), f_vertex, 1e-6 * k);
    // Edge reaction split half-half between a and b; the vertex's all on a.
    expect_vec_absolute("node a reaction" + t, vec_at(out.node_force, 0), -0.5 * f_edge - f_vertex, 1e-6 * k);
    expect_vec_absolute("node b reaction" + t, vec_at(out.node_force, 1), -0.5 * f_edge, 1e-6 * k);
    expect_vec_absolute("node c reaction" + t, vec_at(out.node_force, 2), Vec3::Zero(), 1e-6 * k);
    // Torque lever -r n: a purely normal force gives no torque.
    EXPECT_LE(vec_at(out.particle_torque, 0).norm(), 1e-6 * k);
  }
}

// ------------------------------------------------------------- friction ------

TEST(SurfaceContact, TangentialStickThenSlip) {
  const double k = 1e6, mass = 10.0, dt = 1e-3;
  scene::SurfaceContact settings = explicit_stiffness(k, 0.5);
  SurfaceContact contact({"boulders"}, uniform(settings));
  MeshBuilder b;
  b.grid({-2, -2, 0}, 4, 4, 1.0, b.part("floor"));
  contact.set_surface(b.mesh());
  Cloud cloud;
  const double speed = 0.01;  // m/s along x; the sphere does not move in this test
  cloud.add({0.3, 0.2, 0.49}, 0.5, mass, {speed, 0, 0});
  ContactOutput out;
  const double normal = k * 0.01;  // 1e4 N, Coulomb limit 5e3 N
  for (int step = 1; step <= 3; ++step) {
    contact.compute(cloud.view(), dt, out);
    const Vec3 expected(-k * speed * dt * step, 0, normal);
    expect_vec_absolute("stick, step " + std::to_string(step), vec_at(out.particle_force, 0), expected, 1e-6);
    EXPECT_FALSE(contact.contacts()[0].sliding);
    // Torque on the sphere from the tangential force at the lever -r n.
    const Vec3 torque = Vec3(0, 0, -0.5).cross(expected);
    expect_vec_absolute("stick torque", vec_at(out.particle_torque, 0), torque, 1e-6);
  }
  // Fast slip: the tangential force is capped at mu F_n.
  cloud.velocity[0] = 10.0;
  contact.compute(cloud.view(), dt, out);
  expect_vec_absolute("slip (Coulomb cap)", vec_at(out.particle_force, 0), Vec3(-0.5 * normal, 0, normal), 1e-6);
  EXPECT_TRUE(contact.contacts()[0].sliding);
  EXPECT_GT(out.dissipated_power, 0.0);
  // Contact ends: the spring is dropped.
  EXPECT_EQ(contact.history_size(), 1u);
  cloud.move(0, {0.3, 0.2, 0.6});
  contact.compute(cloud.view(), dt, out);
  EXPECT_EQ(out.contact_count, 0u);
  EXPECT_EQ(contact.history_size(), 0u);
}

TEST(SurfaceContact, SpinGivesContactPointVelocity) {
  // A sphere spinning about y on a floor: its contact point moves at -r w x.
  const double k = 1e6, dt = 1e-3, r = 0.5, w = 2.0;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k, 1.0)));
  MeshBuilder b;
  b.grid({-2, -2, 0}, 2, 2, 2.0, b.part("floor"));
  contact.set_surface(b.mesh());
  Cloud cloud;
  cloud.add({0.3, 0.2, 0.49}, r, 10.0, Vec3::Zero(), {0, w, 0});
  ContactOutput out;
  contact.compute(cloud.view(), dt, out);
  const Vec3 expected(k * r * w * dt, 0, k * 0.01);  // spring stretched by -r w dt along x, pulls back +x
  expect_vec_absolute("spin friction", vec_at(out.particle_force, 0), expected, 1e-6);
  expect_vec_absolute("spin torque", vec_at(out.particle_torque, 0), Vec3(0, 0, -r).cross(expected), 1e-6);
}

TEST(SurfaceContact, MovingSurfaceVelocity) {
  // The floor moves at the sphere's speed: no relative motion, no tangential force.
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k, 1.0)));
  MeshBuilder b;
  b.grid({-2, -2, 0}, 2, 2, 2.0, b.part("floor"));
  contact.set_surface(b.mesh());
  std::vector<double> position, velocity;
  for (const Vec3& p : b.mesh().node_position) {
    for (int a = 0; a < 3; ++a) position.push_back(p[a]);
    velocity.insert(velocity.end(), {0.3, 0.0, -0.1});
  }
  contact.update_nodes(position, velocity);
  Cloud cloud;
  cloud.add({0.3, 0.2, 0.49}, 0.5, 10.0, {0.3, 0.0, -0.1});
  ContactOutput out;
  contact.compute(cloud.view(), 1e-3, out);
  expect_vec_absolute("co-moving floor", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.01), 1e-9);
}

// ------------------------------------------ one contact per smooth surface ---

TEST(SurfaceContact, SharedEdgeOfTwoCoplanarTriangles) {
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  b.grid({-1, -1, 0}, 1, 1, 2.0, b.part("floor"));  // diagonal from (-1,-1) to (1,1)
  contact.set_surface(b.mesh());
  // Rolling across the diagonal x = y, including exactly on it and 1e-13 off it.
  std::vector<double> offsets{-1e-2, -1e-3, -1e-6, -1e-13, 0.0, 1e-13, 1e-6, 1e-3, 1e-2};
  double max_deviation = 0;
  for (double offset : offsets) {
    Cloud cloud;
    cloud.add({0.2 + offset, 0.2 - offset, 0.45}, 0.5);
    ContactOutput out;
    contact.compute(cloud.view(), 0.0, out);
    EXPECT_EQ(out.contact_count, 1u) << "offset " << offset;
    max_deviation = std::max(max_deviation, (vec_at(out.particle_force, 0) - Vec3(0, 0, k * 0.05)).norm());
  }
  std::cout << "shared edge: largest deviation from the single-plane force " << max_deviation << " N of " << k * 0.05
            << " N\n";
  EXPECT_LE(max_deviation, 1e-9 * k * 0.05);
}

TEST(SurfaceContact, SharedVertexOfSixTriangles) {
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  const auto part = b.part("floor");
  const auto centre = b.node({0, 0, 0});
  std::vector<std::uint32_t> rim;
  for (int i = 0; i < 6; ++i) {
    const double angle = i * std::numbers::pi / 3;
    rim.push_back(b.node({2 * std::cos(angle), 2 * std::sin(angle), 0}));
  }
  for (int i = 0; i < 6; ++i)
    b.triangle(centre, rim[static_cast<std::size_t>(i)], rim[static_cast<std::size_t>((i + 1) % 6)], part);
  contact.set_surface(b.mesh());
  for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(1e-13, -1e-13, 0), Vec3(-1e-9, 0, 0), Vec3(0.01, 0.003, 0)}) {
    Cloud cloud;
    cloud.add(Vec3(0, 0, 0.45) + offset, 0.5);
    ContactOutput out;
    contact.compute(cloud.view(), 0.0, out);
    EXPECT_EQ(out.contact_count, 1u);
    expect_vec_absolute("six-triangle vertex", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.05), 1e-9);
    expect_vec_absolute("six-triangle vertex reaction",
                        vec_at(out.node_force, centre) + vec_at(out.node_force, rim[0]) +
                            vec_at(out.node_force, rim[1]) + vec_at(out.node_force, rim[2]) +
                            vec_at(out.node_force, rim[3]) + vec_at(out.node_force, rim[4]) +
                            vec_at(out.node_force, rim[5]),
                        Vec3(0, 0, -k * 0.05), 1e-9);
  }
}

TEST(SurfaceContact, LargeSphereOnFineMeshIsOnePlane) {
  // Triangles much smaller than the sphere: one contact everywhere, force continuous.
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  b.grid({-1, -1, 0}, 20, 20, 0.1, b.part("floor"));
  contact.set_surface(b.mesh());
  Cloud cloud;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  for (int i = 0; i < 200; ++i) cloud.add({u(rng), u(rng), 0.45}, 0.5);
  // Also on grid nodes and edges exactly, and rolling along x in small steps.
  cloud.add({0.0, 0.0, 0.45}, 0.5);
  cloud.add({0.1, 0.05, 0.45}, 0.5);
  cloud.add({0.05, 0.05, 0.45}, 0.5);
  for (int i = 0; i <= 100; ++i) cloud.add({0.001 * i, 0.0301, 0.45}, 0.5);
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, cloud.size());
  double max_deviation = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    max_deviation = std::max(max_deviation, (vec_at(out.particle_force, i) - Vec3(0, 0, k * 0.05)).norm());
  }
  std::cout << "fine mesh: " << out.contact_count << " contacts for " << cloud.size()
            << " spheres; largest deviation from k delta: " << max_deviation << " N of " << k * 0.05 << " N\n";
  EXPECT_LE(max_deviation, 1e-9 * k * 0.05);
}

TEST(SurfaceContact, UnweldedMeshStillOneContact) {
  // Every triangle with its own nodes (an STL file): the shared edge is found by position.
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  const auto part = b.part("floor");
  b.triangle(Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), part);
  b.triangle(Vec3(-1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0), part);
  contact.set_surface(b.mesh());
  for (double offset : {-1e-3, -1e-7, 0.0, 1e-7, 1e-3}) {
    Cloud cloud;
    cloud.add({0.2 + offset, 0.2 - offset, 0.45}, 0.5);
    ContactOutput out;
    contact.compute(cloud.view(), 0.0, out);
    EXPECT_EQ(out.contact_count, 1u);
    expect_vec_absolute("unwelded shared edge", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.05), 1e-9);
  }
}

TEST(SurfaceContact, ConvexEdgeOfABox) {
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  b.box({0, 0, 0}, {1, 1, 1}, b.part("block"), 1.0);
  contact.set_surface(b.mesh());
  Cloud cloud;
  cloud.add({1.3, 0.4, 1.2}, 0.5);    // beyond the edge x = 1, z = 1
  cloud.add({0.85, 0.5, 1.45}, 0.5);  // on the top, near the edge: a face contact only
  cloud.add({1.2, 1.2, 1.2}, 0.5);    // beyond the corner (1, 1, 1)
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 3u);
  const Vec3 d_edge(0.3, 0, 0.2);
  expect_vec_absolute("convex edge force along edge-to-centre", vec_at(out.particle_force, 0),
                      k * (0.5 - d_edge.norm()) * d_edge.normalized(), 1e-6);
  expect_vec_absolute("top face near the edge", vec_at(out.particle_force, 1), Vec3(0, 0, k * 0.05), 1e-6);
  const Vec3 d_corner(0.2, 0.2, 0.2);
  expect_vec_absolute("convex corner force", vec_at(out.particle_force, 2),
                      k * (0.5 - d_corner.norm()) * d_corner.normalized(), 1e-6);
  EXPECT_EQ(contact.contacts()[0].feature, Feature::edge);
  EXPECT_EQ(contact.contacts()[1].feature, Feature::face);
  EXPECT_EQ(contact.contacts()[2].feature, Feature::vertex);
}

TEST(SurfaceContact, RollingOverConvexEdgeIsContinuous) {
  // Sphere centre on a circle of radius 0.45 around the box's top edge: the
  // overlap is 0.05 everywhere, so the force magnitude must stay k * 0.05
  // through face -> edge -> face.
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  b.box({0, 0, 0}, {1, 1, 1}, b.part("block"), 1.0);
  contact.set_surface(b.mesh());
  Cloud cloud;
  for (int i = 0; i <= 90; ++i) {
    const double angle = i * std::numbers::pi / 180;  // 0: above the top, 90 deg: beside the side x = 1
    cloud.add({1 + 0.45 * std::sin(angle), 0.5, 1 + 0.45 * std::cos(angle)}, 0.5);
  }
  // And slightly inward on the top / below on the side, where the face alone acts.
  cloud.add({0.99, 0.5, 1.45}, 0.5);
  cloud.add({1.45, 0.5, 0.99}, 0.5);
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, cloud.size());
  double max_deviation = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    max_deviation = std::max(max_deviation, std::abs(vec_at(out.particle_force, i).norm() - k * 0.05));
  }
  std::cout << "rolling over a convex edge: largest deviation of |F| from k delta " << max_deviation << " N of "
            << k * 0.05 << " N\n";
  EXPECT_LE(max_deviation, 1e-6 * k * 0.05);
}

// A concave corner: the floor z = 0 for x in [0, 2] and a wall x = 0 for z in [0, 2],
// sharing the edge x = 0, z = 0 (part "channel").
geometry::SurfaceMesh floor_and_wall() {
  MeshBuilder b;
  const auto part = b.part("channel");
  const auto p0 = b.node({0, -1, 0}), p1 = b.node({0, 1, 0});
  const auto f0 = b.node({2, -1, 0}), f1 = b.node({2, 1, 0});
  const auto w0 = b.node({0, -1, 2}), w1 = b.node({0, 1, 2});
  b.triangle(p0, f0, f1, part);
  b.triangle(p0, f1, p1, part);
  b.triangle(p0, p1, w1, part);
  b.triangle(p0, w1, w0, part);
  return b.mesh();
}

TEST(SurfaceContact, ConcaveCornerGivesTwoContacts) {
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  contact.set_surface(floor_and_wall());
  Cloud cloud;
  cloud.add({0.45, 0.1, 0.48}, 0.5);
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 2u);
  expect_vec_absolute("concave corner (wall + floor)", vec_at(out.particle_force, 0), Vec3(k * 0.05, 0, k * 0.02),
                      1e-6);
}

// A contact born while the particle already touches starts slack (normal
// offset = its overlap at birth) and stiffens only with further approach: the
// spring energy does not jump (a dent turning concave under a sphere).
TEST(SurfaceContact, ContactBornDuringAContactStartsSlack) {
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  contact.set_surface(floor_and_wall());
  ContactOutput out;
  const auto step = [&](double x) {
    Cloud cloud;
    cloud.add({x, 0.1, 0.48}, 0.5);
    contact.compute(cloud.view(), 1e-4, out);
  };
  step(0.6);  // the floor only, overlap 0.02
  ASSERT_EQ(out.contact_count, 1u);
  EXPECT_NEAR(out.deepest_overlap_ratio, 0.02 / 2.0, 1e-12);  // the floor triangles' shortest edge: 2 m
  step(0.45);                                                 // the wall appears with overlap 0.05: slack
  ASSERT_EQ(out.contact_count, 2u);
  const double elastic_floor = 0.5 * k * 0.02 * 0.02;
  std::cout << "wall contact born with 0.05 m overlap: force x measured " << vec_at(out.particle_force, 0).x()
            << " N expected 0; elastic energy measured " << out.elastic_energy << " J expected " << elastic_floor
            << " J (" << elastic_floor + 0.5 * k * 0.05 * 0.05 << " J with a full spring)\n";
  expect_vec_absolute("slack wall at birth", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.02), 1e-6);
  EXPECT_NEAR(out.elastic_energy, elastic_floor, 1e-9);
  step(0.43);  // 0.02 further into the wall
  expect_vec_absolute("wall stiffens from birth", vec_at(out.particle_force, 0), Vec3(k * 0.02, 0, k * 0.02), 1e-6);
  step(0.47);  // back out past the birth overlap: the offset shrinks to 0.03
  expect_vec_absolute("slack again", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.02), 1e-6);
  step(0.46);  // 0.01 in from the shrunken offset
  expect_vec_absolute("offset followed the overlap", vec_at(out.particle_force, 0), Vec3(k * 0.01, 0, k * 0.02), 1e-6);
}

// A particle sunk deeper than half a small face's edge is reported (the
// coupler warns: the penalty spring is too soft for the mesh).
TEST(SurfaceContact, DeepOverlapRelativeToTheFaceIsReported) {
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(1e6)));
  MeshBuilder b;
  const auto part = b.part("block");
  b.triangle(b.node({-0.05, -0.05, 0}), b.node({0.05, -0.05, 0}), b.node({0.05, 0.05, 0}), part);
  b.triangle(b.node({-0.05, -0.05, 0}), b.node({0.05, 0.05, 0}), b.node({-0.05, 0.05, 0}), part);
  contact.set_surface(b.mesh());
  Cloud cloud;
  cloud.add({0.01, 0.0, 0.44}, 0.5);  // overlap 0.06 m on faces with 0.1 m sides
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  ASSERT_GE(out.contact_count, 1u);
  std::cout << "overlap / face edge: measured " << out.deepest_overlap_ratio << " expected 0.6\n";
  EXPECT_NEAR(out.deepest_overlap_ratio, 0.6, 1e-9);
  EXPECT_NEAR(out.deepest_overlap, 0.06, 1e-12);
  EXPECT_NEAR(out.deepest_face_edge, 0.1, 1e-12);
}

TEST(SurfaceContact, ShallowFoldIsOneContact) {
  // Two floor panels meeting in a 5 degree valley: one contact (the deeper), never both.
  const double k = 1e6;
  const double slope = 5.0 * std::numbers::pi / 180;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  const auto part = b.part("floor");
  const auto a0 = b.node({-2, -1, 0}), a1 = b.node({-2, 1, 0});
  const auto m0 = b.node({0, -1, 0}), m1 = b.node({0, 1, 0});
  const auto c0 = b.node({2, -1, 2 * std::tan(slope)}), c1 = b.node({2, 1, 2 * std::tan(slope)});
  b.triangle(a0, m0, m1, part);
  b.triangle(a0, m1, a1, part);
  b.triangle(m0, c0, c1, part);
  b.triangle(m0, c1, m1, part);
  contact.set_surface(b.mesh());
  Cloud cloud;
  for (int i = -10; i <= 10; ++i) cloud.add({0.005 * i, 0, 0.48}, 0.5);
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const double x = cloud.at(i).x();
    const Vec3 n2(-std::sin(slope), 0, std::cos(slope));
    const double overlap_flat = 0.5 - 0.48;
    const double overlap_slope = 0.5 - (cloud.at(i) - Vec3(0, 0, 0)).dot(n2);
    const double expected = k * std::max(overlap_flat, overlap_slope);
    EXPECT_NEAR(vec_at(out.particle_force, i).norm(), expected, 1e-6) << "x = " << x;
  }
}

TEST(SurfaceContact, ThinSolidBottomFaceDoesNotPull) {
  // A solid plate 1 cm thick: the sphere resting on top is behind the bottom
  // face (within reach), but the top face is nearer: only the top acts.
  const double k = 1e6;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  b.box({-1, -1, -0.01}, {1, 1, 0}, b.part("plate"), 0.04);
  contact.set_surface(b.mesh());
  Cloud cloud;
  cloud.add({0.1, 0.2, 0.45}, 0.5);
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 1u);
  expect_vec_absolute("thin plate", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.05), 1e-6);

  // Sunk into a block: pushed out through the nearest face.
  SurfaceContact block({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder bb;
  bb.box({0, 0, 0}, {1, 1, 1}, bb.part("block"), 1.0);
  block.set_surface(bb.mesh());
  Cloud sunk;
  sunk.add({0.5, 0.5, 0.95}, 0.6);
  block.compute(sunk.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 1u);
  expect_vec_absolute("sunk into a block", vec_at(out.particle_force, 0), Vec3(0, 0, k * 0.65), 1e-6);
}

TEST(SurfaceContact, SpringCarriedAcrossSharedEdge) {
  // Sticking contact dragged across the diagonal of a two-triangle floor: the
  // tangential spring keeps growing linearly, it is not reset at the edge.
  const double k = 1e6, dt = 1e-3, speed = 1e-3;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k, 1.0)));
  MeshBuilder b;
  b.grid({-1, -1, 0}, 1, 1, 2.0, b.part("floor"));
  contact.set_surface(b.mesh());
  Cloud cloud;
  cloud.add({0.2 - 10 * speed * dt, 0.2, 0.49}, 0.5, 10.0, {speed, 0, 0});
  ContactOutput out;
  std::vector<std::uint32_t> faces;
  for (int step = 1; step <= 20; ++step) {
    contact.compute(cloud.view(), dt, out);
    faces.push_back(contact.contacts()[0].face);
    const double expected = -k * speed * dt * step;
    EXPECT_NEAR(out.particle_force[0], expected, 1e-9) << "step " << step;
    cloud.move(0, cloud.at(0) + Vec3(speed * dt, 0, 0));
  }
  std::cout << "spring across the edge: tangential force measured " << out.particle_force[0] << " expected "
            << -k * speed * dt * 20 << "; faces " << faces.front() << " -> " << faces.back() << "\n";
  EXPECT_NE(faces.front(), faces.back());
}

// -------------------------------------------------------- bulk behaviour ---

// A bumpy terrain grid, rotated by a random rotation, and spheres scattered
// near it with random velocities and spins.
struct RandomScene {
  MeshBuilder builder;
  Cloud cloud;
  RandomScene(std::uint64_t seed, int spheres) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const auto terrain = builder.part("terrain");
    const auto block = builder.part("block");
    const int n = 16;
    const double h = 0.25;
    std::vector<std::uint32_t> ids;
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) ids.push_back(builder.node({i * h, j * h, 0.1 * u(rng)}));
    }
    auto at = [&](int i, int j) { return ids[static_cast<std::size_t>(j * (n + 1) + i)]; };
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        builder.triangle(at(i, j), at(i + 1, j), at(i + 1, j + 1), terrain, 0.0, 2e9 + 1e9 * u(rng), 0.0);
        builder.triangle(at(i, j), at(i + 1, j + 1), at(i, j + 1), terrain, 0.05, 2e9, 0.0);
      }
    }
    builder.box({1.5, 1.5, 0.1}, {2.5, 2.2, 0.8}, block, 0.5);
    const Eigen::Quaterniond rotation =
        Eigen::Quaterniond(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized();
    for (Vec3& p : builder.mesh().node_position) p = rotation * p + Vec3(0.3, -0.2, 0.1);
    for (int s = 0; s < spheres; ++s) {
      const double r = 0.05 + 0.15 * u(rng);
      const Vec3 local(4 * u(rng), 4 * u(rng), -0.2 + u(rng));
      const Vec3 v(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
      const Vec3 w(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
      cloud.add(rotation * local + Vec3(0.3, -0.2, 0.1), r, 1000 * r * r * r, v, 10 * w,
                static_cast<std::uint32_t>(s % 2));
    }
  }
};

scene::SurfaceContact bulk_settings() {
  scene::SurfaceContact s;
  s.friction = 0.4;
  s.penalty_scale = 0.1;
  s.normal_damping_ratio = 0.3;
  s.tangential_damping_ratio = 0.2;
  return s;
}

TEST(SurfaceContact, NewtonThirdLaw) {
  RandomScene scene(5, 400);
  SurfaceContact contact({"boulders", "gravel"}, uniform(bulk_settings()));
  contact.set_surface(scene.builder.mesh());
  ContactOutput out;
  contact.compute(scene.cloud.view(), 1e-4, out);
  contact.compute(scene.cloud.view(), 1e-4, out);  // with tangential springs
  Vec3 sum = Vec3::Zero(), particles = Vec3::Zero();
  double scale = 0;
  for (std::size_t i = 0; i < scene.cloud.size(); ++i) {
    sum += vec_at(out.particle_force, i);
    particles += vec_at(out.particle_force, i);
    scale += vec_at(out.particle_force, i).norm();
  }
  for (std::size_t i = 0; i < scene.builder.mesh().node_count(); ++i) sum += vec_at(out.node_force, i);
  std::cout << "Newton: " << out.contact_count << " contacts, |sum of all forces| / sum |F| = " << sum.norm() / scale
            << " (limit 1e-12)\n";
  ASSERT_GT(out.contact_count, 50u);
  EXPECT_LE(sum.norm(), 1e-12 * scale);
  // Part totals (split by source) hold the reaction.
  Vec3 parts = Vec3::Zero(), by_source = Vec3::Zero();
  for (std::size_t p = 0; p < contact.part_count(); ++p) {
    parts += out.part_force[p];
    for (std::size_t s = 0; s < 2; ++s) by_source += out.force_on_part(p, s);
  }
  EXPECT_LE((parts + particles).norm(), 1e-12 * scale);
  EXPECT_LE((by_source + particles).norm(), 1e-12 * scale);
  EXPECT_GT(out.force_on_part(0, 0).norm(), 0.0);
  EXPECT_GT(out.force_on_part(0, 1).norm(), 0.0);
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

// One contact searched through the grid and the same searched by brute force, on a scene's surface.
struct GridAndBruteForce {
  static SurfaceContactOptions brute_force() {
    SurfaceContactOptions options;
    options.brute_force_search = true;
    return options;
  }
  SurfaceContact grid{{"boulders", "gravel"}, uniform(bulk_settings())};
  SurfaceContact all{{"boulders", "gravel"}, uniform(bulk_settings()), brute_force()};
  explicit GridAndBruteForce(const RandomScene& scene) {
    grid.set_surface(scene.builder.mesh());
    all.set_surface(scene.builder.mesh());
  }
};

TEST(SurfaceContact, GridSearchEqualsBruteForce) {
  RandomScene scene(8, 600);
  GridAndBruteForce search(scene);
  SurfaceContact& grid = search.grid;
  SurfaceContact& all = search.all;
  ContactOutput out_grid, out_all;
  grid.compute(scene.cloud.view(), 1e-4, out_grid);
  all.compute(scene.cloud.view(), 1e-4, out_all);
  std::cout << "search: grid " << out_grid.contact_count << " contacts, brute force " << out_all.contact_count
            << "; stable dt " << grid.stable_dt() << " vs " << all.stable_dt() << "\n";
  ASSERT_GT(out_grid.contact_count, 50u);
  ASSERT_EQ(grid.contacts().size(), all.contacts().size());
  for (std::size_t c = 0; c < grid.contacts().size(); ++c) {
    EXPECT_EQ(grid.contacts()[c].particle, all.contacts()[c].particle);
    EXPECT_EQ(grid.contacts()[c].face, all.contacts()[c].face);
    EXPECT_EQ(grid.contacts()[c].feature, all.contacts()[c].feature);
  }
  EXPECT_TRUE(same_bits(out_grid.particle_force, out_all.particle_force));
  EXPECT_TRUE(same_bits(out_grid.node_force, out_all.node_force));
  EXPECT_EQ(grid.stable_dt(), all.stable_dt());
}

// The static faces' candidates are kept per particle between steps: over steps where particles move out
// of their kept box (fails if a list is reused past its box), leave the view, come back in another order,
// and part of the surface starts to move (a second grid, then the static grid rebuilt), every step gives the
// brute-force search's bits.
TEST(SurfaceContact, KeptCandidatesEqualBruteForceOverSteps) {
  RandomScene scene(21, 400);
  GridAndBruteForce search(scene);
  SurfaceContact& grid = search.grid;
  SurfaceContact& all = search.all;
  Cloud cloud = scene.cloud;
  std::vector<double> nodes;
  for (const Vec3& p : scene.builder.mesh().node_position) nodes.insert(nodes.end(), {p.x(), p.y(), p.z()});
  std::size_t contacts = 0, compared = 0;
  for (int step = 0; step < 24; ++step) {
    // Every third step a view without every fifth particle, every fourth step in reverse order.
    std::vector<std::size_t> members;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (step % 3 != 1 || i % 5 != static_cast<std::size_t>(step) % 5) members.push_back(i);
    }
    if (step % 4 == 3) std::reverse(members.begin(), members.end());
    Cloud view;
    for (std::size_t i : members) {
      view.add(cloud.at(i), cloud.radius[i], cloud.mass[i], vec_at(cloud.velocity, i), vec_at(cloud.spin, i),
               cloud.body[i]);
      view.id.back() = cloud.id[i];
    }
    if (step >= 8) {
      // The first nodes (part of the terrain) sink slowly: their faces move from the static grid to the moving one.
      for (std::size_t k = 0; k < 30 && 3 * k + 2 < nodes.size(); ++k) nodes[3 * k + 2] -= 1e-3;
      grid.update_nodes(nodes, {});
      all.update_nodes(nodes, {});
    }
    ContactOutput out_grid, out_all;
    grid.compute(view.view(), 1e-3, out_grid);
    all.compute(view.view(), 1e-3, out_all);
    contacts += out_grid.contact_count;
    ASSERT_EQ(out_grid.contact_count, out_all.contact_count) << "step " << step;
    ASSERT_TRUE(same_bits(out_grid.particle_force, out_all.particle_force)) << "step " << step;
    ASSERT_TRUE(same_bits(out_grid.particle_torque, out_all.particle_torque)) << "step " << step;
    ASSERT_TRUE(same_bits(out_grid.node_force, out_all.node_force)) << "step " << step;
    ASSERT_EQ(grid.stable_dt(), all.stable_dt()) << "step " << step;
    compared += out_grid.particle_force.size() + out_grid.node_force.size();
    // Fast enough that a particle leaves its kept box (a quarter of its reach) within a few steps.
    for (std::size_t i = 0; i < cloud.size(); ++i) cloud.move(i, cloud.at(i) + 0.1 * vec_at(cloud.velocity, i));
  }
  std::cout << "kept candidates: " << contacts << " contacts over 24 steps, " << compared
            << " force components equal to the brute-force search's bits\n";
  EXPECT_GT(contacts, 24u * 30u);
}

TEST(SurfaceContact, DeterministicWithOneAndTwoThreads) {
  RandomScene scene(13, 500);
  auto run = [&](int threads) {
    omp_set_num_threads(threads);
    SurfaceContact contact({"boulders", "gravel"}, uniform(bulk_settings()));
    contact.set_surface(scene.builder.mesh());
    Cloud cloud = scene.cloud;
    ContactOutput out;
    std::vector<double> trace;
    for (int step = 0; step < 5; ++step) {
      contact.compute(cloud.view(), 1e-3, out);
      trace.insert(trace.end(), out.particle_force.begin(), out.particle_force.end());
      trace.insert(trace.end(), out.particle_torque.begin(), out.particle_torque.end());
      trace.insert(trace.end(), out.node_force.begin(), out.node_force.end());
      trace.push_back(out.elastic_energy);
      trace.push_back(contact.stable_dt());
      for (std::size_t i = 0; i < cloud.size(); ++i) cloud.move(i, cloud.at(i) + 1e-3 * vec_at(cloud.velocity, i));
    }
    return trace;
  };
  const auto one = run(1);
  const auto two = run(2);
  omp_set_num_threads(omp_get_num_procs());
  std::cout << "determinism: " << one.size() << " values compared bit for bit\n";
  EXPECT_TRUE(same_bits(one, two));
}

// ------------------------------------------------------ settings, dt, IO ---

TEST(SurfaceContact, PairSettingsFromScene) {
  scene::Scene s;
  s.particle_sets.resize(2);
  s.particle_sets[0].name = "boulders";
  s.particle_sets[1].name = "gravel";
  s.dem_fem_default.penalty_scale = 0.1;
  s.dem_fem_default.friction = 0.3;
  scene::Interaction gravel_dam;
  gravel_dam.a = "gravel";
  gravel_dam.b = "dam";
  gravel_dam.contact = s.dem_fem_default;
  gravel_dam.contact.normal_stiffness = 5e6;
  scene::Interaction boulders_house;
  boulders_house.a = "house";
  boulders_house.b = "boulders";
  boulders_house.contact = s.dem_fem_default;
  boulders_house.contact.enabled = false;
  s.interactions = {gravel_dam, boulders_house};

  MeshBuilder b;
  const auto dam = b.part("dam");
  const auto house = b.part("house");
  b.triangle(Vec3(0, 0, 0), Vec3(4, 0, 0), Vec3(0, 4, 0), dam);
  b.triangle(Vec3(10, 0, 0), Vec3(14, 0, 0), Vec3(10, 4, 0), house, 0.24);
  SurfaceContact contact(s);
  contact.set_surface(b.mesh());
  const double k_eq6 = 0.1 * 1e9 * 8.0 / (4.0 * std::sqrt(2.0));
  EXPECT_NEAR(contact.face_stiffness(0, 0), k_eq6, 1e-6 * k_eq6);
  EXPECT_EQ(contact.face_stiffness(0, 1), 5e6);

  Cloud cloud;
  cloud.add({1, 1, 0.45}, 0.5, 10, Vec3::Zero(), Vec3::Zero(), 0);   // boulder on the dam
  cloud.add({1, 2, 0.45}, 0.5, 10, Vec3::Zero(), Vec3::Zero(), 1);   // gravel on the dam
  cloud.add({11, 1, 0.45}, 0.5, 10, Vec3::Zero(), Vec3::Zero(), 0);  // boulder on the house: disabled
  cloud.add({11, 2, 0.45}, 0.5, 10, Vec3::Zero(), Vec3::Zero(), 1);  // gravel on the house
  ContactOutput out;
  contact.compute(cloud.view(), 0.0, out);
  EXPECT_EQ(out.contact_count, 3u);
  expect_vec_absolute("dam from boulders", out.force_on_part(dam, 0), Vec3(0, 0, -k_eq6 * 0.05), 1e-6 * k_eq6);
  expect_vec_absolute("dam from gravel", out.force_on_part(dam, 1), Vec3(0, 0, -5e6 * 0.05), 1e-3);
  expect_vec_absolute("house from boulders (disabled)", out.force_on_part(house, 0), Vec3::Zero(), 0);
  expect_vec_absolute("house from gravel", out.force_on_part(house, 1), Vec3(0, 0, -k_eq6 * 0.17), 1e-6 * k_eq6);
  EXPECT_EQ(contact.source_names()[1], "gravel");
}

TEST(SurfaceContact, StableStepOverPotentialContacts) {
  const double k = 4e6, mass = 25.0;
  SurfaceContact contact({"boulders"}, uniform(explicit_stiffness(k)));
  MeshBuilder b;
  b.grid({-2, -2, 0}, 2, 2, 2.0, b.part("floor"));
  contact.set_surface(b.mesh());
  ContactOutput out;
  Cloud far;
  far.add({0, 0, 1.01}, 0.5, mass);  // gap 0.51 > one radius
  contact.compute(far.view(), 0.0, out);
  EXPECT_TRUE(std::isinf(contact.stable_dt()));
  Cloud near;
  near.add({0, 0, 0.9}, 0.5, mass);  // gap 0.4: within one radius of touching
  contact.compute(near.view(), 0.0, out);
  const double expected = 0.2 * std::numbers::pi * std::sqrt(mass / k);
  std::cout << "stable dt: measured " << contact.stable_dt() << " expected " << expected << "\n";
  EXPECT_NEAR(contact.stable_dt(), expected, 1e-15);
  EXPECT_EQ(out.contact_count, 0u);

  Aabb region;
  for (const Aabb& box : contact.interest_regions()) region.extend(box);
  EXPECT_NEAR(region.max.z(), 0.5 * 3.0, 1e-12);
  EXPECT_NEAR(region.min.x(), -2.0 - 1.5, 1e-12);
}

TEST(SurfaceContact, InterestRegionsHugASlopingFloor) {
  // A 30 degree ramp, 40 m by 4 m, under a lattice of particles that fills its bounding box: only those
  // within reach of the ramp need to travel (docs/design.md, "Only the interface travels"), and none of those may be
  // left out.
  const double radius = 0.1, slope = std::numbers::pi / 6;
  SurfaceContact contact({"slurry"}, uniform(explicit_stiffness(1e6)));
  MeshBuilder b;
  b.grid({0, 0, 0}, 40, 4, 1.0, b.part("floor"));
  geometry::SurfaceMesh mesh = b.mesh();
  const Eigen::Matrix3d rise = Eigen::AngleAxisd(-slope, Vec3::UnitY()).toRotationMatrix();
  for (Vec3& x : mesh.node_position) x = rise * x;
  contact.set_surface(mesh);
  Cloud cloud;
  const Vec3 top = rise * Vec3(40, 4, 0);
  for (double x = -1; x <= top.x() + 1; x += 0.5) {
    for (double y = -1; y <= 5; y += 0.5) {
      for (double z = -1; z <= top.z() + 1; z += 0.5) cloud.add({x, y, z}, radius, 1.0);
    }
  }
  const std::vector<Aabb> regions = contact.interest_regions(radius);
  Aabb one_box;
  for (const Aabb& box : regions) one_box.extend(box);
  const double reach = radius * (2.0 + SurfaceContactOptions{}.potential_margin);
  std::size_t sent = 0, sent_by_one_box = 0, within_reach = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3 p = cloud.at(i);
    const Vec3 local = rise.transpose() * p;  // ramp frame: the floor is z = 0, 0 <= x <= 40, 0 <= y <= 4
    const Vec3 nearest(std::clamp(local.x(), 0.0, 40.0), std::clamp(local.y(), 0.0, 4.0), 0.0);
    bool inside = false;
    for (const Aabb& box : regions) inside = inside || box.contains(p);
    sent += inside ? 1 : 0;
    sent_by_one_box += one_box.contains(p) ? 1 : 0;
    if ((local - nearest).norm() <= reach) {
      ++within_reach;
      ASSERT_TRUE(inside) << "a particle within reach of the ramp is left out: " << p.transpose();
    }
  }
  std::cout << regions.size() << " interest boxes: " << sent << " of " << cloud.size() << " particles sent, "
            << within_reach << " within reach; one box would send " << sent_by_one_box << " (ratio "
            << static_cast<double>(sent) / static_cast<double>(sent_by_one_box) << ", expected <= 0.25)\n";
  EXPECT_LE(regions.size(), geometry::kMaxInterestBoxes);
  EXPECT_LE(4 * sent, sent_by_one_box);
}

TEST(SurfaceContact, RejectsInconsistentInput) {
  SurfaceContact contact({"boulders"}, uniform(eq6_settings()));
  auto mesh = single_triangle(0.0, 0.0);
  auto bad_node = mesh.mesh();
  bad_node.triangle[0][2] = 7;
  EXPECT_THROW(contact.set_surface(bad_node), ProtocolError);
  auto no_bulk = mesh.mesh();
  no_bulk.face_bulk_modulus[0] = 0.0;
  EXPECT_THROW(contact.set_surface(no_bulk), ProtocolError);
  contact.set_surface(mesh.mesh());
  Cloud cloud;
  cloud.add({1, 1, 0.45}, 0.5, 10, Vec3::Zero(), Vec3::Zero(), 3);
  ContactOutput out;
  EXPECT_THROW(contact.compute(cloud.view(), 0.0, out), ProtocolError);
  const std::vector<double> short_positions(5, 0.0);
  EXPECT_THROW(contact.update_nodes(short_positions, {}), ProtocolError);
}

TEST(SurfaceContact, HertzImpactOnARigidFloorIsBenchmarkD1) {
  // D1 test 2 (Chung & Ooi 2011): aluminium sphere R 0.1 m (E 70 GPa, nu 0.33, rho 2700) at 0.2 m/s on a
  // rigid wall: peak force 11.47 kN, largest overlap 49.3 um, contact time 0.726 ms, within 1 %. The
  // kernel on a floor of 32 triangles; the sphere integrated here (central difference, 4000 steps per
  // contact), striking across a shared edge.
  scene::SurfaceContact settings;
  settings.model = scene::SurfaceContact::Model::hertz_mindlin;
  settings.restitution = 1.0;
  settings.friction = 0.0;
  const double inf = std::numeric_limits<double>::infinity();
  SurfaceContact contact({"sphere"}, uniform(settings), {}, [inf](const std::string&, const std::string&) {
    return std::array<double, 4>{70e9, 0.33, inf, 0.33};
  });
  MeshBuilder builder;
  const std::uint32_t floor = builder.part("floor");
  builder.grid(Vec3(-1, -1, 0), 4, 4, 0.5, floor);
  contact.set_surface(builder.mesh());
  const double radius = 0.1, mass = 2700 * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  Cloud cloud;
  cloud.add({0.0, 0.0, radius + 1e-6}, radius, mass, {0, 0, -0.2});
  const double dt = 0.726e-3 / 4000;
  double dt_previous = 0, t = 0, start = -1, end = -1, peak = 0, deepest = 0, previous = -1e-6;
  ContactOutput out;
  for (int n = 0; n < 20000 && end < 0; ++n) {
    contact.compute(cloud.view(), dt_previous, out);
    const double force = out.particle_force[2];
    peak = std::max(peak, force);
    const double dt_update = dt_previous == 0 ? 0.5 * dt : 0.5 * (dt_previous + dt);
    cloud.velocity[2] += dt_update * force / mass;
    cloud.position[2] += dt * cloud.velocity[2];
    dt_previous = dt;
    t += dt;
    const double overlap = radius - cloud.position[2];
    deepest = std::max(deepest, overlap);
    if (start < 0 && previous <= 0 && overlap > 0) start = t - dt * overlap / (overlap - previous);
    if (start >= 0 && previous > 0 && overlap <= 0) end = t - dt * overlap / (overlap - previous);
    previous = overlap;
  }
  std::cout << "coupler Hertz D1 test 2: peak force measured " << peak << " N expected 11470; largest overlap "
            << deepest << " m expected 4.93e-5; contact time " << end - start << " s expected 7.26e-4; rebound "
            << cloud.velocity[2] << " m/s expected 0.2\n";
  EXPECT_NEAR(peak, 11.47e3, 0.01 * 11.47e3);
  EXPECT_NEAR(deepest, 49.3e-6, 0.01 * 49.3e-6);
  EXPECT_NEAR(end - start, 0.726e-3, 0.01 * 0.726e-3);
  EXPECT_NEAR(cloud.velocity[2], 0.2, 0.01 * 0.2);
  // The step bound of a Hertz pair: a fifth of the sphere's Rayleigh time at most.
  const double shear = 70e9 / (2 * 1.33);
  const double rayleigh = std::numbers::pi * radius * std::sqrt(2700 / shear) / (0.1631 * 0.33 + 0.8766);
  cloud.move(0, {0, 0, radius + 0.01});
  contact.compute(cloud.view(), dt, out);
  EXPECT_NEAR(contact.stable_dt(), 0.2 * rayleigh, 1e-9 * rayleigh);
  // Without the materials the Hertz pair is refused.
  SurfaceContact blind({"sphere"}, uniform(settings));
  EXPECT_THROW(blind.set_surface(builder.mesh()), ProtocolError);
}

}  // namespace
}  // namespace sabo::contact

namespace sabo::contact {
namespace {

// Eq. 7's contact term with the node masses: 0.2 pi sqrt(m_r / k), m_r the
// reduced mass of the particle and the face's lightest node. Without node
// masses (rigid) m_r is the particle's mass; a light node of a fine FEM mesh
// under a heavy boulder lowers it, as the spring then moves the node.
TEST(SurfaceContact, StableDtUsesTheReducedMassWithTheFaceNodes) {
  const double k = 1e6, particle_mass = 10.0;
  auto stable_dt = [&](const std::vector<double>& node_mass) {
    test::MeshBuilder builder;
    const auto part = builder.part("plate");
    builder.triangle(Vec3(-1, -1, 0), Vec3(2, -1, 0), Vec3(-1, 2, 0), part);
    builder.mesh().node_mass = node_mass;
    SurfaceContact contact({"boulders"}, test::uniform(test::explicit_stiffness(k)));
    contact.set_surface(builder.mesh());
    test::Cloud cloud;
    cloud.add(Vec3(0, 0, 0.45), 0.5, particle_mass);
    ContactOutput out;
    contact.compute(cloud.view(), 1e-4, out);
    return contact.stable_dt();
  };
  const double factor = 0.2 * std::numbers::pi;
  const double rigid = stable_dt({});
  const double rigid_expected = factor * std::sqrt(particle_mass / k);
  std::cout << "contact dt, rigid face: measured " << rigid << " s expected " << rigid_expected << " s\n";
  EXPECT_NEAR(rigid, rigid_expected, 1e-12 * rigid_expected);
  EXPECT_EQ(stable_dt({0.0, 0.0, 0.0}), rigid);  // mass 0: a rigid node

  const double light = stable_dt({0.5, 2.0, 3.0});
  const double reduced = particle_mass * 0.5 / (particle_mass + 0.5);
  const double light_expected = factor * std::sqrt(reduced / k);
  std::cout << "contact dt, 0.5 kg node under a 10 kg particle: measured " << light << " s expected " << light_expected
            << " s\n";
  EXPECT_NEAR(light, light_expected, 1e-12 * light_expected);
  // Central difference is stable for omega dt < 2: the two-mass spring's omega = sqrt(k / m_r).
  EXPECT_LT(light * std::sqrt(k / reduced), 2.0);
  EXPECT_GT(rigid * std::sqrt(k / reduced), 2.0) << "the particle-only dt would be unstable for this node";
}

}  // namespace
}  // namespace sabo::contact
