// The coupler's checks of what solvers send (issue 18, item 2): each bad field is named with its entity and
// value, and thousands of bit-flipped registrations either are refused or hold only valid values.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>
#include <set>

#include "coupler/message_checks.hpp"

using namespace sabo;
using namespace sabo::coupler;

namespace {

scene::Scene two_material_scene() {
  scene::Scene s;
  s.run.end_time = 1.0;
  for (const char* name : {"concrete", "granite"}) {
    scene::Material m;
    m.name = name;
    m.density = 2500;
    m.youngs_modulus = 30e9;
    m.poisson_ratio = 0.2;
    s.materials.push_back(m);
  }
  s.particle_sets.resize(2);
  s.structures.resize(1);
  return s;
}

sabo::v1::ParticleTable table_of(int n) {
  sabo::v1::ParticleTable t;
  for (int k = 0; k < n; ++k) {
    t.add_id(static_cast<std::uint64_t>(k)), t.add_radius(0.5), t.add_mass(1000.0);
    t.add_material(static_cast<std::uint32_t>(k % 2)), t.add_body(static_cast<std::uint32_t>(k % 2));
  }
  return t;
}

// Two triangles over four nodes, part 0.
sabo::v1::SurfaceTopology square() {
  sabo::v1::SurfaceTopology s;
  for (int k = 0; k < 4; ++k) {
    s.add_node_id(static_cast<std::uint64_t>(10 + k));
    for (double v : {static_cast<double>(k % 2), static_cast<double>(k / 2), 0.0}) s.add_node_position(v);
    s.add_node_mass(1.0);
  }
  for (std::uint32_t v : {0u, 1u, 3u, 0u, 3u, 2u}) s.add_triangle(v);
  for (int f = 0; f < 2; ++f) {
    s.add_face_part(0), s.add_face_material(0), s.add_face_thickness(0.0), s.add_face_bulk_modulus(1e10);
    s.add_face_element_volume(0.1);
  }
  s.add_part_name("floor");
  return s;
}

void expect_problem(const std::optional<std::string>& problem, const std::string& text) {
  ASSERT_TRUE(problem.has_value()) << "accepted; expected: " << text;
  std::cout << *problem << "\n";
  EXPECT_NE(problem->find(text), std::string::npos) << *problem;
}

TEST(MessageChecks, EachBadFieldIsNamedWithItsEntityAndValue) {
  const scene::Scene scene = two_material_scene();
  EXPECT_FALSE(particle_table_problem(table_of(5), scene, sabo::Role::dem));
  EXPECT_FALSE(surface_problem(square(), scene));

  auto t = table_of(5);
  t.set_radius(3, std::nan(""));
  expect_problem(particle_table_problem(t, scene, sabo::Role::dem), "particle 3 (id 3) has radius nan m");
  t = table_of(5);
  t.set_mass(2, -1.0);
  expect_problem(particle_table_problem(t, scene, sabo::Role::dem), "particle 2 (id 2) has mass -1 kg");
  t = table_of(5);
  t.set_material(4, 7);
  expect_problem(particle_table_problem(t, scene, sabo::Role::dem), "has material 7, the scene has 2");
  t = table_of(5);
  t.set_body(1, 2);
  expect_problem(particle_table_problem(t, scene, sabo::Role::dem), "belongs to body 2, the scene has 2 bodies");
  t = table_of(5);
  t.set_id(4, 1);
  expect_problem(particle_table_problem(t, scene, sabo::Role::dem), "has the id 1 of an earlier particle");
  t = table_of(5);
  t.add_radius(1.0);
  expect_problem(particle_table_problem(t, scene, sabo::Role::dem), "arrays differ in length");

  auto s = square();
  s.set_face_bulk_modulus(1, std::nan(""));
  expect_problem(surface_problem(s, scene), "face 1 has bulk modulus nan Pa");
  s = square();
  s.set_triangle(4, 9);
  expect_problem(surface_problem(s, scene), "face 1 names node 9, the surface has 4 nodes");
  s = square();
  s.set_node_position(7, std::numeric_limits<double>::infinity());
  expect_problem(surface_problem(s, scene), "surface node 2 (id 12) has a non-finite position");
  s = square();
  s.set_face_part(0, 3);
  expect_problem(surface_problem(s, scene), "face 0 belongs to part 3, there are 1 parts");
  s = square();
  s.set_node_id(3, 10);
  expect_problem(surface_problem(s, scene), "has the id 10 of an earlier node");

  EXPECT_FALSE(stable_dt_problem(1e-4, 1.0));
  EXPECT_FALSE(stable_dt_problem(std::numeric_limits<double>::infinity(), 1.0));
  expect_problem(stable_dt_problem(0.0, 1.0), "stable_dt = 0 s must be > 0");
  expect_problem(stable_dt_problem(std::nan(""), 1.0), "NaN");
  expect_problem(stable_dt_problem(1e-300, 1.0), "more than 1e+10 steps");
}

// Bit-flipped registrations (seeded): every one that parses is either refused or holds only values the
// coupler can compute with.
TEST(MessageChecks, BitFlippedRegistrationsAreRefusedOrValid) {
  const scene::Scene scene = two_material_scene();
  sabo::v1::Register good;
  *good.mutable_particles() = table_of(40);
  *good.mutable_surface() = square();
  good.set_stable_dt(1e-4);
  const std::string bytes = good.SerializeAsString();
  std::mt19937_64 random(2026);
  int parsed = 0, refused = 0, accepted = 0;
  for (int trial = 0; trial < 5000; ++trial) {
    std::string mutated = bytes;
    const int flips = 1 + static_cast<int>(random() % 3);
    for (int f = 0; f < flips; ++f) {
      const std::size_t at = random() % mutated.size();
      mutated[at] = static_cast<char>(mutated[at] ^ (1 << (random() % 8)));
    }
    sabo::v1::Register r;
    if (!r.ParseFromString(mutated)) continue;
    ++parsed;
    const auto table = particle_table_problem(r.particles(), scene, sabo::Role::dem);
    const auto surface = surface_problem(r.surface(), scene);
    const auto dt = r.stable_dt() != 0 ? stable_dt_problem(r.stable_dt(), scene.run.end_time) : std::nullopt;
    if (table || surface || dt) {
      ++refused;
      continue;
    }
    ++accepted;
    const auto& t = r.particles();
    std::set<std::uint64_t> ids(t.id().begin(), t.id().end());
    ASSERT_EQ(static_cast<int>(ids.size()), t.id_size());
    for (int k = 0; k < t.id_size(); ++k) {
      ASSERT_TRUE(std::isfinite(t.radius(k)) && t.radius(k) > 0);
      ASSERT_TRUE(std::isfinite(t.mass(k)) && t.mass(k) > 0);
      ASSERT_LT(t.body(k), scene.particle_sets.size());
    }
    for (const double v : r.surface().node_position()) ASSERT_TRUE(std::isfinite(v));
    for (const double k : r.surface().face_bulk_modulus()) ASSERT_TRUE(std::isfinite(k) && k > 0);
    for (const std::uint32_t v : r.surface().triangle())
      ASSERT_LT(v, static_cast<std::uint32_t>(r.surface().node_id_size()));
  }
  std::cout << "5000 mutated registrations: " << parsed << " parse, " << refused << " refused, " << accepted
            << " accepted with valid values\n";
  EXPECT_GT(refused, parsed / 4);
}

}  // namespace
