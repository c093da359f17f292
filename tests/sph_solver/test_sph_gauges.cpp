// Gauges (docs/scene.md [[gauges]]): SphModel::sample() on analytic fields, the free-surface depth along a
// line, and gauges.csv across a checkpoint.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "libsabo/io/hdf5.hpp"
#include "sph_solver/gauges.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::water_scene;

constexpr double kDx = 0.05, kDepth = 0.3, kRho = 1000, kG = 9.81;
// So stiff that the fill's pressure is linear in z to 0.03 Pa over the block (the Tait fill's curvature
// d2p/dz2 = g^2 rho / c^2 = 2.4 Pa/m^2).
constexpr double kSoundSpeed = 200.0;
const Vec3 kVelocity(0.3, -0.2, 0.1);
// A linear velocity field v = kVelocity + kGradient x (1/s).
const Mat3 kGradient = (Mat3() << 0.5, -1.0, 2.0, 0.25, 3.0, -0.75, -2.0, 1.5, 0.1).finished();

// A hydrostatic block 0.4 x 0.4 x height m, its forces computed once (the neighbour grid).
SphModel block_model(double height = kDepth, bool linear_velocity = false) {
  scene::Scene scene = water_scene(kDx, kSoundSpeed);
  scene::FluidBody body = box_body("water", Vec3::Zero(), Vec3(0.4, 0.4, height));
  body.velocity = kVelocity;
  scene.fluids.push_back(body);
  SphModel model(scene);
  if (linear_velocity) {
    for (std::size_t i = 0; i < model.size(); ++i) {
      model.velocities()[i] = kVelocity + kGradient * model.positions()[i];
    }
  }
  model.compute_internal_forces(0.0);
  return model;
}

// The chord p = a + b z through the lowest and the highest particle's pressure.
std::pair<double, double> pressure_chord(const SphModel& model) {
  const auto x = model.positions();
  const auto p = model.pressures();
  std::size_t low = 0, high = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (x[i].z() < x[low].z()) low = i;
    if (x[i].z() > x[high].z()) high = i;
  }
  const double b = (p[high] - p[low]) / (x[high].z() - x[low].z());
  return {p[low] - b * x[low].z(), b};
}

// Lattice points, points between them, next to a side, a corner, and the free surface's top row.
const Vec3 kInside[] = {Vec3(0.2, 0.2, 0.15),   Vec3(0.137, 0.211, 0.093), Vec3(0.01, 0.2, 0.15),
                        Vec3(0.02, 0.03, 0.02), Vec3(0.2, 0.2, 0.28),      Vec3(0.31, 0.07, 0.2)};

TEST(SphGauges, LinearVelocityIsExactInsideTheFluid) {
  const SphModel model = block_model(kDepth, true);
  for (const Vec3& x : kInside) {
    const FluidSample s = model.sample(x);
    const Vec3 expected = kVelocity + kGradient * x;
    std::cout << "at (" << x.transpose() << "): kernel sum " << s.kernel_sum << ", velocity measured "
              << s.velocity.transpose() << " expected " << expected.transpose() << " (to 1e-12 m/s)\n";
    EXPECT_TRUE(s.linear_fit);
    EXPECT_NEAR((s.velocity - expected).norm(), 0.0, 1e-12);
  }
}

TEST(SphGauges, HydrostaticPressureIsReadToItsCurvature) {
  // The same fit as the velocity's (one solve, four columns); the fill's pressure departs from its chord
  // by its curvature only: 0.03 Pa over the depth, 0.04 Pa over a support (2h)^2 g^2 rho / c^2.
  const SphModel model = block_model();
  const auto [a, b] = pressure_chord(model);
  std::cout << "fill pressure chord p = " << a << " + " << b << " z Pa (rho g = " << kRho * kG << ")\n";
  for (const Vec3& x : kInside) {
    const FluidSample s = model.sample(x);
    const double expected = a + b * x.z();
    std::cout << "at (" << x.transpose() << "): pressure measured " << s.pressure << " expected " << expected
              << " (+- 0.1 Pa)\n";
    EXPECT_NEAR(s.pressure, expected, 0.1);
    EXPECT_NEAR((s.velocity - kVelocity).norm(), 0.0, 1e-12);
  }
}

TEST(SphGauges, AGaugeInTheAirReadsZero) {
  const SphModel model = block_model();
  const double support = model.kernel().support();
  for (const Vec3& x : {Vec3(0.2, 0.2, kDepth + support + 0.01), Vec3(-1.0, 0.2, 0.1), Vec3(50.0, 50.0, 50.0)}) {
    const FluidSample s = model.sample(x);
    std::cout << "at (" << x.transpose() << "): kernel sum " << s.kernel_sum << ", pressure " << s.pressure
              << " (expected 0 and 0)\n";
    EXPECT_EQ(s.kernel_sum, 0.0);
    EXPECT_EQ(s.pressure, 0.0);
    EXPECT_EQ(s.velocity, Vec3::Zero());
  }
  // Within the support of a few top particles but below the dry threshold: still 0.
  const Vec3 above(0.2, 0.2, kDepth + 0.4 * support);
  const FluidSample s = model.sample(above);
  std::cout << "just above the surface: kernel sum " << s.kernel_sum << " (dry below " << kDryKernelSum
            << "), pressure " << s.pressure << "\n";
  EXPECT_GT(s.kernel_sum, 0.0);
  EXPECT_LT(s.kernel_sum, kDryKernelSum);
  EXPECT_EQ(s.pressure, 0.0);
}

TEST(SphGauges, OneLayerOfParticlesFallsBackToTheShepardMean) {
  // One lattice layer: the neighbours span no volume, so the linear fit is singular; the Shepard mean
  // of the constant pressure and velocity is exact.
  const SphModel model = block_model(kDx);
  const double p = model.pressures()[0];
  const FluidSample s = model.sample(Vec3(0.2, 0.2, 0.03));
  std::cout << "one layer: kernel sum " << s.kernel_sum << ", linear fit " << s.linear_fit << ", pressure "
            << s.pressure << " expected " << p << "\n";
  EXPECT_FALSE(s.linear_fit);
  EXPECT_NEAR(s.pressure, p, 1e-12 * std::abs(p));
  EXPECT_NEAR((s.velocity - kVelocity).norm(), 0.0, 1e-12);
}

TEST(SphGauges, DepthAlongAVerticalLineIsTheFreeSurface) {
  const SphModel model = block_model();
  const double spacing = 0.25 * kDx;
  const double depth = surface_distance(model, Vec3(0.2, 0.2, 0.0), Vec3(0.2, 0.2, 0.5), spacing);
  std::cout << "depth measured " << depth << " m, expected " << kDepth << " m (+- dx/4 = " << spacing << ")\n";
  EXPECT_NEAR(depth, kDepth, spacing);
  EXPECT_EQ(surface_distance(model, Vec3(0.2, 0.2, 0.6), Vec3(0.2, 0.2, 0.9), spacing), 0.0);           // dry
  EXPECT_DOUBLE_EQ(surface_distance(model, Vec3(0.2, 0.2, 0.05), Vec3(0.2, 0.2, 0.2), spacing), 0.15);  // all wet
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(SphGauges, GaugesCsvContinuesFromACheckpoint) {
  const auto folder = std::filesystem::temp_directory_path() / "sabo_test_gauges";
  std::filesystem::remove_all(folder);
  std::filesystem::create_directories(folder);
  scene::Scene scene = water_scene(kDx, kSoundSpeed);
  scene.fluids.push_back(box_body("water", Vec3::Zero(), Vec3(0.4, 0.4, kDepth)));
  scene.run.output_interval = 0.1;
  scene::Gauge point;
  point.name = "point";
  point.start = point.end = Vec3(0.2, 0.2, 0.1);
  scene::Gauge line;
  line.name = "line";
  line.start = Vec3(0.2, 0.2, 0.0);
  line.end = Vec3(0.2, 0.2, 0.5);
  line.points = 3;
  line.interval = 0.05;
  scene.gauges = {point, line};
  SphModel model(scene);
  model.compute_internal_forces(0.0);

  GaugeRecorder recorder(folder, scene);
  const auto checkpoint = folder / "checkpoint.h5";
  for (const double t : {0.0, 0.02, 0.05}) recorder.sample(model, t);
  {
    io::hdf5::File file = io::hdf5::File::create(checkpoint);
    recorder.save(file);
  }
  const std::string at_checkpoint = read_text(folder / "gauges.csv");
  for (const double t : {0.07, 0.1, 0.12}) recorder.sample(model, t);
  const std::string uninterrupted = read_text(folder / "gauges.csv");

  GaugeRecorder resumed(folder, scene);
  resumed.load(io::hdf5::File::open(checkpoint));
  EXPECT_EQ(read_text(folder / "gauges.csv"), at_checkpoint);
  for (const double t : {0.07, 0.1, 0.12}) resumed.sample(model, t);
  EXPECT_EQ(read_text(folder / "gauges.csv"), uninterrupted);
  // Samples: t = 0 (both), 0.05 (line), 0.1 (both): 1 + 3 + 3 + 1 + 3 rows after the header.
  const std::string text = read_text(folder / "gauges.csv");
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1 + 11);
  EXPECT_EQ(text.substr(0, text.find('\n')),
            "time,gauge,point,x,y,z,kernel_sum,pressure,velocity_x,velocity_y,velocity_z,depth");
  std::filesystem::remove_all(folder);
}

}  // namespace
}  // namespace sabo::sph
