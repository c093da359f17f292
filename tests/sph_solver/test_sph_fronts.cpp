// Fronts (docs/scene.md [[fronts]]): the leading edge of a block of fluid, spray left out, the speed and
// a station's arrival between two samples, a station's depth, and fronts.csv and the results across a
// checkpoint.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "libsabo/io/hdf5.hpp"
#include "sph_solver/fronts.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::water_scene;

constexpr double kDx = 0.05, kDepth = 0.3, kSoundSpeed = 200.0;
const Vec3 kVelocity(0.3, -0.2, 0.1);

// A block [0, length] x [0, 0.4] x [0, 0.3] m moving at kVelocity, with a front along x.
scene::Scene block_scene(double length) {
  scene::Scene scene = water_scene(kDx, kSoundSpeed);
  scene::FluidBody body = box_body("water", Vec3::Zero(), Vec3(length, 0.4, kDepth));
  body.velocity = kVelocity;
  scene.fluids.push_back(body);
  scene.run.output_interval = 0.1;
  scene::Front front;
  front.name = "front";
  front.kind = scene::Front::Kind::channel;  // a flat bed at z = 0 along the block's middle
  front.start = Vec3(0, 0.2, 7.0);           // its z is the bed's, not the start's
  front.direction = Vec3(1, 0, 0);
  front.bed = {{-1.0, 0.0}, {2.0, 0.0}};
  front.depth_height = 0.6;
  front.stations = {{"inside", 0.2}, {"between", 0.475}, {"dry", 0.9}};
  scene.fronts = {front};
  return scene;
}

SphModel computed_model(const scene::Scene& scene) {
  SphModel model(scene);
  model.compute_internal_forces(0.0);
  return model;
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(SphFronts, TheFrontIsTheLeadingParticleLessThoseAllowedAhead) {
  scene::Scene scene = block_scene(0.4);
  const SphModel model = computed_model(scene);
  scene::Front front = scene.fronts.front();
  front.kind = scene::Front::Kind::axis;
  front.start = Vec3(0.1, 0.0, 0.0);
  // The lattice's last column stands at x = 0.4 - dx/2; it holds 8 x 6 = 48 particles.
  struct Case {
    std::size_t ahead;
    double expected;
  };
  for (const Case c : {Case{0, 0.275}, Case{47, 0.275}, Case{48, 0.225}}) {
    front.ahead = c.ahead;
    const FrontReading reading = read_front(model, front);
    std::cout << "ahead " << c.ahead << ": front measured " << reading.position << " m, expected " << c.expected
              << " m; flow speed " << reading.flow_speed << " m/s, expected " << kVelocity.x() << "\n";
    EXPECT_NEAR(reading.position, c.expected, 1e-12);
    EXPECT_NEAR(reading.point.x() - 0.1, c.expected, 1e-12);
    EXPECT_NEAR(reading.flow_speed, kVelocity.x(), 1e-12);
  }
  front.ahead = model.size();
  EXPECT_TRUE(std::isnan(read_front(model, front).position)) << "no front with every particle ahead of it";
}

TEST(SphFronts, AlongABendingTerrainLineTheFrontIsTheFarthestAlongIt) {
  const SphModel model = computed_model(block_scene(0.4));
  scene::Front front = block_scene(0.4).fronts.front();
  // Along y = 0.2 to x = 0.25, then along +y: the block's corner (0.375, 0.375) leads, at 0.45 + 0.175.
  front.kind = scene::Front::Kind::terrain;
  front.structure = "gully";
  front.path = {Vec3(-0.2, 0.2, 0.0), Vec3(0.25, 0.2, 0.0), Vec3(0.25, 1.0, 0.0)};
  front.path_s = {0.0, 0.45, 1.25};
  const FrontReading reading = read_front(model, front);
  std::cout << "bending line: front measured " << reading.position << " m, expected 0.625 m; flow speed "
            << reading.flow_speed << " m/s, expected " << kVelocity.y() << " (along the second leg)\n";
  EXPECT_NEAR(reading.position, 0.625, 1e-12);
  EXPECT_NEAR(reading.point.y(), 0.375, 1e-12);
  EXPECT_NEAR(reading.flow_speed, kVelocity.y(), 1e-12);
  EXPECT_TRUE(front.path_point(0.5).isApprox(Vec3(0.25, 0.25, 0.0), 1e-12));
  EXPECT_TRUE(front.path_point(0.2).isApprox(Vec3(0.0, 0.2, 0.0), 1e-12));
  const auto projection = front.project(Vec3(0.1, 0.18, 3.0));
  EXPECT_NEAR(projection.s, 0.3, 1e-12);
  EXPECT_TRUE(projection.tangent.isApprox(Vec3(1, 0, 0), 1e-12));
}

TEST(SphFronts, SpeedArrivalAndDepthBetweenTwoSamples) {
  const auto folder = std::filesystem::temp_directory_path() / "sabo_test_fronts_speed";
  std::filesystem::remove_all(folder);
  std::filesystem::create_directories(folder);
  const scene::Scene scene = block_scene(0.4);
  const SphModel short_block = computed_model(scene);
  const SphModel long_block = computed_model(block_scene(0.6));
  FrontRecorder recorder(folder, scene);
  recorder.sample(short_block, 0.0);   // front at 0.375 m
  recorder.sample(short_block, 0.05);  // not due (interval 0.1 s)
  recorder.sample(long_block, 0.1);    // front at 0.575 m
  const nlohmann::json results = recorder.results();
  std::cout << results.dump(1) << "\n";
  const auto& front = results.at("front");
  EXPECT_EQ(front.at("samples"), 2);
  EXPECT_NEAR(front.at("final_position").get<double>(), 0.575, 1e-12);
  // (0.575 - 0.375) m / 0.1 s; the station at 0.475 m is passed halfway, at t = 0.05 s.
  EXPECT_NEAR(front.at("max_speed").get<double>(), 2.0, 1e-9);
  EXPECT_NEAR(front.at("max_speed_time").get<double>(), 0.1, 0);
  const auto& stations = front.at("stations");
  EXPECT_NEAR(stations.at("inside").at("arrival_time").get<double>(), 0.0, 0);
  EXPECT_NEAR(stations.at("between").at("arrival_time").get<double>(), 0.05, 1e-12);
  EXPECT_TRUE(stations.at("dry").at("arrival_time").is_null());
  const double depth = stations.at("inside").at("final_depth").get<double>();
  std::cout << "depth at the station inside measured " << depth << " m, expected " << kDepth << " m (+- dx/4)\n";
  EXPECT_NEAR(depth, kDepth, 0.25 * kDx);
  EXPECT_EQ(stations.at("dry").at("max_depth").get<double>(), 0.0);
  const std::string csv = read_text(folder / "fronts.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')), "time,front,position,speed,flow_speed,x,y,z");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3);
  const std::string stations_csv = read_text(folder / "front_stations.csv");
  EXPECT_EQ(std::count(stations_csv.begin(), stations_csv.end(), '\n'), 1 + 2 * 3);
  std::filesystem::remove_all(folder);
}

TEST(SphFronts, FilesAndResultsContinueFromACheckpoint) {
  const auto folder = std::filesystem::temp_directory_path() / "sabo_test_fronts_checkpoint";
  std::filesystem::remove_all(folder);
  std::filesystem::create_directories(folder);
  const scene::Scene scene = block_scene(0.4);
  const SphModel short_block = computed_model(scene);
  const SphModel long_block = computed_model(block_scene(0.6));
  const auto checkpoint = folder / "checkpoint.h5";
  FrontRecorder recorder(folder, scene);
  recorder.sample(short_block, 0.0);
  {
    io::hdf5::File file = io::hdf5::File::create(checkpoint);
    recorder.save(file);
  }
  const std::string fronts_at_checkpoint = read_text(folder / "fronts.csv");
  recorder.sample(long_block, 0.1);
  recorder.sample(long_block, 0.2);
  const std::string uninterrupted = read_text(folder / "fronts.csv");
  const std::string uninterrupted_stations = read_text(folder / "front_stations.csv");

  FrontRecorder resumed(folder, scene);
  resumed.load(io::hdf5::File::open(checkpoint));
  EXPECT_EQ(read_text(folder / "fronts.csv"), fronts_at_checkpoint);
  resumed.sample(long_block, 0.1);
  resumed.sample(long_block, 0.2);
  EXPECT_EQ(read_text(folder / "fronts.csv"), uninterrupted);
  EXPECT_EQ(read_text(folder / "front_stations.csv"), uninterrupted_stations);
  EXPECT_EQ(resumed.results(), recorder.results());
  std::filesystem::remove_all(folder);
}

}  // namespace
}  // namespace sabo::sph
