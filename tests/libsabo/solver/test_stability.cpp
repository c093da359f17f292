// Instability detection (libsabo/solver/stability.hpp): what counts as unstable, what the message names, what
// instability.vtp holds, and the limits a scene gives each solver.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

#include "libsabo/scene/scene.hpp"
#include "libsabo/solver/stability.hpp"

namespace sabo::solver {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(Stability, AStateWithinTheLimitsIsStable) {
  const std::vector<Vec3> x{{0, 0, 0}, {1, 0, 0}}, v{{0, 0, -9.99}, {3, 4, 0}};
  EXPECT_FALSE(check_motion(x, v, {}, 10.0, "sphere"));
  const std::vector<double> density{1000, 1500, 550};
  const std::vector<std::uint32_t> material{0, 0, 1};
  const std::vector<double> rest{1000, 1000};
  EXPECT_FALSE(check_density(density, material, rest, {}, {.max_speed = 1, .min_density_ratio = 0.5,
                                                           .max_density_ratio = 2.0}));
}

TEST(Stability, NamesEveryKindOfBadEntityWithItsValues) {
  const std::vector<Vec3> x{{0, 0, 0}, {1, 2, 3}, {kNaN, 0, 0}, {0, 0, 0}, {5, 5, 5}};
  const std::vector<Vec3> v{{0, 0, 1}, {0, 0, 12.5}, {0, 0, 0}, {kInf, 0, 0}, {0, 0, 20}};
  const std::vector<std::uint8_t> active{1, 1, 1, 1, 0};  // the last is out of the simulation: not judged
  const auto found = check_motion(x, v, active, 10.0, "sphere");
  ASSERT_TRUE(found);
  std::cout << found->detail << "\n";
  EXPECT_EQ(found->what, "not finite");
  EXPECT_EQ(found->indices, (std::vector<std::size_t>{1, 2, 3}));
  EXPECT_NE(found->detail.find("3 spheres not finite, or faster than max_speed = 10 m/s"), std::string::npos);
  EXPECT_NE(found->detail.find("sphere 1: at (1, 2, 3) m, velocity (0, 0, 12.5) m/s, speed 12.5 m/s"),
            std::string::npos);
  EXPECT_NE(found->detail.find("sphere 2: at (nan, 0, 0) m"), std::string::npos);

  const auto fast = check_motion(x, v, {}, 10.0, "node", std::vector<std::uint64_t>{10, 11, 12, 13, 14});
  ASSERT_TRUE(fast);
  EXPECT_NE(fast->detail.find("node 14:"), std::string::npos);  // the ids, not the indices

  // Many: the first kMaxReported named, the rest counted.
  std::vector<Vec3> many_x(25, Vec3::Zero()), many_v(25, Vec3(0, 0, 100));
  const auto many = check_motion(many_x, many_v, {}, 10.0, "particle");
  ASSERT_TRUE(many);
  EXPECT_EQ(many->what, "too fast");
  EXPECT_EQ(many->indices.size(), Instability::kMaxReported);
  EXPECT_NE(many->detail.find("25 particles faster than max_speed = 10 m/s"), std::string::npos);
  EXPECT_NE(many->detail.find("; and 15 more"), std::string::npos);

  const std::vector<double> density{1000, 2100, kNaN, 400};
  const std::vector<std::uint32_t> material{0, 0, 0, 0};
  const std::vector<double> rest{1000};
  const auto dense = check_density(density, material, rest, {}, {.max_speed = 1, .min_density_ratio = 0.5,
                                                                 .max_density_ratio = 2.0});
  ASSERT_TRUE(dense);
  std::cout << dense->detail << "\n";
  EXPECT_EQ(dense->indices, (std::vector<std::size_t>{1, 2, 3}));
  EXPECT_NE(dense->detail.find("particle 1: density 2100 kg/m^3, 2.1 times its rest density"), std::string::npos);
  EXPECT_NE(dense->detail.find("outside sph.density_ratio_limits = [0.5, 2]"), std::string::npos);
}

TEST(Stability, TheFileHoldsTheCulpritsAndTheirNeighbours) {
  const auto folder = std::filesystem::temp_directory_path() / ("sabo-stability-" + std::to_string(::getpid()));
  std::filesystem::create_directories(folder);
  std::vector<Vec3> x, v;
  for (int i = 0; i < 10; ++i) {
    x.emplace_back(i, 0, 0);
    v.emplace_back(0, 0, i == 4 ? 1e4 : 0.0);
  }
  const auto found = check_motion(x, v, {}, 100.0, "sphere");
  ASSERT_TRUE(found);
  const std::vector<double> radius(10, 0.5);
  const std::pair<std::string, std::span<const double>> arrays[] = {{"radius", radius}};
  const auto file = instability_file(folder, Role::dem);
  EXPECT_EQ(file.filename(), "instability.vtp");
  EXPECT_EQ(instability_file(folder, Role::fem).filename(), "instability_fem_solver.vtp");  // the first is taken
  write_instability(file, x, v, *found, 1.5, arrays);
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  // The culprit (4) and the spheres within 1.5 m of it (3 and 5).
  EXPECT_NE(text.str().find("NumberOfPoints=\"3\""), std::string::npos) << text.str().substr(0, 400);
  for (const char* name : {"Name=\"velocity\"", "Name=\"culprit\"", "Name=\"index\"", "Name=\"radius\""}) {
    EXPECT_NE(text.str().find(name), std::string::npos) << name;
  }
  std::filesystem::remove_all(folder);
}

TEST(Stability, TheLimitsComeFromTheSceneOrAreDerived) {
  scene::Scene scene;
  scene.sph.sound_speed = 40.0;
  EXPECT_EQ(stability_limits(scene, Role::sph).max_speed, 40.0);  // the weakly compressible model's bound
  EXPECT_EQ(stability_limits(scene, Role::dem).max_speed, kDefaultMaxSpeed);
  scene::ParticleSet fast;
  fast.spheres.push_back({.center = Vec3::Zero(), .radius = 1, .velocity = Vec3(0, 0, -300), .angular_velocity = Vec3::Zero()});
  scene.particle_sets.push_back(fast);
  EXPECT_EQ(stability_limits(scene, Role::fem).max_speed, 3000.0);  // ten times the fastest initial speed
  scene.run.max_speed = 55.0;
  EXPECT_EQ(stability_limits(scene, Role::sph).max_speed, 55.0);
  EXPECT_EQ(stability_limits(scene, Role::dem).max_speed, 55.0);
  EXPECT_EQ(stability_limits(scene, Role::sph).min_density_ratio, 0.5);
  EXPECT_EQ(stability_limits(scene, Role::sph).max_density_ratio, 2.0);
}

}  // namespace
}  // namespace sabo::solver
