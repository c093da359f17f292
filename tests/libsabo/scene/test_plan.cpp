// The launch plan and the `sabo_scene check` command.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "libsabo/scene/loader.hpp"
#include "libsabo/scene/plan.hpp"
#include "scene_test_support.hpp"

namespace sabo::scene {
namespace {

using testing::kGround;
using testing::kOneSphere;
using testing::kSceneHead;

std::vector<std::string> roles_of(const nlohmann::json& plan) {
  std::vector<std::string> roles;
  for (const auto& process : plan.at("processes")) roles.push_back(process.at("role"));
  return roles;
}

TEST(LaunchPlan, BouldersChute) {
  const auto file = testing::source_dir() / "configs/boulders_chute.toml";
  const Scene scene = load_scene(file);
  const nlohmann::json plan = launch_plan(scene, "/opt/sabo/bin/");
  std::cout << plan.dump(2) << "\n";
  EXPECT_EQ(plan.at("scene"), std::filesystem::canonical(file).string());
  EXPECT_EQ(plan.at("endpoint"), "ipc");
  EXPECT_DOUBLE_EQ(plan.at("end_time").get<double>(), scene.run.end_time);
  EXPECT_DOUBLE_EQ(plan.at("output_interval").get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(plan.at("hang_timeout").get<double>(), 10.0);
  EXPECT_FALSE(plan.contains("max_dt"));
  EXPECT_EQ(roles_of(plan), (std::vector<std::string>{"coupler", "dem_solver", "fem_solver"}));
  EXPECT_EQ(plan["processes"][0]["command"], nlohmann::json::array({"/opt/sabo/bin/coupler"}));
  EXPECT_EQ(plan["processes"][1]["command"], nlohmann::json::array({"/opt/sabo/bin/dem_solver"}));
  EXPECT_EQ(plan["processes"][2]["command"], nlohmann::json::array({"/opt/sabo/bin/fem_solver"}));
  EXPECT_DOUBLE_EQ(plan["processes"][1]["beta"].get<double>(), 0.25);
  EXPECT_EQ(plan["bodies"]["spheres"], 200);
  EXPECT_EQ(plan["bodies"]["particle_sets"], 1);
  EXPECT_EQ(plan["bodies"]["structures"], 2);
  EXPECT_EQ(plan["bodies"]["fluids"], 0);
}

TEST(LaunchPlan, OnlyTheNeededRolesAndCustomCommands) {
  testing::TempFolder folder;
  std::string head = kSceneHead;
  head.insert(head.find("[materials"), "endpoint = \"tcp://127.0.0.1:5555\"\nmax_dt = 1e-4\n");
  const Scene dem_only =
      load_scene(folder.write("a.toml", head + kOneSphere + "[solvers.dem]\ncommand = [\"sh\", \"-c\", \"x\"]\n"));
  const nlohmann::json plan = launch_plan(dem_only, "bin");
  EXPECT_EQ(roles_of(plan), (std::vector<std::string>{"coupler", "dem_solver"}));
  EXPECT_EQ(plan["processes"][1]["command"], nlohmann::json::array({"sh", "-c", "x"}));
  EXPECT_EQ(plan["processes"][0]["command"][0], (std::filesystem::current_path() / "bin/coupler").string());
  EXPECT_EQ(plan["endpoint"], "tcp://127.0.0.1:5555");
  EXPECT_DOUBLE_EQ(plan["max_dt"].get<double>(), 1e-4);
  EXPECT_EQ(plan["bodies"]["spheres"], 1);

  const Scene fem_only = load_scene(folder.write("b.toml", std::string(kSceneHead) + kGround));
  EXPECT_EQ(roles_of(launch_plan(fem_only, "/x")), (std::vector<std::string>{"coupler", "fem_solver"}));
}

TEST(SceneTool, CheckPrintsThePlan) {
  const auto file = testing::source_dir() / "configs/tests/sphere_drop.toml";
  const auto result = testing::run_tool("check '" + file.string() + "' --bin-dir /opt/sabo/bin");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_TRUE(result.err.empty()) << result.err;
  const auto plan = nlohmann::json::parse(result.out);
  EXPECT_EQ(plan, launch_plan(load_scene(file), "/opt/sabo/bin"));

  // Without --bin-dir the executables are looked for beside sabo_scene.
  const auto beside = testing::run_tool("check '" + file.string() + "'");
  ASSERT_EQ(beside.exit_code, 0) << beside.err;
  EXPECT_EQ(nlohmann::json::parse(beside.out)["processes"][0]["command"][0],
            (std::filesystem::canonical(testing::bin_dir()) / "coupler").string());
}

TEST(SceneTool, MissingSceneFileIsBadInput) {
  const auto missing = testing::run_tool("check /nonexistent/sabo/scene.toml");
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("cannot open the scene file"), std::string::npos) << missing.err;
}

TEST(SceneTool, CommandLineErrorsExitWithOne) {
  EXPECT_EQ(testing::run_tool("frobnicate").exit_code, 1);
  EXPECT_EQ(testing::run_tool("check").exit_code, 1);
  EXPECT_EQ(testing::run_tool("--help").exit_code, 0);
}

}  // namespace
}  // namespace sabo::scene
