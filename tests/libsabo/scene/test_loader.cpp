// The scene loader: the configs load, values map onto the scene model,
// defaults agree with scene.hpp, and the checks across keys fire. Over 800
// lines as one concept, the loader's mapping of every section; the refused
// scenes of tests/scenes/bad are test_bad_scenes.cpp's.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/scene/estimate.hpp"
#include "libsabo/scene/loader.hpp"
#include "libsabo/scene/suggest.hpp"
#include "scene_test_support.hpp"

namespace sabo::scene {
namespace {

using testing::kGround;
using testing::kOneSphere;
using testing::kSceneHead;
using testing::TempFolder;

Scene load_text(const std::string& text) {
  TempFolder folder;
  return load_scene(folder.write("scene.toml", text));
}

// The SceneError message of loading `text` written into `folder` (empty if it loads).
std::string error_of_in(const TempFolder& folder, const std::string& text) {
  try {
    (void)load_scene(folder.write("scene.toml", text));
  } catch (const SceneError& error) {
    return error.what();
  }
  return {};
}

// The SceneError message of loading `text` (empty if it loads).
std::string error_of(const std::string& text) {
  TempFolder folder;
  return error_of_in(folder, text);
}

std::size_t line_count(const std::string& text) {
  return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) + (text.empty() ? 0 : 1);
}

TEST(SceneLoader, EveryConfigLoads) {
  std::size_t loaded = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(testing::source_dir() / "configs")) {
    if (entry.path().extension() != ".toml") continue;
    // Study files (./sabo study) are checked by e2e_study; their scenes are the configs here.
    if (entry.path().parent_path().filename() == "studies") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW({
      const Scene scene = load_scene(entry.path());
      EXPECT_FALSE(scene.solvers.empty());
    });
    ++loaded;
  }
  std::cout << "configs loaded: " << loaded << "\n";
  EXPECT_GE(loaded, 5u);
}

TEST(SceneLoader, BouldersChuteIsThePaperSetup) {
  const Scene scene = load_scene(testing::source_dir() / "configs/boulders_chute.toml");
  EXPECT_TRUE(scene.file.is_absolute());
  EXPECT_DOUBLE_EQ(scene.run.output_interval, 0.25);
  EXPECT_GT(scene.run.end_time, 0.0);
  ASSERT_EQ(scene.particle_sets.size(), 1u);
  const ParticleSet& boulders = scene.particle_sets[0];
  EXPECT_EQ(boulders.kind, ParticleSet::Kind::fill);
  EXPECT_EQ(boulders.count, 200u);
  EXPECT_DOUBLE_EQ(boulders.diameter_min, 1.0);
  EXPECT_DOUBLE_EQ(boulders.diameter_max, 2.0);
  const Material& granite = scene.materials[scene.material_index(boulders.material)];
  EXPECT_DOUBLE_EQ(granite.density, 3000.0);
  EXPECT_DOUBLE_EQ(granite.youngs_modulus, 30e9);
  EXPECT_DOUBLE_EQ(granite.poisson_ratio, 0.3);
  EXPECT_DOUBLE_EQ(scene.dem_contact.normal_damping_ratio, 0.7);
  EXPECT_DOUBLE_EQ(scene.dem_contact.tangential_damping_ratio, 0.4);
  EXPECT_DOUBLE_EQ(scene.dem_contact.friction, 1.0);
  EXPECT_DOUBLE_EQ(scene.dem_contact.rolling_friction, 0.1);
  EXPECT_DOUBLE_EQ(scene.dem_contact.normal_stiffness_scale, 0.01);
  EXPECT_FALSE(scene.dem_contact.normal_stiffness.has_value());

  ASSERT_EQ(scene.structures.size(), 2u);
  const Structure& chute = scene.structures[0];
  EXPECT_EQ(chute.shape.type, Shape::Type::chute);
  EXPECT_DOUBLE_EQ(chute.shape.slope_deg, 20.0);
  EXPECT_DOUBLE_EQ(chute.shape.length, 60.0);
  EXPECT_DOUBLE_EQ(chute.shape.width, 8.0);
  EXPECT_DOUBLE_EQ(chute.shape.wall_height, 4.0);
  EXPECT_DOUBLE_EQ(chute.shape.end_wall_height, 0.0);  // the end wall is a part of its own
  const Structure& wall = scene.structures[1];
  EXPECT_EQ(wall.name, "wall");
  EXPECT_EQ(wall.shape.type, Shape::Type::plane);
  // The wall stands at the floor's lower end (60 m along a 20 degree slope), facing up the chute.
  const double slope = 20.0 * std::numbers::pi / 180.0;
  const Vec3 floor_end(60.0 * std::cos(slope), 0.0, -60.0 * std::sin(slope));
  const Vec3 down_slope(std::cos(slope), 0.0, -std::sin(slope));
  EXPECT_NEAR((wall.shape.origin - floor_end).dot(down_slope), 0.0, 1e-3);
  EXPECT_NEAR(wall.shape.normal.dot(-down_slope), 1.0, 1e-6);
  const Material& concrete = scene.materials[scene.material_index(chute.material)];
  EXPECT_DOUBLE_EQ(concrete.poisson_ratio, 0.24);
  EXPECT_DOUBLE_EQ(scene.surface_contact("boulders", "chute").friction, 0.3);

  // The fill box lies between the side walls and above the floor's top edge.
  EXPECT_LE(std::abs(boulders.region.min.y()), chute.shape.width / 2);
  EXPECT_LE(std::abs(boulders.region.max.y()), chute.shape.width / 2);
  EXPECT_GT(boulders.region.min.z(), chute.shape.origin.z());
  ASSERT_NE(scene.solver(Role::dem), nullptr);
  ASSERT_NE(scene.solver(Role::fem), nullptr);
  EXPECT_FALSE(scene.needs(Role::sph));
}

TEST(SceneLoader, SphereDropIsTheBrief) {
  const Scene scene = load_scene(testing::source_dir() / "configs/tests/sphere_drop.toml");
  ASSERT_EQ(scene.particle_sets.size(), 1u);
  ASSERT_EQ(scene.particle_sets[0].spheres.size(), 1u);
  const Sphere& sphere = scene.particle_sets[0].spheres[0];
  EXPECT_DOUBLE_EQ(sphere.radius, 0.5);
  EXPECT_DOUBLE_EQ(sphere.center.z(), 3.0);
  EXPECT_EQ(scene.structures.at(0).shape.type, Shape::Type::plane);
  EXPECT_DOUBLE_EQ(scene.dem_fem_default.normal_damping_ratio, 0.3);
  EXPECT_DOUBLE_EQ(scene.dem_fem_default.friction, 0.0);
  EXPECT_DOUBLE_EQ(scene.run.end_time, 2.5);
  EXPECT_DOUBLE_EQ(scene.structures.at(0).shape.element_size, 1.0);
}

// The schema's defaults (docs/scene.md) must be the defaults of scene.hpp.
TEST(SceneLoader, SchemaDefaultsEqualSceneModelDefaults) {
  const Scene scene = load_text(std::string(kSceneHead) + kOneSphere + kGround);
  const RunSettings run_defaults;
  EXPECT_EQ(scene.run.endpoint, run_defaults.endpoint);
  EXPECT_EQ(scene.run.gravity, run_defaults.gravity);
  EXPECT_EQ(scene.run.hang_timeout, run_defaults.hang_timeout);
  EXPECT_FALSE(scene.run.max_dt.has_value());

  const DemContact dem;
  EXPECT_EQ(scene.dem_contact.normal_damping_ratio, dem.normal_damping_ratio);
  EXPECT_EQ(scene.dem_contact.tangential_damping_ratio, dem.tangential_damping_ratio);
  EXPECT_EQ(scene.dem_contact.friction, dem.friction);
  EXPECT_EQ(scene.dem_contact.rolling_friction, dem.rolling_friction);
  EXPECT_EQ(scene.dem_contact.normal_stiffness, dem.normal_stiffness);
  EXPECT_EQ(scene.dem_contact.normal_stiffness_scale, dem.normal_stiffness_scale);
  EXPECT_EQ(scene.dem_contact.tangential_stiffness_ratio, dem.tangential_stiffness_ratio);

  const SurfaceContact surface;
  EXPECT_EQ(scene.dem_fem_default.friction, surface.friction);
  EXPECT_EQ(scene.dem_fem_default.penalty_scale, surface.penalty_scale);
  EXPECT_EQ(scene.dem_fem_default.normal_stiffness, surface.normal_stiffness);
  EXPECT_EQ(scene.dem_fem_default.normal_damping_ratio, surface.normal_damping_ratio);
  EXPECT_EQ(scene.dem_fem_default.tangential_damping_ratio, surface.tangential_damping_ratio);
  EXPECT_EQ(scene.dem_fem_default.enabled, surface.enabled);
  EXPECT_EQ(scene.dem_fem_default.rolling, surface.rolling);
  EXPECT_EQ(scene.dem_fem_default.rolling_friction, surface.rolling_friction);
  EXPECT_EQ(scene.dem_fem_default.rolling_viscosity, surface.rolling_viscosity);
  EXPECT_FALSE(surface.has_rolling());
  EXPECT_EQ(scene.particle_sets[0].fixed, ParticleSet{}.fixed);

  const Recording recording;
  EXPECT_EQ(scene.recording.enabled, recording.enabled);
  EXPECT_EQ(scene.recording.fields, recording.fields);
  EXPECT_EQ(scene.recording.every, recording.every);
  EXPECT_EQ(scene.recording.first_step, recording.first_step);
  EXPECT_EQ(scene.recording.last_step, recording.last_step);
  EXPECT_EQ(scene.recording.flush_interval, recording.flush_interval);

  const SolverSettings solver;
  ASSERT_EQ(scene.solvers.size(), 2u);
  for (const auto& s : scene.solvers) {
    EXPECT_EQ(s.beta, solver.beta);
    EXPECT_TRUE(s.command.empty());
  }
  const Sphere sphere;
  EXPECT_EQ(scene.particle_sets[0].spheres[0].velocity, sphere.velocity);
  EXPECT_EQ(scene.particle_sets[0].spheres[0].angular_velocity, sphere.angular_velocity);

  const Structure structure_defaults;
  const Shape shape_defaults;
  const Structure& ground = scene.structures[0];
  EXPECT_EQ(ground.rigid, structure_defaults.rigid);
  EXPECT_EQ(ground.thickness, structure_defaults.thickness);
  EXPECT_EQ(ground.shape.normal, shape_defaults.normal);
  EXPECT_EQ(ground.shape.direction, shape_defaults.direction);
  EXPECT_EQ(ground.shape.element_size, shape_defaults.element_size);

  const Scene filled = load_text(std::string(kSceneHead) + R"(
[[particles]]
name = "b"
material = "granite"
fill = { min = [0, 0, 0], max = [4, 4, 4], count = 5, diameter = [0.5, 1.0] }
[[structures]]
name = "dam"
material = "concrete"
shape = "chute"
origin = [0, 0, 0]
length = 5
width = 2
slope_deg = 10
)");
  const ParticleSet set_defaults;
  EXPECT_EQ(filled.particle_sets[0].seed, set_defaults.seed);
  EXPECT_EQ(filled.particle_sets[0].velocity, set_defaults.velocity);
  EXPECT_EQ(filled.structures[0].shape.wall_height, shape_defaults.wall_height);
  EXPECT_EQ(filled.structures[0].shape.end_wall_height, shape_defaults.end_wall_height);
  EXPECT_EQ(filled.structures[0].shape.direction, shape_defaults.direction);
}

TEST(SceneLoader, ReadsAChannelProfileInlineAndFromItsCsvFile) {
  TempFolder folder;
  folder.write("profiles/gully.csv",
               "# Branch 2, assumed\ndistance_m,elevation_m\n0,1300\n\n 250.5 ; 1180\n900\t985.25\n");
  const auto file = folder.write("scene.toml", std::string(kSceneHead) + kOneSphere + R"(
[[structures]]
name = "gully"
material = "concrete"
shape = "channel"
origin = [10, 5, 99]
direction = [0, 3, 0]
profile_file = "profiles/gully.csv"
width = 7
wall_height = 12
start_wall_height = 20
element_size = 2
[[structures]]
name = "flume"
material = "concrete"
shape = "channel"
origin = [0, 0, 0]
profile = [[0.0, 1.0], [2.0, 0.5]]
width = 1
wall_height = 0.5
floor = false
)");
  const Scene scene = load_scene(file);
  const Shape& gully = scene.structures.at(0).shape;
  EXPECT_EQ(gully.type, Shape::Type::channel);
  EXPECT_EQ(gully.direction, Vec3(0, 1, 0));
  const std::vector<std::array<double, 2>> expected{{0, 1300}, {250.5, 1180}, {900, 985.25}};
  EXPECT_EQ(gully.profile, expected);
  EXPECT_DOUBLE_EQ(gully.width, 7.0);
  EXPECT_DOUBLE_EQ(gully.wall_height, 12.0);
  EXPECT_DOUBLE_EQ(gully.start_wall_height, 20.0);
  EXPECT_DOUBLE_EQ(gully.end_wall_height, 0.0);
  const Shape& flume = scene.structures.at(1).shape;
  EXPECT_EQ(flume.profile.size(), 2u);
  EXPECT_DOUBLE_EQ(flume.profile[1][1], 0.5);
  EXPECT_TRUE(gully.floor);
  EXPECT_FALSE(flume.floor);
}

TEST(SceneLoader, ReadsInflowsAfterTheFluidsWithTheirHydrographsInlineAndFromCsv) {
  TempFolder folder;
  folder.write("q.csv", "# design event\ntime_s,discharge_m3s\n0,0\n10 ; 1530\n60\t0\n");
  const std::string text = R"(format_version = 1
[run]
end_time = 80.0
output_interval = 1.0
[materials.slurry]
density = 2000.0
youngs_modulus = 1e9
poisson_ratio = 0.3
rheology = "bingham"
viscosity = 20.0
yield_stress = 500.0
[sph]
particle_spacing = 1.0
sound_speed = 400.0
[[fluids]]
name = "pool"
material = "slurry"
shape = "box"
min = [0.0, 0.0, 0.0]
max = [4.0, 4.0, 2.0]
[[inflows]]
name = "event"
material = "slurry"
position = [-10.0, 2.0, 5.0]
direction = [3.0, 0.0, -1.0]
width = 7.0
depth = 3.2
hydrograph_file = "q.csv"
[[inflows]]
name = "tributary"
material = "slurry"
position = [0.0, -20.0, 5.0]
direction = [0.0, 1.0, 0.0]
width = 2.0
depth = 1.0
hydrograph = [[5.0, 0.0], [6.0, 4.0]]
hydrostatic = false
)";
  const Scene scene = load_scene(folder.write("scene.toml", text));
  ASSERT_EQ(scene.fluids.size(), 3u);
  EXPECT_EQ(scene.fluids[0].shape, FluidBody::Shape::box);
  const FluidBody& event = scene.fluids[1];
  EXPECT_EQ(event.name, "event");
  EXPECT_EQ(event.shape, FluidBody::Shape::inflow);
  EXPECT_TRUE(event.hydrostatic);
  const std::vector<std::array<double, 2>> q{{0, 0}, {10, 1530}, {60, 0}};
  EXPECT_EQ(event.inflow.hydrograph, q);
  EXPECT_NEAR((event.inflow.direction - Vec3(3, 0, -1).normalized()).norm(), 0.0, 1e-15);
  EXPECT_NEAR((event.inflow.across() - Vec3(0, 1, 0)).norm(), 0.0, 1e-15);
  EXPECT_GT(event.inflow.up().z(), 0.9);  // perpendicular to the bed, upwards
  EXPECT_NEAR(event.inflow.up().dot(event.inflow.direction), 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(event.inflow.volume(0, 80), 0.5 * 1530 * 60);
  // 7 x 3 particles a layer, a buffer of ceil(3) + 1 layers, 45 900 m^3 over 21 m^2 is 2185.7 m of advance.
  const InflowLattice lattice = event.inflow.lattice(scene.sph, scene.run.end_time);
  EXPECT_EQ(lattice.per_layer(), 21u);
  EXPECT_EQ(lattice.layers, 4u + 2186u + 1u);
  const FluidBody& tributary = scene.fluids[2];
  EXPECT_FALSE(tributary.hydrostatic);
  EXPECT_DOUBLE_EQ(tributary.inflow.discharge(5.5), 2.0);
  EXPECT_DOUBLE_EQ(tributary.inflow.discharge(7.0), 0.0);
  // The estimate counts every particle the inflows will need.
  EXPECT_DOUBLE_EQ(estimate_scene(scene).fluid_particles[1], static_cast<double>(lattice.particles()));

  std::string both_text = text;
  both_text.replace(both_text.find("hydrograph_file"), 0, "hydrograph = [[0.0, 1.0], [1.0, 0.0]]\n");
  const std::string both = error_of_in(folder, both_text);
  EXPECT_NE(both.find("gives both hydrograph and hydrograph_file"), std::string::npos) << both;
  const std::string zero = error_of(std::string(R"(format_version = 1
[run]
end_time = 1.0
output_interval = 0.1
[materials.water]
density = 1000.0
youngs_modulus = 1e9
poisson_ratio = 0.0
[sph]
particle_spacing = 0.1
sound_speed = 20.0
[[inflows]]
name = "dry"
material = "water"
position = [0.0, 0.0, 0.0]
width = 0.05
depth = 1.0
hydrograph = [[0.0, 0.0], [1.0, 0.0]]
)"));
  EXPECT_NE(zero.find("inflows[0].width"), std::string::npos) << zero;
  EXPECT_NE(zero.find("smaller than the particle spacing"), std::string::npos) << zero;
  EXPECT_NE(zero.find("every discharge is 0: nothing would enter"), std::string::npos) << zero;
}

// A 10 x 8 grid of 5 m cells from (1000, 2000), the ground rising 0.1 m per m along x.
constexpr const char* kRampGrid =
    "ncols 10\nnrows 8\nxllcorner 1000\nyllcorner 2000\ncellsize 5\nNODATA_value -9999\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n"
    "300.25 300.75 301.25 301.75 302.25 302.75 303.25 303.75 304.25 304.75\n";

constexpr const char* kTerrainHead = R"(
[[structures]]
name = "gully"
material = "concrete"
shape = "terrain"
raster_file = "dem/ramp.asc"
translate = [-1000.0, -2000.0, -300.0]
)";

TEST(SceneLoader, ReadsATerrainFromItsRasterAndSizesIt) {
  TempFolder folder;
  folder.write("dem/ramp.asc", kRampGrid);
  const auto file = folder.write("scene.toml", std::string(kSceneHead) + kOneSphere + kTerrainHead +
                                                   "strip = [[1005.0, 2020.0], [1045.0, 2020.0]]\n"
                                                   "strip_width = 10.0\nelement_size = 2.5\n");
  const Scene scene = load_scene(file);
  const Shape& gully = scene.structures.at(0).shape;
  EXPECT_EQ(gully.type, Shape::Type::terrain);
  EXPECT_EQ(gully.file, (folder.path() / "dem/ramp.asc").lexically_normal());
  EXPECT_EQ(gully.translate, Vec3(-1000.0, -2000.0, -300.0));
  EXPECT_DOUBLE_EQ(gully.strip_width, 10.0);
  EXPECT_NE(gully.raster.find("AAIGrid, 10 x 8 cells of 5 x 5 m"), std::string::npos) << gully.raster;
  // 40 m by 10 m at 2.5 m: 16 x 4 quads, on a ground sloping at 0.1.
  EXPECT_EQ(gully.mesh_size.triangles, 2u * 16u * 4u);
  EXPECT_EQ(gully.mesh_size.nodes, 17u * 5u);
  EXPECT_NEAR(gully.mesh_size.area, 400.0 * std::sqrt(1.01), 1e-6);
}

TEST(SceneLoader, ATerrainFrontFollowsTheStripOnTheGround) {
  TempFolder folder;
  folder.write("dem/ramp.asc", kRampGrid);
  const std::string fluid = R"(
[sph]
particle_spacing = 0.5
sound_speed = 20.0
[[fluids]]
name = "slurry"
material = "concrete"
shape = "box"
min = [6.0, 16.0, 1.0]
max = [8.0, 18.0, 2.0]
)";
  const std::string scene_text = std::string(kSceneHead) + kTerrainHead +
                                 "strip = [[1005.0, 2020.0], [1025.0, 2020.0], [1035.0, 2030.0]]\n"
                                 "strip_width = 6.0\nelement_size = 2.0\n" +
                                 fluid;
  const auto with_front = [&](const std::string& front) {
    return folder.write("scene.toml", scene_text + "[[fronts]]\nname = \"front\"\nkind = \"terrain\"\n" + front);
  };
  const Scene scene = load_scene(with_front("terrain = \"gully\"\nstations = [ { name = \"bend\", at = 20.0 } ]\n"));
  const Front& front = scene.fronts.at(0);
  EXPECT_EQ(front.kind, Front::Kind::terrain);
  ASSERT_GE(front.path.size(), 2u);
  const double length = 20.0 + std::hypot(10.0, 10.0);
  EXPECT_NEAR(front.path_s.back(), length, 1e-9);
  double worst = 0;
  for (const Vec3& p : front.path) worst = std::max(worst, std::abs(p.z() - 0.1 * (p.x() + 1000.0 - 1000.0)));
  std::cout << "terrain front: path of " << front.path.size() << " points, " << front.path_s.back()
            << " m long (expected " << length << "), ground elevation error " << worst << " m\n";
  EXPECT_LT(worst, 1e-9);
  EXPECT_TRUE(front.path_point(20.0).isApprox(Vec3(25.0, 20.0, 2.5), 1e-9));
  const std::string outside =
      error_of_in(folder, scene_text +
                              "[[fronts]]\nname = \"front\"\nkind = \"terrain\"\n"
                              "terrain = \"gully\"\nstations = [ { name = \"far\", at = 40.0 } ]\n");
  EXPECT_NE(outside.find("outside the centre line of terrain 'gully'"), std::string::npos) << outside;
  const std::string misspelt =
      error_of_in(folder, scene_text + "[[fronts]]\nname = \"front\"\nkind = \"terrain\"\nterrain = \"gulley\"\n");
  EXPECT_NE(misspelt.find("Did you mean 'gully'?"), std::string::npos) << misspelt;
}

TEST(SceneLoader, RefusesTerrainsItCannotBuild) {
  const std::string head = std::string(kSceneHead) + kOneSphere + kTerrainHead;
  const auto error_with_grid = [&](const std::string& text) {
    TempFolder folder;
    folder.write("dem/ramp.asc", kRampGrid);
    folder.write("dem/profile.csv", "0,100\n10,90\n");
    return error_of_in(folder, text);
  };
  const std::string both = error_with_grid(head +
                                           "strip = [[1005.0, 2020.0], [1045.0, 2020.0]]\nstrip_width = 10.0\n"
                                           "clip_polygon = [[1005.0, 2005.0], [1040.0, 2005.0], [1020.0, 2030.0]]\n");
  EXPECT_NE(both.find("gives both strip and clip_polygon"), std::string::npos) << both;
  const std::string no_width = error_with_grid(head + "strip = [[1005.0, 2020.0], [1045.0, 2020.0]]\n");
  EXPECT_NE(no_width.find("structures[0].strip_width"), std::string::npos) << no_width;
  EXPECT_NE(no_width.find("a strip needs its width"), std::string::npos) << no_width;
  const std::string outside =
      error_with_grid(head + "strip = [[1005.0, 2020.0], [1080.0, 2020.0]]\nstrip_width = 10.0\n");
  EXPECT_NE(outside.find("key 'structures[0].strip'"), std::string::npos) << outside;
  EXPECT_NE(outside.find("outside the cell centres"), std::string::npos) << outside;
  EXPECT_NE(outside.find("keep the strip or the polygon inside the raster"), std::string::npos) << outside;
  const std::string not_raster = error_with_grid(std::string(kSceneHead) + kOneSphere +
                                                 "[[structures]]\nname = \"gully\"\nmaterial = \"concrete\"\n"
                                                 "shape = \"terrain\"\nraster_file = \"dem/profile.csv\"\n");
  EXPECT_NE(not_raster.find("key 'structures[0].raster_file'"), std::string::npos) << not_raster;
  EXPECT_NE(not_raster.find("GDAL cannot open it"), std::string::npos) << not_raster;
  const std::string deformable = error_with_grid(head + "rigid = false\n");
  EXPECT_NE(deformable.find("not shape = \"terrain\""), std::string::npos) << deformable;
  const std::string polygon = error_with_grid(head + "clip_polygon = [[1005.0, 2005.0], [1040.0, 2005.0]]\n");
  EXPECT_NE(polygon.find("at least 3 points, not 2"), std::string::npos) << polygon;
}

TEST(SceneLoader, RefusesChannelProfilesItCannotUse) {
  const std::string head = std::string(kSceneHead) + kOneSphere + R"(
[[structures]]
name = "gully"
material = "concrete"
shape = "channel"
origin = [0.0, 0.0, 0.0]
width = 7
)";
  const std::string neither = error_of(head);
  EXPECT_NE(neither.find("a channel needs its longitudinal profile"), std::string::npos) << neither;
  const std::string both = error_of(head + "profile = [[0.0, 1.0], [2.0, 0.5]]\nprofile_file = \"p.csv\"\n");
  EXPECT_NE(both.find("gives both profile and profile_file"), std::string::npos) << both;
  const std::string one_point = error_of(head + "profile = [[0.0, 1.0]]\n");
  EXPECT_NE(one_point.find("at least 2 points, not 1"), std::string::npos) << one_point;
  const std::string missing = error_of(head + "profile_file = \"no_such.csv\"\n");
  EXPECT_NE(missing.find("key 'structures[0].profile_file'"), std::string::npos) << missing;
  EXPECT_NE(missing.find("cannot open the profile"), std::string::npos) << missing;
  const std::string sloped = error_of(head + "profile = [[0.0, 1.0], [2.0, 0.5]]\ndirection = [1.0, 0.0, 1.0]\n");
  EXPECT_NE(sloped.find("a channel's direction must be horizontal"), std::string::npos) << sloped;
  const std::string length = error_of(head + "profile = [[0.0, 1.0], [2.0, 0.5]]\nlength = 3.0\n");
  EXPECT_NE(length.find("structures[0].length"), std::string::npos) << length;
  const std::string nothing = error_of(head + "profile = [[0.0, 1.0], [2.0, 0.5]]\nfloor = false\n");
  EXPECT_NE(nothing.find("a channel without its floor needs walls"), std::string::npos) << nothing;
  const std::string deformable = error_of(head + "profile = [[0.0, 1.0], [2.0, 0.5]]\nrigid = false\n");
  EXPECT_NE(deformable.find("not shape = \"channel\""), std::string::npos) << deformable;
}

TEST(SceneLoader, ReadsEveryShapeAndNormalisesDirections) {
  TempFolder folder;
  // The check reads the mesh (issue 18): one triangle.
  folder.write("meshes/wall.stl",
               "solid w\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
               "endsolid w\n");
  const auto file = folder.write("scene.toml", std::string(kSceneHead) + kOneSphere + R"(
[[structures]]
name = "slanted"
material = "concrete"
shape = "plane"
origin = [0, 0, -1]
normal = [0, 0, 2]
direction = [3, 0, 4]
length = 4
width = 2
thickness = 0.24
[[structures]]
name = "block"
material = "concrete"
shape = "box"
min = [5, 5, 0]
max = [6, 7, 1]
element_size = 0.25
[[structures]]
name = "chute"
material = "concrete"
shape = "chute"
origin = [20, 0, 0]
direction = [0, -2, 0]
length = 12
width = 3
slope_deg = 30
wall_height = 1
end_wall_height = 2
[[structures]]
name = "wall"
material = "concrete"
shape = "mesh"
file = "meshes/../meshes/wall.stl"
scale = 2.0
translate = [1, 2, 3]
)");
  const Scene scene = load_scene(file);
  ASSERT_EQ(scene.structures.size(), 4u);
  const Shape& plane = scene.structures[0].shape;
  EXPECT_EQ(plane.type, Shape::Type::plane);
  EXPECT_NEAR((plane.normal - Vec3(0, 0, 1)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((plane.direction - Vec3(1, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(scene.structures[0].thickness, 0.24);
  const Shape& box = scene.structures[1].shape;
  EXPECT_EQ(box.type, Shape::Type::box);
  EXPECT_EQ(box.box.min, Vec3(5, 5, 0));
  EXPECT_EQ(box.box.max, Vec3(6, 7, 1));
  EXPECT_DOUBLE_EQ(box.element_size, 0.25);
  const Shape& chute = scene.structures[2].shape;
  EXPECT_EQ(chute.type, Shape::Type::chute);
  EXPECT_EQ(chute.direction, Vec3(0, -1, 0));
  EXPECT_DOUBLE_EQ(chute.slope_deg, 30.0);
  EXPECT_DOUBLE_EQ(chute.end_wall_height, 2.0);
  const Shape& mesh = scene.structures[3].shape;
  EXPECT_EQ(mesh.type, Shape::Type::mesh);
  EXPECT_TRUE(mesh.file.is_absolute());
  EXPECT_EQ(mesh.file, std::filesystem::canonical(folder.path() / "meshes/wall.stl"));
  EXPECT_DOUBLE_EQ(mesh.scale, 2.0);
  EXPECT_EQ(mesh.translate, Vec3(1, 2, 3));
  EXPECT_EQ(mesh.mesh_size.triangles, 1u);  // read by the check
  EXPECT_EQ(mesh.mesh_size.nodes, 3u);
  EXPECT_DOUBLE_EQ(mesh.mesh_size.area, 0.5);
}

TEST(SceneLoader, MaterialsAreSortedByNameAndRolesFollowBodies) {
  const Scene scene = load_text(std::string(kSceneHead) + kOneSphere);
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].name, "concrete");
  EXPECT_EQ(scene.materials[1].name, "granite");
  EXPECT_EQ(scene.material_index("granite"), 1u);
  EXPECT_GT(scene.materials[1].origin.line, 0);
  ASSERT_EQ(scene.solvers.size(), 1u);
  EXPECT_EQ(scene.solvers[0].role, Role::dem);
  EXPECT_FALSE(scene.needs(Role::fem));

  const Scene structures_only = load_text(std::string(kSceneHead) + kGround);
  ASSERT_EQ(structures_only.solvers.size(), 1u);
  EXPECT_EQ(structures_only.solvers[0].role, Role::fem);
}

TEST(SceneLoader, InteractionsOverrideTheDefaultPerPair) {
  const Scene scene = load_text(std::string(kSceneHead) + kOneSphere + kGround + R"(
[[structures]]
name = "dam"
material = "concrete"
shape = "box"
min = [3, -1, 0]
max = [4, 1, 2]
[contact.dem_fem]
friction = 0.3
normal_damping_ratio = 0.2
[[interactions]]
pair = ["dam", "boulders"]
friction = 0.4
[[interactions]]
pair = ["boulders", "ground"]
enabled = false
)");
  ASSERT_EQ(scene.interactions.size(), 2u);
  EXPECT_EQ(scene.interactions[0].a, "boulders");  // the particle set comes first
  EXPECT_EQ(scene.interactions[0].b, "dam");
  const SurfaceContact dam = scene.surface_contact("boulders", "dam");
  EXPECT_DOUBLE_EQ(dam.friction, 0.4);
  EXPECT_DOUBLE_EQ(dam.normal_damping_ratio, 0.2);  // inherited from [contact.dem_fem]
  EXPECT_TRUE(dam.enabled);
  EXPECT_FALSE(scene.surface_contact("boulders", "ground").enabled);
  EXPECT_DOUBLE_EQ(scene.surface_contact("boulders", "ground").friction, 0.3);

  // Rolling resistance against structures, per pair; fixed particle sets.
  const Scene rolling = load_text(std::string(kSceneHead) + R"(
[[particles]]
name = "boulders"
material = "granite"
fixed = true
spheres = [ { center = [0.0, 0.0, 3.0], radius = 0.5 } ]
)" + kGround + R"(
[contact.dem_fem]
rolling_friction = 0.05
[[interactions]]
pair = ["boulders", "ground"]
rolling = "viscous"
rolling_viscosity = 0.2
)");
  EXPECT_TRUE(rolling.particle_sets[0].fixed);
  EXPECT_DOUBLE_EQ(rolling.dem_fem_default.rolling_friction, 0.05);
  const SurfaceContact ground = rolling.surface_contact("boulders", "ground");
  EXPECT_EQ(ground.rolling, RollingModel::viscous);
  EXPECT_DOUBLE_EQ(ground.rolling_viscosity, 0.2);
  EXPECT_TRUE(ground.has_rolling());
  const std::string refused =
      error_of(std::string(kSceneHead) + kOneSphere + kGround + "[contact.dem_fem]\nrolling_viscosity = 0.2\n");
  EXPECT_NE(refused.find("rolling_viscosity applies to rolling = \"viscous\""), std::string::npos) << refused;
}

// [contact.sph_dem] and the interactions of a fluid with a particle set: defaults as scene.hpp's, overrides
// per pair, which sets meet the fluid as boundary particles, the derived penalty stiffness.
TEST(SceneLoader, SphDemContactDefaultsAndOverrides) {
  const std::string head = std::string(kSceneHead) + R"(
[materials.water]
density = 1000.0
youngs_modulus = 2.2e9
poisson_ratio = 0.0
[sph]
particle_spacing = 0.1
sound_speed = 20.0
[[fluids]]
name = "slurry"
material = "water"
shape = "box"
min = [-1, -1, 0]
max = [1, 1, 1]
[[particles]]
name = "boulders"
material = "granite"
spheres = [ { center = [0.0, 0.0, 3.0], radius = 0.5 } ]
[[particles]]
name = "gravel"
material = "granite"
spheres = [ { center = [0.0, 0.0, 5.0], radius = 0.04 } ]
)";
  const Scene scene = load_text(head + R"(
[contact.sph_dem]
normal_damping_ratio = 0.3
[[interactions]]
pair = ["gravel", "slurry"]
model = "penalty"
friction = 0.2
)");
  const SphDemContact defaults;
  EXPECT_EQ(defaults.model, SphDemContact::Model::boundary_particles);
  const SphDemContact boulders = scene.sph_dem_contact("slurry", "boulders");
  EXPECT_EQ(boulders.model, defaults.model);
  EXPECT_DOUBLE_EQ(boulders.normal_damping_ratio, 0.3);
  EXPECT_DOUBLE_EQ(boulders.friction, defaults.friction);
  EXPECT_FALSE(boulders.normal_stiffness.has_value());
  ASSERT_EQ(scene.sph_dem_interactions.size(), 1u);
  EXPECT_EQ(scene.sph_dem_interactions[0].fluid, "slurry");  // the fluid comes first
  EXPECT_EQ(scene.sph_dem_interactions[0].set, "gravel");
  const SphDemContact gravel = scene.sph_dem_contact("slurry", "gravel");
  EXPECT_EQ(gravel.model, SphDemContact::Model::penalty);
  EXPECT_DOUBLE_EQ(gravel.friction, 0.2);
  EXPECT_DOUBLE_EQ(gravel.normal_damping_ratio, 0.3);  // inherited from [contact.sph_dem]
  EXPECT_TRUE(scene.boundary_particle_set("boulders"));
  EXPECT_FALSE(scene.boundary_particle_set("gravel"));
  EXPECT_TRUE(scene.sph_receives_boundary_particles());
  // rho0 c^2 dx: the pair's step 0.2 pi sqrt(rho0 dx^3 / K) = 0.2 pi dx / c is above cfl h / c.
  EXPECT_DOUBLE_EQ(scene.sph_dem_derived_stiffness(scene.fluids[0]), 1000.0 * 20.0 * 20.0 * 0.1);
  EXPECT_GT(scene.sph_dem_pair_dt(scene.fluids[0], scene.sph_dem_derived_stiffness(scene.fluids[0])),
            scene.sph_acoustic_dt());
  // The gravel (0.8 dx) as boundary particles is refused; disabled, it is not sampled at all.
  const std::string refused = error_of(head);
  EXPECT_NE(refused.find("particles[1].spheres"), std::string::npos) << refused;
  const Scene disabled = load_text(head + "[[interactions]]\npair = [\"slurry\", \"gravel\"]\nenabled = false\n");
  EXPECT_FALSE(disabled.boundary_particle_set("gravel"));
  EXPECT_FALSE(disabled.sph_dem_contact("slurry", "gravel").enabled);
}

// configs/tests/sph_tank_boundary.toml with `line` inserted after `anchor` (a whole line of it).
std::string tank_scene_with(const std::string& anchor, const std::string& line) {
  std::ifstream in(testing::source_dir() / "configs/tests/sph_tank_boundary.toml");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t at = text.find(anchor);
  EXPECT_NE(at, std::string::npos) << anchor;
  return at == std::string::npos ? text : text.insert(at + anchor.size(), line);
}

// A fluid body's settling phase: read in seconds, 0 without the key.
TEST(SceneLoader, FluidSettleTime) {
  EXPECT_EQ(load_scene(testing::source_dir() / "configs/tests/sph_tank_boundary.toml").fluids.at(0).settle_time, 0.0);
  TempFolder folder;
  // Loaded from another folder: the tank is planes and names no file.
  const auto file = folder.write("scene.toml", tank_scene_with("max = [0.4, 0.4, 0.3]\n", "settle_time = 0.25\n"));
  EXPECT_EQ(load_scene(file).fluids.at(0).settle_time, 0.25);
}

// What becomes of the walls' work: bounded unless the scene names another choice; a name
// outside the choices is refused with the key and the allowed values.
TEST(SceneLoader, SphWallWork) {
  using WallWork = SphSettings::WallWork;
  EXPECT_EQ(load_scene(testing::source_dir() / "configs/tests/sph_tank_boundary.toml").sph.wall_work,
            WallWork::bounded);
  TempFolder folder;
  const std::string anchor = "wall_model = \"boundary_particles\"\n";
  EXPECT_EQ(load_scene(folder.write("stored.toml", tank_scene_with(anchor, "wall_work = \"stored\"\n"))).sph.wall_work,
            WallWork::stored);
  EXPECT_EQ(
      load_scene(folder.write("unstored.toml", tank_scene_with(anchor, "wall_work = \"unstored\"\n"))).sph.wall_work,
      WallWork::unstored);
  try {
    (void)load_scene(folder.write("typo.toml", tank_scene_with(anchor, "wall_work = \"store\"\n")));
    ADD_FAILURE() << "wall_work = \"store\" was accepted";
  } catch (const SceneError& e) {
    const std::string message = e.what();
    std::cout << message << "\n";
    EXPECT_NE(message.find("sph.wall_work"), std::string::npos);
    EXPECT_NE(message.find("\"bounded\""), std::string::npos);
    EXPECT_NE(message.find("typo.toml:"), std::string::npos);
  }
}

// The viscous operator: strain_rate unless the scene names morris. A Herschel-Bulkley material
// reads its consistency index, flow index, yield stress and regularisation rate.
TEST(SceneLoader, SphViscousOperatorAndHerschelBulkley) {
  using Operator = SphSettings::ViscousOperator;
  EXPECT_EQ(load_scene(testing::source_dir() / "configs/tests/sph_tank_boundary.toml").sph.viscous_operator,
            Operator::strain_rate);
  TempFolder folder;
  const std::string anchor = "wall_model = \"boundary_particles\"\n";
  EXPECT_EQ(load_scene(folder.write("morris.toml", tank_scene_with(anchor, "viscous_operator = \"morris\"\n")))
                .sph.viscous_operator,
            Operator::morris);
  const std::string hb =
      "rheology = \"herschel_bulkley\"\nconsistency_index = 4.5\nflow_index = 0.4\nyield_stress = 60.0\n"
      "yield_shear_rate = 0.5\n";
  const Scene scene = load_scene(folder.write("hb.toml", tank_scene_with("eos = \"tait\"\n", hb)));
  const Material& water = scene.materials.at(scene.material_index("water"));
  EXPECT_EQ(water.rheology, Material::Rheology::herschel_bulkley);
  EXPECT_EQ(water.consistency_index, 4.5);
  EXPECT_EQ(water.flow_index, 0.4);
  EXPECT_EQ(water.yield_stress, 60.0);
  EXPECT_EQ(water.yield_shear_rate, 0.5);
  // herschel_bulkley takes its viscous part from K and n: viscosity is refused, naming the fix.
  try {
    (void)load_scene(folder.write("hb_viscosity.toml", tank_scene_with("eos = \"tait\"\n", hb + "viscosity = 2.0\n")));
    ADD_FAILURE() << "herschel_bulkley with viscosity was accepted";
  } catch (const SceneError& e) {
    const std::string message = e.what();
    std::cout << message << "\n";
    EXPECT_NE(message.find("materials.water.viscosity"), std::string::npos);
    EXPECT_NE(message.find("consistency_index"), std::string::npos);
  }
}

// A deformable structure's failure strain bounds the maximum principal strain unless failure_measure names the
// effective plastic strain (MAT_PLASTIC_KINEMATIC's FS). The scenes it refuses are in tests/scenes/bad.
TEST(SceneLoader, FailureMeasure) {
  const auto dam_scene = [](const std::string& material_keys) {
    return "format_version = 1\n[run]\nend_time = 2.0\noutput_interval = 0.1\n[materials.masonry]\n"
           "density = 2300.0\nyoungs_modulus = 8e9\npoisson_ratio = 0.23\n" +
           material_keys +
           "[[structures]]\nname = \"dam\"\nmaterial = \"masonry\"\nrigid = false\nshape = \"box\"\n"
           "min = [0.0, 0.0, 0.0]\nmax = [2.0, 7.0, 8.0]\nelement_size = 1.0\nfixed = [\"z-\"]\n";
  };
  using Measure = Material::FailureMeasure;
  TempFolder folder;
  const auto masonry = [](const Scene& scene) { return scene.materials.at(scene.material_index("masonry")); };
  EXPECT_EQ(masonry(load_scene(folder.write("principal.toml", dam_scene("yield_stress = 8e6\nfailure_strain = "
                                                                        "0.0033\n"))))
                .failure_measure,
            Measure::principal_strain);
  const Material plastic = masonry(load_scene(
      folder.write("plastic.toml", dam_scene("yield_stress = 8e6\nfailure_strain = 0.0033\nfailure_measure = "
                                             "\"plastic_strain\"\n"))));
  EXPECT_EQ(plastic.failure_measure, Measure::plastic_strain);
  EXPECT_EQ(plastic.failure_strain, 0.0033);
}

TEST(SceneLoader, SolverCommandsResolve) {
  TempFolder folder;
  const auto program = folder.write("bin/my_dem", "#!/bin/sh\nexit 0\n");
  std::filesystem::permissions(program, std::filesystem::perms::owner_all);
  const auto file = folder.write("scene.toml", std::string(kSceneHead) + kOneSphere + R"(
[solvers.dem]
command = ["./bin/my_dem", "--fast"]
beta = 0.5
)");
  const Scene scene = load_scene(file);
  const SolverSettings* dem = scene.solver(Role::dem);
  ASSERT_NE(dem, nullptr);
  ASSERT_EQ(dem->command.size(), 2u);
  EXPECT_EQ(std::filesystem::path(dem->command[0]), (folder.path() / "bin/my_dem").lexically_normal());
  EXPECT_EQ(dem->command[1], "--fast");
  EXPECT_DOUBLE_EQ(dem->beta, 0.5);

  // A bare name is looked up on PATH and kept as written.
  const Scene on_path = load_text(std::string(kSceneHead) + kOneSphere + "[solvers.dem]\ncommand = [\"sh\"]\n");
  EXPECT_EQ(on_path.solver(Role::dem)->command, std::vector<std::string>{"sh"});

  // A file that is not executable is refused.
  const auto plain = folder.write("bin/not_executable", "data\n");
  std::filesystem::permissions(plain, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  const std::string message =
      error_of(std::string(kSceneHead) + kOneSphere + "[solvers.dem]\ncommand = [\"" + plain.string() + "\"]\n");
  EXPECT_NE(message.find("not executable"), std::string::npos) << message;
}

TEST(SceneLoader, CollectsEveryErrorSortedByLine) {
  const std::string message = error_of(std::string(kSceneHead) + R"(
[[particles]]
name = "b"
material = "granite"
spheres = [ { center = [0, 0, 0], radius = -1.0 } ]
[contact.dem_dem]
friction = -1.0
rolling_friction = -0.1
)" + "[recording]\nevery = 0\n");
  std::cout << message << "\n";
  EXPECT_EQ(line_count(message), 4u);
  const auto radius = message.find("radius"), friction = message.find("dem_dem.friction"),
             rolling = message.find("rolling_friction"), every = message.find("recording.every");
  ASSERT_NE(radius, std::string::npos);
  ASSERT_NE(every, std::string::npos);
  EXPECT_LT(radius, friction);
  EXPECT_LT(friction, rolling);
  EXPECT_LT(rolling, every);
}

TEST(SceneLoader, NumbersAndIntegers) {
  // Integers are numbers; floats are not integers; nan is not finite.
  const Scene scene = load_text(std::string(kSceneHead) +
                                "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\n"
                                "spheres = [ { center = [0, 0, 5], radius = 1 } ]\n");
  EXPECT_DOUBLE_EQ(scene.particle_sets[0].spheres[0].radius, 1.0);

  const std::string count = error_of(std::string(kSceneHead) +
                                     "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\n"
                                     "fill = { min = [0, 0, 0], max = [4, 4, 4], count = 10.0, diameter = [1, 1] }\n");
  EXPECT_NE(count.find("key 'particles[0].fill.count' = 10.0: must be an integer, not a float"), std::string::npos)
      << count;
  const std::string nan = error_of(std::string(kSceneHead) + kOneSphere + "[contact.dem_dem]\nfriction = nan\n");
  EXPECT_NE(nan.find("key 'contact.dem_dem.friction' = nan: must be a finite number"), std::string::npos) << nan;
  const std::string vector = error_of(std::string(kSceneHead) +
                                      "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\n"
                                      "spheres = [ { center = [0, 0], radius = 1 } ]\n");
  EXPECT_NE(vector.find("must be an array of 3 numbers [x, y, z] (m), not an array of 2 elements"), std::string::npos)
      << vector;
}

TEST(SceneLoader, OverlapsWithinASetAndTouchingIsAllowed) {
  // Touching exactly (distance = r1 + r2) loads.
  const Scene touching = load_text(std::string(kSceneHead) +
                                   "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\nspheres = [\n"
                                   "  { center = [0, 0, 0], radius = 0.5 },\n"
                                   "  { center = [1.0, 0, 0], radius = 0.5 },\n]\n");
  EXPECT_EQ(touching.particle_sets[0].spheres.size(), 2u);
  const std::string message = error_of(std::string(kSceneHead) +
                                       "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\nspheres = [\n"
                                       "  { center = [0, 0, 0], radius = 0.5 },\n"
                                       "  { center = [5, 5, 5], radius = 0.5 },\n"
                                       "  { center = [0, 0.9, 0], radius = 0.5 },\n]\n");
  EXPECT_NE(message.find(":19: key 'particles[0].spheres[2]'"), std::string::npos) << message;
  EXPECT_NE(message.find("overlaps particles[0].spheres[0] (line 17) by 0.1 m"), std::string::npos) << message;
}

TEST(SceneLoader, ManyOverlapsAreSummarised) {
  std::string spheres;
  for (int k = 0; k < 30; ++k) spheres += "  { center = [" + std::to_string(0.01 * k) + ", 0, 0], radius = 0.5 },\n";
  const std::string message = error_of(
      std::string(kSceneHead) + "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\nspheres = [\n" + spheres + "]\n");
  EXPECT_EQ(line_count(message), 21u);
  EXPECT_NE(message.find("415 more pairs of listed spheres overlap"), std::string::npos) << message;
}

TEST(SceneLoader, ChecksAcrossKeys) {
  struct Case {
    std::string text;
    std::string expected;
  };
  const std::string head = kSceneHead;
  const std::vector<Case> cases{
      {head + kOneSphere + "[contact.dem_dem]\nnormal_stiffness = 1e7\nnormal_stiffness_scale = 0.01\n",
       "key 'contact.dem_dem.normal_stiffness_scale' = 0.01: give either normal_stiffness or "
       "normal_stiffness_scale, not both"},
      {head + kGround + "[contact.dem_dem]\nfriction = 0.5\n",
       "key 'contact.dem_dem': there are no particles, so no sphere-sphere contact"},
      {head + kGround + "[contact.dem_fem]\nfriction = 0.5\n",
       "key 'contact.dem_fem': sphere-structure contact needs both particles and structures"},
      {head + kOneSphere + "[[interactions]]\npair = [\"boulders\", \"x\"]\n",
       "key 'interactions': interactions pair a particle set or fluid with a structure, a fluid with a particle "
       "set, or two structures, but the scene lacks the bodies for any"},
      {head + kOneSphere + kGround +
           "[[interactions]]\npair = [\"boulders\", \"ground\"]\n[[interactions]]\npair = "
           "[\"ground\", \"boulders\"]\n",
       "this pair is already given at line"},
      {head + kOneSphere + kGround + "[[interactions]]\npair = [\"boulders\"]\n",
       "a pair names exactly two bodies, not 1"},
      {head + kOneSphere + kGround + "rigid = false\n", "key 'structures[0].rigid' = false: deformable structures"},
      {head + kOneSphere + kGround + "normal = [0, 0, 0]\n",
       "key 'structures[0].normal' = [0, 0, 0]: the normal is zero"},
      {head + kOneSphere + kGround + "direction = [0, 0, 1]\n",
       "key 'structures[0].direction' = [0, 0, 1]: the direction is zero or along the normal"},
      {head + kOneSphere +
           "[[structures]]\nname = \"c\"\nmaterial = \"concrete\"\nshape = \"chute\"\norigin = [0, 0, 0]\n"
           "direction = [1, 0, -0.3]\nlength = 5\nwidth = 2\nslope_deg = 10\n",
       "a chute's direction must be horizontal"},
      {head + kOneSphere +
           "[[structures]]\nname = \"c\"\nmaterial = \"concrete\"\nshape = \"box\"\nmin = [0, 0, 0]\nmax = [1, 0, 1]\n",
       "key 'structures[0].max' = [1, 0, 1]: the box is empty or inverted"},
      {head + kOneSphere + "[[structures]]\nname = \"c\"\nmaterial = \"concrete\"\nshape = \"box\"\nmin = [0, 0, 0]\n",
       "key 'structures[0].max': missing; it is required (m). Fix: add max = [1.0, 1.0, 1.0] to 'structures[0]'"},
      {head + "[[particles]]\nname = \"my set\"\nmaterial = \"granite\"\nspheres = [ { center = [0, 0, 0], radius = 1 "
              "} ]\n",
       "key 'particles[0].name' = \"my set\": a name must be made of letters, digits, '_' and '-'"},
      {head + "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\n",
       "key 'particles[0]': has neither 'spheres' nor 'fill'"},
      {head + "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\nspheres = [ { center = [0, 0, 0], radius = 1 } ]\n"
              "fill = { min = [0, 0, 0], max = [4, 4, 4], count = 1, diameter = [1, 1] }\n",
       "a particle set gives either 'spheres' or 'fill', not both"},
      {head + "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\nspheres = []\n",
       "key 'particles[0].spheres' = []: the list has no spheres"},
      {head + "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\n"
              "fill = { min = [0, 0, 0], max = [4, 4, 1.5], count = 1, diameter = [1, 2] }\n",
       "too small for a sphere of the largest diameter 2.0 m"},
      {head + "[[particles]]\nname = \"b\"\nmaterial = \"granite\"\n"
              "fill = { min = [0, 0, 0], max = [4, 4, 4], count = 1, diameter = [-1, 2] }\n",
       "key 'particles[0].fill.diameter' = [-1, 2]: every element must be > 0 (m)"},
      {"format_version = 1\n" + std::string(kOneSphere), "key 'run': missing; it is required"},
      {head.substr(head.find('\n') + 1) + kOneSphere, "key 'format_version': missing; it is required"},
      {head + kOneSphere + "[materals.rock]\ndensity = 1.0\n",
       "key 'materals' = { rock = { density = 1.0 } }: unknown key. Did you "
       "mean 'materials'? Fix: rename it to 'materials'"},
      {head + kOneSphere + "[solvers.dme]\nbeta = 0.5\n",
       "key 'solvers.dme' = { beta = 0.5 }: unknown key. Did you "
       "mean 'dem'?"},
      {head + kOneSphere + "[solvers.sph]\nbeta = 0.5\n",
       "key 'solvers.sph': no bodies need the sph_solver. Fix: remove [solvers.sph]"},
      {head + kOneSphere + "[solvers.dem]\ncommand = []\n", "the command names no program"},
      {head + kOneSphere + "[solvers.dem]\nbeta = 12.0\n", "key 'solvers.dem.beta' = 12.0: must be in (0, 10]"},
      {head + kOneSphere + "[solvers.dem]\ncommand = [\"no_such_sabo_program_xyz\"]\n",
       "program 'no_such_sabo_program_xyz' is not found on PATH"},
      {head + kOneSphere + "[recording]\nevery = 0\n", "key 'recording.every' = 0: must be >= 1"},
      {head + kOneSphere + "[run.extra]\n", "key 'run.extra' = {}: unknown key"},
      {"format_version = 1\nparticles = { name = \"x\" }\n[run]\nend_time = 1.0\noutput_interval = 0.1\n",
       "key 'particles' = { name = \"x\" }: must be an array of tables, not a table. Fix: start each entry with a "
       "[[particles]] header"},
      {"format_version = 1\n[run]\nend_time = 1.0\noutput_interval = 0.1\nparticles = []\nstructures = []\n",
       "the scene has no bodies"},
  };
  for (const auto& c : cases) {
    const std::string message = error_of(c.text);
    EXPECT_NE(message.find(c.expected), std::string::npos) << "expected: " << c.expected << "\ngot: " << message;
  }
}

// Two hexahedra (x in [0, 2], y and z in [0, 1]) with the physical groups "solid" (the volume), "base"
// (the bottom quadrangles, z = 0) and "empty" (a name without elements).
constexpr const char* kTaggedHexes = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
3
3 1 "solid"
2 2 "base"
2 3 "empty"
$EndPhysicalNames
$Entities
0 0 1 1
1 0 0 0 2 1 0 1 2 0
1 0 0 0 2 1 1 1 1 0
$EndEntities
$Nodes
1 12 1 12
3 1 0 12
1
2
3
4
5
6
7
8
9
10
11
12
0 0 0
1 0 0
2 0 0
0 1 0
1 1 0
2 1 0
0 0 1
1 0 1
2 0 1
0 1 1
1 1 1
2 1 1
$EndNodes
$Elements
2 4 1 4
3 1 5 2
1 1 2 5 4 7 8 11 10
2 2 3 6 5 8 9 12 11
2 1 3 2
3 1 4 5 2
4 2 5 6 3
$EndElements
)";

// A deformable mesh structure of kTaggedHexes written beside the scene, with `keys` added.
std::string tagged_mesh_structure(const std::string& keys) {
  return "\n[[structures]]\nname = \"block\"\nmaterial = \"concrete\"\nrigid = false\nshape = \"mesh\"\n"
         "file = \"hexes.msh\"\n" +
         keys + "\n";
}

std::string error_with_mesh(const std::string& text) {
  TempFolder folder;
  folder.write("hexes.msh", kTaggedHexes);
  try {
    (void)load_scene(folder.write("scene.toml", text));
  } catch (const SceneError& error) {
    return error.what();
  }
  return {};
}

TEST(SceneLoader, ConstraintsByBoxAndByMeshTag) {
  TempFolder folder;
  folder.write("hexes.msh", kTaggedHexes);
  const std::string text =
      std::string(kSceneHead) +
      tagged_mesh_structure(
          "translate = [0.0, 0.0, 1.0]\nconstraints = [ { tag = \"base\", dofs = [\"z\"] }, "
          "{ box = { min = [-1.0, -1.0, 1.0], max = [0.0, 2.0, 3.0] }, dofs = [\"x\", \"y\"] } ]") +
      "[[structures]]\nname = \"wall\"\nmaterial = \"concrete\"\nrigid = false\nshape = \"plane\"\n"
      "thickness = 0.1\norigin = [5.0, 0.0, 1.0]\nnormal = [1.0, 0.0, 0.0]\n"
      "direction = [0.0, 0.0, 1.0]\nlength = 2.0\nwidth = 4.0\nelement_size = 0.5\n"
      "constraints = [ { box = { min = [4.0, -3.0, 0.0], max = [6.0, 3.0, 0.0] }, "
      "dofs = [\"all\"] }, { box = { min = [4.0, -3.0, 0.0], max = [6.0, 3.0, 2.0] }, "
      "dofs = [\"x\", \"ry\", \"rz\"] } ]\n";
  const Scene scene = load_scene(folder.write("scene.toml", text));
  const auto& block = scene.structures[0].constraints;
  ASSERT_EQ(block.size(), 2u);
  EXPECT_EQ(block[0].selection, Constraint::Selection::tag);
  EXPECT_EQ(block[0].tag, "base");
  EXPECT_EQ(block[0].dofs, Constraint::z);
  EXPECT_EQ(block[0].origin.key, "structures[0].constraints[0]");
  EXPECT_EQ(block[1].selection, Constraint::Selection::box);
  EXPECT_EQ(block[1].box.min, Vec3(-1, -1, 1));
  EXPECT_EQ(block[1].box.max, Vec3(0, 2, 3));
  EXPECT_EQ(block[1].dofs, Constraint::x | Constraint::y);
  const auto& wall = scene.structures[1].constraints;
  ASSERT_EQ(wall.size(), 2u);
  EXPECT_TRUE(wall[0].all);
  EXPECT_EQ(wall[1].dofs, Constraint::x | Constraint::ry | Constraint::rz);
  EXPECT_FALSE(wall[1].all);
}

TEST(SceneLoader, ConstraintErrorsNameTheKeyTheValueAndTheFix) {
  struct Case {
    std::string keys;  // of the mesh structure
    std::string expected;
  };
  const std::vector<Case> cases{
      {"constraints = [ { tag = \"bsae\", dofs = [\"z\"] } ]",
       "key 'structures[0].constraints[0].tag' = \"bsae\": hexes.msh has no physical group of that name. Did you "
       "mean 'base'? Fix: use one of the file's groups: solid, base, empty"},
      {"constraints = [ { tag = \"empty\", dofs = [\"z\"] } ]",
       "key 'structures[0].constraints[0].tag' = \"empty\": the physical group \"empty\" of hexes.msh holds no "
       "elements, so no nodes"},
      {"constraints = [ { box = { min = [5.0, 5.0, 5.0], max = [6.0, 6.0, 6.0] }, dofs = [\"z\"] } ]",
       "key 'structures[0].constraints[0].box' = { max = [6.0, 6.0, 6.0], min = [5.0, 5.0, 5.0] }: the box holds "
       "no node of the mesh, whose nodes span [0.0, 0.0, 0.0] to [2.0, 1.0, 1.0] (after scale and translate)"},
      {"constraints = [ { box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, -1.0] }, dofs = [\"z\"] } ]",
       "key 'structures[0].constraints[0].box.max' = [1.0, 1.0, -1.0]: the box is inverted"},
      {"constraints = [ { dofs = [\"z\"] } ]",
       "key 'structures[0].constraints[0]' = { dofs = [\"z\"] }: selects no nodes: it needs a box or a tag"},
      {"constraints = [ { tag = \"base\", box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] }, dofs = [\"z\"] } ]",
       "gives both box and tag: a constraint selects its nodes one way"},
      {"constraints = [ { tag = \"base\", dofs = [\"w\"] } ]",
       "key 'structures[0].constraints[0].dofs' = [\"w\"]: \"w\" is not one of \"x\", \"y\", \"z\", \"rx\", \"ry\", "
       "\"rz\", \"all\""},
      {"constraints = [ { tag = \"base\", dofs = [] } ]",
       "key 'structures[0].constraints[0].dofs' = []: holds no degree of freedom"},
      {"constraints = [ { tag = \"base\", dofs = [\"rx\"] } ]",
       "key 'structures[0].constraints[0].dofs' = [\"rx\"]: rotations belong to shells, and this structure has no "
       "thickness"},
      {"constraints = [ { tag = \"base\" } ]", "key 'structures[0].constraints[0].dofs': missing; it is required"},
  };
  for (const auto& c : cases) {
    const std::string message = error_with_mesh(std::string(kSceneHead) + tagged_mesh_structure(c.keys));
    EXPECT_NE(message.find(c.expected), std::string::npos) << "expected: " << c.expected << "\ngot: " << message;
  }
  // A tag on a generated shape, a box beside a box, constraints on a rigid structure.
  const std::string box =
      "[[structures]]\nname = \"b\"\nmaterial = \"concrete\"\nrigid = false\nshape = \"box\"\n"
      "min = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\n";
  const std::vector<Case> shapes{
      {box + "constraints = [ { tag = \"base\", dofs = [\"z\"] } ]",
       "key 'structures[0].constraints[0].tag' = \"base\": a tag names a physical group of a Gmsh mesh, and this "
       "structure's shape is \"box\". Fix: select the nodes with box = { min = [...], max = [...] }"},
      {box + "constraints = [ { box = { min = [2.0, 0.0, 0.0], max = [3.0, 1.0, 1.0] }, dofs = [\"z\"] } ]",
       "the box misses the structure, which spans [0.0, 0.0, 0.0] to [1.0, 1.0, 1.0]"},
      {std::string(kGround) + "constraints = [ { box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] }, dofs = "
                              "[\"z\"] } ]",
       "belongs to deformable structures, but this one is rigid"},
  };
  for (const auto& c : shapes) {
    const std::string message = error_of(std::string(kSceneHead) + kOneSphere + "\n" + c.keys + "\n");
    EXPECT_NE(message.find(c.expected), std::string::npos) << "expected: " << c.expected << "\ngot: " << message;
  }
}

TEST(SceneLoader, ContactBetweenStructures) {
  const std::string head = kSceneHead;
  const std::string bar =
      "[[structures]]\nname = \"bar\"\nmaterial = \"concrete\"\nrigid = false\nshape = \"box\"\n"
      "min = [0.0, 0.0, 0.1]\nmax = [1.0, 1.0, 1.0]\n";
  const std::string plate =
      "[[structures]]\nname = \"plate\"\nmaterial = \"concrete\"\nrigid = false\nshape = \"box\"\n"
      "min = [0.0, 0.0, 2.0]\nmax = [1.0, 1.0, 2.5]\n";
  // Off by default; a pair's interaction turns that pair on, with [contact.fem_fem]'s keys as its defaults.
  const Scene off = load_text(head + kGround + bar);
  EXPECT_FALSE(off.fem_fem_default.enabled);
  EXPECT_FALSE(off.fem_fem_contact("bar", "ground").enabled);
  const Scene paired = load_text(head + kGround + bar + plate +
                                 "[contact.fem_fem]\nfriction = 0.2\npenalty_scale = 0.5\n"
                                 "[[interactions]]\npair = [\"ground\", \"bar\"]\nnormal_damping_ratio = 0.1\n");
  ASSERT_EQ(paired.fem_fem_interactions.size(), 1u);
  for (const auto& [a, b] : {std::pair{"bar", "ground"}, std::pair{"ground", "bar"}}) {
    const SurfaceContact c = paired.fem_fem_contact(a, b);
    EXPECT_TRUE(c.enabled);
    EXPECT_DOUBLE_EQ(c.friction, 0.2);
    EXPECT_DOUBLE_EQ(c.penalty_scale, 0.5);
    EXPECT_DOUBLE_EQ(c.normal_damping_ratio, 0.1);
  }
  EXPECT_FALSE(paired.fem_fem_contact("bar", "plate").enabled);
  EXPECT_FALSE(paired.fem_fem_contact("bar", "bar").enabled);
  // [contact.fem_fem] enabled: every pair with a deformable structure, unless its interaction says no.
  const Scene all = load_text(head + kGround + bar + plate +
                              "[contact.fem_fem]\nenabled = true\n"
                              "[[interactions]]\npair = [\"plate\", \"ground\"]\nenabled = false\n");
  EXPECT_TRUE(all.fem_fem_contact("bar", "plate").enabled);
  EXPECT_TRUE(all.fem_fem_contact("ground", "bar").enabled);
  EXPECT_FALSE(all.fem_fem_contact("plate", "ground").enabled);
  EXPECT_FALSE(all.fem_fem_contact("plate", "plate").enabled);

  struct Case {
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases{
      {head + kGround + bar + "[[interactions]]\npair = [\"bar\", \"bar\"]\n",
       "key 'interactions[0].pair' = [\"bar\", \"bar\"]: names one structure twice; a structure does not meet its own "
       "faces"},
      {head + kGround + bar + "[[interactions]]\npair = [\"bar\", \"ground\"]\nmodel = \"hertz_mindlin\"\n",
       "key 'interactions[0].model' = \"hertz_mindlin\": two structures meet through the penalty law (node to "
       "segment) only"},
      {head + kGround + bar + "[[interactions]]\npair = [\"bar\", \"ground\"]\nrestitution = 0.5\n",
       "key 'interactions[0].restitution' = 0.5: two structures meet through the penalty law"},
      {head + kGround + bar + "[[interactions]]\npair = [\"bar\", \"ground\"]\nrolling_friction = 0.1\n",
       "key 'interactions[0].rolling_friction' = 0.1: two structures meet"},
      {head + kGround + "[contact.fem_fem]\nenabled = true\n",
       "key 'contact.fem_fem': structure-structure contact needs two structures, one of them deformable"},
  };
  for (const auto& c : cases) {
    const std::string message = error_of(c.text);
    EXPECT_NE(message.find(c.expected), std::string::npos) << "expected: " << c.expected << "\ngot: " << message;
  }
}

TEST(SceneLoader, Endpoints) {
  const auto with_endpoint = [](const char* endpoint) {
    std::string text = kSceneHead;
    text.insert(text.find("[materials"), std::string("endpoint = \"") + endpoint + "\"\n");
    return text + kOneSphere;
  };
  for (const char* good : {"ipc", "tcp", "tcp://127.0.0.1:5555", "tcp://node-7.cluster:65535", "tcp://[::1]:1",
                           "tcp://10.0.0.1:*", "tcp://0.0.0.0:5555"}) {
    EXPECT_EQ(load_text(with_endpoint(good)).run.endpoint, good);
  }
  for (const char* bad :
       {"tcp://127.0.0.1", "tcp://:5555", "tcp://host:0", "tcp://host:70000", "ipc://x", "tcp://a b:1", "tcp:"}) {
    const std::string message = error_of(with_endpoint(bad));
    EXPECT_NE(message.find("must be \"ipc\", \"tcp\" or \"tcp://HOST:PORT\""), std::string::npos)
        << bad << ": " << message;
  }
  // Every interface is said in so many words.
  const std::string star = error_of(with_endpoint("tcp://*:5555"));
  EXPECT_NE(star.find("'*' would listen on every interface"), std::string::npos) << star;
  EXPECT_NE(star.find("tcp://0.0.0.0:5555"), std::string::npos) << star;
}

TEST(SceneLoader, TcpSecurityHeartbeatAndLaunchers) {
  const auto scene_with = [](const std::string& run_keys, const std::string& solver_table = "") {
    std::string text = kSceneHead;
    text.insert(text.find("[materials"), run_keys + "\n" + solver_table + "\n");
    return text + kOneSphere;
  };
  const Scene defaults = load_text(scene_with(""));
  EXPECT_EQ(defaults.run.tcp_security, RunSettings::TcpSecurity::curve);
  EXPECT_EQ(defaults.run.heartbeat_timeout, 5.0);
  EXPECT_TRUE(defaults.run.connect_host.empty());
  EXPECT_TRUE(defaults.solver(Role::dem)->launcher.empty());

  const Scene remote = load_text(scene_with(
      "endpoint = \"tcp://0.0.0.0:5555\"\ntcp_security = \"none\"\nheartbeat_timeout = 2.5\nconnect_host = \"head\"",
      "[solvers.dem]\nlauncher = [\"ssh\", \"node2\"]"));
  EXPECT_EQ(remote.run.tcp_security, RunSettings::TcpSecurity::none);
  EXPECT_EQ(remote.run.heartbeat_timeout, 2.5);
  EXPECT_EQ(remote.run.connect_host, "head");
  EXPECT_EQ(remote.solver(Role::dem)->launcher, (std::vector<std::string>{"ssh", "node2"}));

  const std::string choice = error_of(scene_with("tcp_security = \"tls\""));
  EXPECT_NE(choice.find("run.tcp_security"), std::string::npos) << choice;
  EXPECT_NE(choice.find("\"curve\""), std::string::npos) << choice;
  const std::string heartbeat = error_of(scene_with("heartbeat_timeout = 0.0"));
  EXPECT_NE(heartbeat.find("run.heartbeat_timeout"), std::string::npos) << heartbeat;
  const std::string host = error_of(scene_with("connect_host = \"tcp://head:5555\""));
  EXPECT_NE(host.find("not a host name"), std::string::npos) << host;
  // A launched process may sit on another host: an ipc socket cannot reach it.
  const std::string ipc = error_of(scene_with("", "[solvers.dem]\nlauncher = [\"ssh\", \"node2\"]"));
  EXPECT_NE(ipc.find("solvers.dem.launcher"), std::string::npos) << ipc;
  EXPECT_NE(ipc.find("endpoint = \"tcp://0.0.0.0:5555\""), std::string::npos) << ipc;
  const std::string empty = error_of(scene_with("endpoint = \"tcp\"", "[solvers.dem]\nlauncher = []"));
  EXPECT_NE(empty.find("the launcher names no program"), std::string::npos) << empty;

  // A role started by hand: the supervisor neither starts nor places it.
  const Scene by_hand = load_text(scene_with("registration_timeout = 300.0", "[solvers.dem]\nby_hand = true"));
  EXPECT_TRUE(by_hand.solver(Role::dem)->by_hand);
  EXPECT_EQ(by_hand.run.registration_timeout, 300.0);
  EXPECT_EQ(defaults.run.registration_timeout, 30.0);
  const std::string both =
      error_of(scene_with("endpoint = \"tcp\"", "[solvers.dem]\nby_hand = true\nlauncher = [\"ssh\", \"n2\"]"));
  EXPECT_NE(both.find("solvers.dem.by_hand"), std::string::npos) << both;
  EXPECT_NE(both.find("its 'launcher' would never be used"), std::string::npos) << both;
}

TEST(SceneLoader, UnreadableFileIsAFileError) {
  EXPECT_THROW((void)load_scene("/nonexistent/sabo/scene.toml"), FileError);
  TempFolder folder;
  EXPECT_THROW((void)load_scene(folder.path()), FileError);
}

TEST(SceneSuggest, EditDistanceAndClosestMatch) {
  EXPECT_EQ(edit_distance("end_tme", "end_time"), 1u);
  EXPECT_EQ(edit_distance("raduis", "radius"), 1u);  // transposition
  EXPECT_EQ(edit_distance("Radius", "radius"), 0u);
  EXPECT_EQ(edit_distance("", "abc"), 3u);
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
  const std::vector<std::string> keys{"end_time", "output_interval", "endpoint"};
  EXPECT_EQ(closest_match("end_tim", keys), "end_time");
  EXPECT_EQ(closest_match("endpont", keys), "endpoint");
  EXPECT_FALSE(closest_match("gravity", keys).has_value());
  EXPECT_FALSE(closest_match("abc", {"xyz"}).has_value());
}

}  // namespace
}  // namespace sabo::scene

namespace sabo::scene {
namespace {

// A scene with the DEM contact models, size distributions and a polygon region.
Scene testing_load_dem_scene() {
  return load_text(std::string(testing::kSceneHead) + R"(
[[particles]]
name = "rocks"
material = "granite"
fill = { polygon_xz = [[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 2.0]], y_range = [-1.5, 1.5], count = 20, distribution = "sieve", sieve = [[0.5, 0.0], [0.75, 0.25], [1.0, 1.0]], sieve_basis = "count", settle_time = 0.5 }
[[particles]]
name = "pebbles"
material = "concrete"
fill = { min = [20.0, 0.0, 0.0], max = [25.0, 5.0, 5.0], count = 10, distribution = "normal", diameter = [0.5, 1.1], mean_diameter = 0.8, std_diameter = 0.1 }
[[particles]]
name = "mass_graded"
material = "granite"
fill = { min = [30.0, 0.0, 0.0], max = [40.0, 10.0, 10.0], count = 10, distribution = "sieve", sieve = [[1.0, 0.0], [1.0001, 0.5], [2.0, 1.0]] }
[[structures]]
name = "ground"
material = "concrete"
shape = "plane"
origin = [0.0, 0.0, -1.0]
length = 100.0
width = 100.0
[contact.dem_dem]
model = "hertz_mindlin"
restitution = 0.3
rolling = "viscous"
rolling_viscosity = 0.05
[[contact.dem_dem.pairs]]
materials = ["granite", "concrete"]
model = "linear"
friction = 0.5
rolling = "constant"
[contact.dem_fem]
model = "hertz_mindlin"
restitution = 0.8
[[interactions]]
pair = ["rocks", "ground"]
model = "penalty"
)");
}

TEST(LoaderDem, ContactModelsPerPairAndSurfaceHertz) {
  const Scene scene = testing_load_dem_scene();
  const DemContact& dem = scene.dem_contact;
  EXPECT_EQ(dem.model, DemLaw::hertz_mindlin);
  EXPECT_DOUBLE_EQ(dem.restitution, 0.3);
  EXPECT_EQ(dem.rolling, RollingModel::viscous);
  EXPECT_DOUBLE_EQ(dem.rolling_viscosity, 0.05);
  ASSERT_EQ(dem.pairs.size(), 1u);
  EXPECT_EQ(dem.pairs[0].material_a, "concrete");  // sorted
  EXPECT_EQ(dem.pairs[0].material_b, "granite");
  const DemContactLaw& pair = dem.law("granite", "concrete");
  EXPECT_EQ(pair.model, DemLaw::linear);
  EXPECT_DOUBLE_EQ(pair.friction, 0.5);
  EXPECT_EQ(pair.rolling, RollingModel::constant);
  EXPECT_DOUBLE_EQ(pair.restitution, 0.3);  // inherited
  EXPECT_EQ(&dem.law("granite", "granite"), static_cast<const DemContactLaw*>(&dem));
  EXPECT_EQ(scene.dem_fem_default.model, SurfaceContact::Model::hertz_mindlin);
  EXPECT_DOUBLE_EQ(scene.dem_fem_default.restitution, 0.8);
  EXPECT_EQ(scene.surface_contact("rocks", "ground").model, SurfaceContact::Model::penalty);
}

TEST(LoaderDem, SizeDistributionsPolygonRegionAndSettling) {
  const Scene scene = testing_load_dem_scene();
  ASSERT_EQ(scene.particle_sets.size(), 3u);
  const ParticleSet& graded = scene.particle_sets[0];
  EXPECT_EQ(graded.distribution, SizeDistribution::sieve);
  EXPECT_FALSE(graded.sieve_by_mass);
  EXPECT_DOUBLE_EQ(graded.diameter_min, 0.5);
  EXPECT_DOUBLE_EQ(graded.diameter_max, 1.0);
  // Count basis: the class probabilities are the fraction steps.
  const auto p = graded.sieve_class_probabilities();
  EXPECT_DOUBLE_EQ(p[1], 0.25);
  EXPECT_DOUBLE_EQ(p[2], 0.75);
  // A profile polygon (a trapezoid 10 m long, 2 m high at x = 0 and 4 m at x = 10) over 3 m.
  ASSERT_EQ(graded.polygon_xz.size(), 4u);
  EXPECT_NEAR(graded.region_volume(), 10.0 * 3.0 * 3.0, 1e-12);
  EXPECT_EQ(graded.region.min, Vec3(0, -1.5, 0));
  EXPECT_EQ(graded.region.max, Vec3(10, 1.5, 4));
  EXPECT_TRUE(graded.contains_sphere(Vec3(9, 0, 3), 0.5));
  EXPECT_FALSE(graded.contains_sphere(Vec3(1, 0, 2.2), 0.5));  // pokes through the sloping top
  EXPECT_DOUBLE_EQ(graded.settle_time, 0.5);
  const ParticleSet& normal = scene.particle_sets[1];
  EXPECT_EQ(normal.distribution, SizeDistribution::normal);
  EXPECT_DOUBLE_EQ(normal.mean_diameter, 0.8);
  EXPECT_DOUBLE_EQ(normal.std_diameter, 0.1);
  // A narrow normal distribution: E[d^3] ~ mu^3 + 3 mu sigma^2.
  EXPECT_NEAR(normal.mean_sphere_volume(), std::numbers::pi / 6 * (0.512 + 3 * 0.8 * 0.01), 1e-3);
  // Mass basis: class weights share / E[d^3] in the class.
  const ParticleSet& by_mass = scene.particle_sets[2];
  const auto q = by_mass.sieve_class_probabilities();
  const double w1 = 0.5 / ((std::pow(1.0001, 4) - 1.0) / (4 * 0.0001)),
               w2 = 0.5 / ((16.0 - std::pow(1.0001, 4)) / (4 * 0.9999));
  EXPECT_NEAR(q[1], w1 / (w1 + w2), 1e-12);
}

}  // namespace
}  // namespace sabo::scene
