// Filling particle-set regions: count, no overlap, seeded bits, errors.
#include <gtest/gtest.h>

#include <cstring>
#include <iostream>

#include "dem_solver/dem_model.hpp"
#include "dem_test_scene.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/sphere_fill.hpp"

namespace sabo::dem {
namespace {

using testing::fill_set;
using testing::list_set;
using testing::rock_scene;

const Aabb kRegion{Vec3(0, 0, 0), Vec3(1, 1, 0.5)};

std::size_t count_overlaps(const DemModel& model) {
  std::size_t overlaps = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    for (std::size_t j = i + 1; j < model.size(); ++j) {
      const double reach = model.radii()[i] + model.radii()[j];
      if ((model.positions()[i] - model.positions()[j]).norm() < reach) ++overlaps;
    }
  }
  return overlaps;
}

TEST(SphereFill, UnitUniformUsesTheTop53Bits) {
  EXPECT_EQ(geometry::unit_uniform(0), 0.0);
  EXPECT_EQ(geometry::unit_uniform(~std::uint64_t{0}), 1.0 - 0x1.0p-53);
  EXPECT_EQ(geometry::unit_uniform(std::uint64_t{1} << 63), 0.5);
}

TEST(SphereFill, FillsTheRequestedCountWithoutOverlap) {
  scene::Scene scene = rock_scene();
  // A listed boulder in the middle of the region: the fill must avoid it.
  scene.particle_sets.push_back(list_set("boulder", {scene::Sphere{Vec3(0.5, 0.5, 0.25), 0.2}}));
  scene.particle_sets.push_back(fill_set("gravel", kRegion, 400, 0.04, 0.08, 5));
  scene.particle_sets.back().velocity = Vec3(1, 0, 0);
  const DemModel model(scene);
  ASSERT_EQ(model.size(), 401U);
  std::size_t outside = 0, wrong_size = 0;
  for (std::size_t i = 1; i < model.size(); ++i) {
    const Vec3& x = model.positions()[i];
    const double r = model.radii()[i];
    if ((x.array() - r < kRegion.min.array()).any() || (x.array() + r > kRegion.max.array()).any()) ++outside;
    if (r < 0.02 || r > 0.04) ++wrong_size;
    EXPECT_EQ(model.body_index()[i], 1U);
    EXPECT_EQ(model.velocities()[i], Vec3(1, 0, 0));
  }
  const std::size_t overlaps = count_overlaps(model);
  std::cout << "fill: measured " << model.size() - 1 << " spheres, " << overlaps << " overlaps, " << outside
            << " outside, " << wrong_size << " off-size; expected 400, 0, 0, 0\n";
  EXPECT_EQ(overlaps, 0U);
  EXPECT_EQ(outside, 0U);
  EXPECT_EQ(wrong_size, 0U);
  // Ids follow set order; the largest filled spheres come first.
  EXPECT_EQ(model.body_index()[0], 0U);
  EXPECT_GE(model.radii()[1], model.radii()[400]);
}

TEST(SphereFill, SameSeedSameBitsOtherSeedOtherSpheres) {
  auto build = [](std::uint64_t seed) {
    scene::Scene scene = rock_scene();
    scene.particle_sets.push_back(fill_set("a", kRegion, 150, 0.04, 0.08, seed));
    scene.particle_sets.push_back(fill_set("b", kRegion, 150, 0.04, 0.08, seed + 100));
    return DemModel(scene);
  };
  const DemModel first = build(9), again = build(9), other = build(10);
  ASSERT_EQ(first.size(), 300U);
  EXPECT_EQ(std::memcmp(first.positions().data(), again.positions().data(), 300 * sizeof(Vec3)), 0);
  EXPECT_EQ(std::memcmp(first.radii().data(), again.radii().data(), 300 * sizeof(double)), 0);
  std::size_t same = 0;
  for (std::size_t i = 0; i < 300; ++i) same += first.positions()[i] == other.positions()[i] ? 1 : 0;
  std::cout << "different seed: " << same << " of 300 positions equal (expected 0)\n";
  EXPECT_EQ(same, 0U);
  EXPECT_EQ(count_overlaps(first), 0U);  // the second set avoided the first
}

TEST(SphereFill, ASetThatCannotFitNamesItsOriginAndTheFix) {
  scene::Scene scene = rock_scene();
  scene.particle_sets.push_back(fill_set("crowd", Aabb{Vec3::Zero(), Vec3(0.3, 0.3, 0.3)}, 300, 0.05, 0.1, 1, 42));
  try {
    DemModel model(scene);
    FAIL() << "expected SceneError";
  } catch (const SceneError& error) {
    const std::string message = error.what();
    std::cout << message << "\n";
    EXPECT_NE(message.find("scene.toml:42"), std::string::npos);
    EXPECT_NE(message.find("crowd"), std::string::npos);
    EXPECT_NE(message.find("of 300 spheres"), std::string::npos);
    EXPECT_NE(message.find("Fix: enlarge the region"), std::string::npos);
  }
  // A sphere larger than the region.
  scene.particle_sets[0] = fill_set("big", Aabb{Vec3::Zero(), Vec3(1, 1, 0.1)}, 3, 0.2, 0.3, 1, 43);
  try {
    DemModel model(scene);
    FAIL() << "expected SceneError";
  } catch (const SceneError& error) {
    std::cout << error.what() << "\n";
    EXPECT_NE(std::string(error.what()).find("scene.toml:43"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("does not fit in the region"), std::string::npos);
  }
}

TEST(SphereFill, OverlappingListedSetsAreRejected) {
  scene::Scene scene = rock_scene();
  scene.particle_sets.push_back(list_set("left", {scene::Sphere{Vec3(0, 0, 0), 0.1}}, 50));
  scene.particle_sets.push_back(list_set("right", {scene::Sphere{Vec3(0.15, 0, 0), 0.1}}, 60));
  try {
    DemModel model(scene);
    FAIL() << "expected SceneError";
  } catch (const SceneError& error) {
    std::cout << error.what() << "\n";
    EXPECT_NE(std::string(error.what()).find("scene.toml:50"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("scene.toml:60"), std::string::npos);
  }
  // Touching is fine.
  scene.particle_sets[1].spheres[0].center.x() = 0.2;
  EXPECT_NO_THROW(DemModel{scene});
}

}  // namespace
}  // namespace sabo::dem
