// The scene check's warnings (libsabo/scene/warnings.hpp): a structure that
// nothing can touch is named with its line and the fix, sabo_scene check
// prints it and still gives the launch plan, and no scene of configs/ warns.
#include <gtest/gtest.h>

#include <iostream>

#include "libsabo/scene/loader.hpp"
#include "libsabo/scene/warnings.hpp"
#include "scene_test_support.hpp"

namespace sabo::scene {
namespace {

using testing::kGround;
using testing::kOneSphere;
using testing::kSceneHead;

std::vector<std::string> warnings_of(const std::string& text) {
  testing::TempFolder folder;
  return scene_warnings(load_scene(folder.write("scene.toml", text)));
}

TEST(SceneWarnings, StructureThatNothingTouchesIsNamed) {
  const auto file = testing::source_dir() / "tests/scenes/warn/untouchable_structure.toml";
  const auto warnings = scene_warnings(load_scene(file));
  for (const auto& w : warnings) std::cout << w << "\n";
  ASSERT_EQ(warnings.size(), 1u) << "expected one warning, for the marker only";
  const std::string& w = warnings[0];
  EXPECT_NE(w.find("untouchable_structure.toml:32: key 'structures[1]': warning: nothing can touch structure "
                   "\"marker\""),
            std::string::npos)
      << w;
  EXPECT_NE(w.find("none of the scene's particle sets and other structures has contact with it enabled"),
            std::string::npos)
      << w;
  EXPECT_NE(w.find("Fix: give it a contact"), std::string::npos) << w;
}

TEST(SceneWarnings, AStepAboveTheStableOneAndTcpInClearAreSaid) {
  const auto beta = warnings_of(std::string(kSceneHead) + kOneSphere + kGround + "[solvers.dem]\nbeta = 2.5\n");
  ASSERT_EQ(beta.size(), 1u);
  EXPECT_NE(beta[0].find("key 'solvers.dem.beta': warning: beta = 2.5 takes steps 2.5 times the dem_solver's stable "
                         "step: the run may become unstable"),
            std::string::npos)
      << beta[0];
  std::string clear = std::string(kSceneHead) + kOneSphere + kGround;
  clear.insert(clear.find("[materials"), "endpoint = \"tcp://0.0.0.0:5555\"\ntcp_security = \"none\"\n");
  const auto tcp = warnings_of(clear);
  ASSERT_EQ(tcp.size(), 1u);
  EXPECT_NE(tcp[0].find("key 'run.endpoint': warning: run.tcp_security = \"none\" over tcp://0.0.0.0:5555: any process "
                        "that reaches the port, on any interface of this machine, can register as a solver"),
            std::string::npos)
      << tcp[0];
}

TEST(SceneWarnings, CheckPrintsTheWarningAndStillPlansTheRun) {
  const auto result =
      testing::run_tool("check '" + (testing::source_dir() / "tests/scenes/warn/untouchable_structure.toml").string() +
                        "' --bin-dir '" + testing::bin_dir().string() + "'");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.err.find("nothing can touch structure \"marker\""), std::string::npos) << result.err;
  EXPECT_NE(result.out.find("\"processes\""), std::string::npos) << result.out;
}

TEST(SceneWarnings, TouchedStructuresAndALoneDeformableOneGiveNone) {
  // Boulders on the ground: the default DEM-FEM contact touches it.
  EXPECT_TRUE(warnings_of(std::string(kSceneHead) + kOneSphere + kGround).empty());
  // A lone deformable beam under its own weight is a valid FEM scene.
  EXPECT_TRUE(warnings_of(std::string(kSceneHead) + R"(
[[structures]]
name = "beam"
material = "concrete"
rigid = false
shape = "box"
min = [0.0, 0.0, 0.0]
max = [2.0, 0.2, 0.2]
fixed = ["x-"]
)")
                  .empty());
}

TEST(SceneWarnings, TwoDeformableStructuresWithoutContactAreBothNamed) {
  const std::string block = R"(
[[structures]]
name = "NAME"
material = "concrete"
rigid = false
shape = "box"
min = [0.0, 0.0, Z0]
max = [1.0, 1.0, Z1]
)";
  auto with = [&](const char* name, const char* z0, const char* z1) {
    std::string s = block;
    s.replace(s.find("NAME"), 4, name);
    s.replace(s.find("Z0"), 2, z0);
    s.replace(s.find("Z1"), 2, z1);
    return s;
  };
  const std::string scene = std::string(kSceneHead) + with("lower", "0.0", "1.0") + with("upper", "1.5", "2.5");
  const auto warnings = warnings_of(scene);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[0].find("\"lower\""), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[1].find("\"upper\""), std::string::npos) << warnings[1];
  // [contact.fem_fem] enabled: they can meet.
  EXPECT_TRUE(warnings_of(scene + "\n[contact.fem_fem]\nenabled = true\n").empty());
}

TEST(SceneWarnings, SensorNarrowerThanTheParticleSpacingIsNamed) {
  // Water on the ground (dx = 10 mm) and sensors on the ground's face: 5 mm x 100 mm is narrower than dx, 20 mm
  // x 20 mm is not, and a whole-part sensor never warns.
  const std::string fluid = std::string(kSceneHead) + kGround + R"(
[materials.water]
density = 1000.0
youngs_modulus = 2.2e9
poisson_ratio = 0.0

[sph]
particle_spacing = 0.01
sound_speed = 10.0

[[fluids]]
name = "water"
material = "water"
shape = "box"
min = [0.0, 0.0, 0.0]
max = [0.2, 0.2, 0.1]

[[sensors]]
name = "whole"
part = "ground"
)";
  const std::string strip = R"(
[[sensors]]
name = "strip"
part = "ground"
min = [0.05, 0.0, -0.001]
max = [0.055, 0.1, 0.001]
)";
  const std::string square = R"(
[[sensors]]
name = "square"
part = "ground"
min = [0.05, 0.05, -0.001]
max = [0.07, 0.07, 0.001]
)";
  EXPECT_TRUE(warnings_of(fluid + square).empty());
  const auto warnings = warnings_of(fluid + strip + square);
  for (const auto& w : warnings) std::cout << w << "\n";
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("key 'sensors[1]': warning: sensor \"strip\" covers 0.0005 m^2 of \"ground\", 0.005 m "
                             "wide along the face, narrower than the particle spacing sph.particle_spacing = 0.01 m"),
            std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[0].find("Fix: make the box at least 0.01 m wide along the face"), std::string::npos)
      << warnings[0];
}

TEST(SceneWarnings, NoSceneOfTheConfigsWarns) {
  std::size_t scenes = 0;
  for (const char* folder : {"configs", "configs/tests"}) {
    for (const auto& entry : std::filesystem::directory_iterator(testing::source_dir() / folder)) {
      if (entry.path().extension() != ".toml") continue;
      ++scenes;
      const auto warnings = scene_warnings(load_scene(entry.path()));
      EXPECT_TRUE(warnings.empty()) << entry.path() << ": " << (warnings.empty() ? "" : warnings[0]);
    }
  }
  EXPECT_GT(scenes, 10u);
}

}  // namespace
}  // namespace sabo::scene
