// SphModel: Monaghan's artificial stress against the tensile instability of the
// elastic-plastic slurry, and the S8 deposit profile of a yield-stress slump on a flat bed.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <utility>
#include <vector>

#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::container_walls;
using testing::hydrostatic_pressure_error;
using testing::run_until;
using testing::water_scene;

// Smallest distance between two fluid particles (m).
double closest_pair(const SphModel& model) {
  double closest2 = std::numeric_limits<double>::infinity();
  const auto x = model.positions();
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t j = i + 1; j < x.size(); ++j) closest2 = std::min(closest2, (x[i] - x[j]).squaredNorm());
  }
  return std::sqrt(closest2);
}

// Particles whose stress -p I + S has a tensile (positive) principal value.
int tensile_particles(const SphModel& model) {
  const auto S = model.deviatoric_stress();
  int count = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    const double* q = &S[6 * i];
    const double p = model.pressures()[i];
    Mat3 sigma;
    sigma << q[0] - p, q[3], q[5], q[3], q[1] - p, q[4], q[5], q[4], q[2] - p;
    count += Eigen::SelfAdjointEigenSolver<Mat3>(sigma, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff() > 0 ? 1 : 0;
  }
  return count;
}

// An elastic-plastic column H = 0.2 m deep at rest in a 0.2 x 0.1 m tank with boundary-particle
// walls (the S4 tank: dx = H/10, cubic spline at 1.3 dx, c = 10 sqrt(gH), alpha 0.1),
// shear modulus 1e5 Pa, yield stress sigma_y, artificial stress epsilon.
struct ColumnRun {
  double largest_speed = 0;       // m/s, over the run
  double largest_speed_late = 0;  // m/s, second half
  double closest = 0;             // m, smallest particle distance over the run (sampled)
  double pressure_error = 0;      // L2 against rho g (H - z), of rho g H, at the end
  bool finite = true;
  double end_time = 0;  // s reached
  int tensile = 0;      // particles with a tensile principal stress of -p I + S, sampled
};
ColumnRun elastic_plastic_column(double yield_stress, double epsilon, double t_end) {
  const double H = 0.2, dx = 0.02, g = 9.81, L = 0.2, W = 0.1;
  scene::Scene s = water_scene(dx, 10.0 * std::sqrt(g * H));
  s.sph.kernel = scene::SphSettings::Kernel::cubic_spline;
  s.sph.artificial_viscosity = 0.1;
  s.fluids.push_back(box_body("water", Vec3(0, 0, 0), Vec3(L, W, H)));
  scene::Material& m = s.materials[0];
  m.rheology = scene::Material::Rheology::elastic_plastic;
  m.yield_stress = yield_stress;
  m.fluid_shear_modulus = 1e5;
  m.artificial_stress = epsilon;
  SphModel model(s);
  model.set_boundary(container_walls(Vec3(0, 0, 0), Vec3(L, W, H + 4 * dx), dx, 3));
  ColumnRun out;
  out.closest = closest_pair(model);
  int step = 0;
  run_until(model, t_end, [&](double t) {
    out.end_time = t;
    double fastest = 0;
    for (const Vec3& v : model.velocities()) fastest = std::max(fastest, v.norm());
    if (!std::isfinite(fastest) || fastest > 100 * std::sqrt(g * H)) {
      out.finite = false;
      out.largest_speed = std::numeric_limits<double>::infinity();
      return false;
    }
    out.largest_speed = std::max(out.largest_speed, fastest);
    if (t > 0.5 * t_end) out.largest_speed_late = std::max(out.largest_speed_late, fastest);
    if (++step % 50 == 0) {
      out.closest = std::min(out.closest, closest_pair(model));
      out.tensile += tensile_particles(model);
    }
    return true;
  });
  if (out.finite) {
    out.closest = std::min(out.closest, closest_pair(model));
    out.pressure_error = hydrostatic_pressure_error(model, H, g);
  }
  return out;
}

void print(const char* name, const ColumnRun& run, double dx, double speed_scale) {
  std::cout << "  " << name << ": " << (run.finite ? "finite" : "BLEW UP") << " to t = " << run.end_time
            << " s, largest speed " << run.largest_speed / speed_scale << " sqrt(gH) (second half "
            << run.largest_speed_late / speed_scale << "), closest pair " << run.closest / dx
            << " dx, pressure L2 error " << 100 * run.pressure_error << " % of rho g H, particle samples in tension "
            << run.tensile << "\n";
}

// The column to t = 3 sqrt(H/g) without and with artificial stress (epsilon 0.3), both printed.
std::pair<ColumnRun, ColumnRun> columns_without_and_with(double yield_stress) {
  const double H = 0.2, dx = 0.02, g = 9.81, t_end = 3.0 * std::sqrt(H / g);
  std::pair<ColumnRun, ColumnRun> runs{elastic_plastic_column(yield_stress, 0.0, t_end),
                                       elastic_plastic_column(yield_stress, 0.3, t_end)};
  std::cout << "elastic-plastic column at rest, sigma_y = " << yield_stress
            << " Pa, G = 1e5 Pa, to t = 3 sqrt(H/g) = " << t_end << " s:\n";
  print("epsilon 0  ", runs.first, dx, std::sqrt(g * H));
  print("epsilon 0.3", runs.second, dx, std::sqrt(g * H));
  return runs;
}

// (a) A stiff column (sigma_y = 1e4 Pa: it stays elastic) at rest in a tank. Before the stress
// was updated with the new velocities (docs/physics.md, "Elastic-plastic stress update") it
// blew up: largest speed 1.26 sqrt(gH) by t = 4 sqrt(H/g), closest pair 0.32 dx, pressure
// error 100 %, with or without artificial stress (epsilon 0.3: 2.2 sqrt(gH), 0.33 dx).
TEST(SphArtificialStress, StiffElasticPlasticColumnStaysAtRest) {
  const double H = 0.2, dx = 0.02, g = 9.81, scale = std::sqrt(g * H);
  const auto [without, with] = columns_without_and_with(1e4);
  std::cout << "expected (both): finite, largest speed < 0.1 sqrt(gH), closest pair > 0.9 dx, pressure error < 2 %"
               " (before the stress update fix: 1.26 sqrt(gH), 0.32 dx, 100 %)\n";
  for (const ColumnRun* run : {&without, &with}) {
    EXPECT_TRUE(run->finite);
    EXPECT_LT(run->largest_speed, 0.1 * scale);
    EXPECT_GT(run->closest, 0.9 * dx);
    EXPECT_LT(run->pressure_error, 0.02);
  }
}

// (b), (c) The S8 slurry's yield stress (sigma_y = 580 Pa): the free-surface jitter and the
// pressure error with and without artificial stress. Before the stress update fix: largest
// speed 0.98 sqrt(gH) by t = 4 sqrt(H/g) (0.06-0.09 over the first 2 sqrt(H/g)), pressure
// error 19.5 % (epsilon 0.3: 0.55 sqrt(gH), 9.5 %).
TEST(SphArtificialStress, SlurryColumnJitterAndPressure) {
  const double H = 0.2, g = 9.81, scale = std::sqrt(g * H);
  const auto [without, with] = columns_without_and_with(580);
  std::cout << "expected (both): largest speed < 0.1 sqrt(gH) (before the stress update fix: 0.98), pressure "
               "error < 2 % (before: 19.5 %), epsilon 0.3 no worse than 0 by more than 0.1 % of rho g H\n";
  for (const ColumnRun* run : {&without, &with}) {
    EXPECT_TRUE(run->finite);
    EXPECT_LT(run->largest_speed, 0.1 * scale);
    EXPECT_LT(run->pressure_error, 0.02);
  }
  EXPECT_LT(with.pressure_error, without.pressure_error + 1e-3);
}

// Where the stress does go into tension (a stiff block standing free on a floor, its sides
// unsupported), artificial stress changes the motion; the same bits on 1 and 2 threads.
TEST(SphArtificialStress, ActsInTensionAndRunsAreDeterministic) {
  const double dx = 0.02, g = 9.81, L = 0.24, W = 0.1, H = 0.2;
  const auto run = [&](double epsilon, int threads, int& tensile) {
    scene::Scene s = water_scene(dx, 10.0 * std::sqrt(g * H));
    s.sph.artificial_viscosity = 0.1;
    s.fluids.push_back(box_body("block", Vec3(0, 0, 0), Vec3(L, W, H)));
    scene::Material& m = s.materials[0];
    m.rheology = scene::Material::Rheology::elastic_plastic;
    m.yield_stress = 1e4;
    m.fluid_shear_modulus = 1e5;
    m.artificial_stress = epsilon;
    SphModel model(s);
    model.set_boundary(container_walls(Vec3(-5 * dx, -5 * dx, 0), Vec3(L + 5 * dx, W + 5 * dx, 0), dx, 3));
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    tensile = 0;
    run_until(model, 0.02, [&](double) { tensile += tensile_particles(model); });
    omp_set_num_threads(saved);
    return std::vector<Vec3>(model.positions().begin(), model.positions().end());
  };
  int tensile_off = 0, tensile_one = 0, tensile_two = 0;
  const std::vector<Vec3> off = run(0.0, 1, tensile_off);
  const std::vector<Vec3> one = run(0.3, 1, tensile_one);
  const std::vector<Vec3> two = run(0.3, 2, tensile_two);
  ASSERT_GT(off.size(), 512u);  // above the parallel threshold
  double change = 0;
  bool same_bits = true;
  for (std::size_t i = 0; i < off.size(); ++i) {
    change = std::max(change, (one[i] - off[i]).norm());
    same_bits = same_bits && one[i] == two[i];
  }
  std::cout << "free-standing 1e4 Pa block to t = 0.02 s: particle-steps in tension " << tensile_off << " (epsilon 0), "
            << tensile_one << " (0.3); largest position change from epsilon 0.3 " << change / dx
            << " dx (expected > 0); 1 and 2 threads " << (same_bits ? "bit-identical" : "DIFFER") << "\n";
  EXPECT_GT(tensile_off, 0);
  EXPECT_GT(change, 0.0);
  EXPECT_TRUE(same_bits);
}

// S8 deposit: a yield-stress slump at rest on a flat bed has h(d) = sqrt(2 tau_y d / (rho g))
// at distance d behind its front (the shallow static balance rho g h |dh/dx| = tau_y on the
// bed). A slice W wide (free-slip side walls: a plane flow) of a column a long and b tall,
// behind a no-slip back wall at x = 0, collapses onto a no-slip floor. tau_y = 98.1 Pa gives
// a deposit of the column's area about 0.32 m long and 0.08 m thick at the back (32 and 8 dx at
// dx = 0.01 m); the regularisation rate 1/s keeps the explicit viscous step at
// rho h^2 / (8 tau_y / gamma_0) = 2.8e-4 s (dx = 0.01 m), at the price of a slow creep.
struct DepositCase {
  double dx = 0.01;                     // m
  double tau_y = 98.1;                  // Pa
  double plastic_viscosity = 1;         // Pa s (bingham)
  double yield_shear_rate = 1;          // 1/s (bingham regularisation)
  double length = 0.12, height = 0.14;  // m, the column
  int width_cells = 3;                  // slice width, dx
  double t_end = 3.0;                   // s, at most
  double rest_speed = 0.025;            // m/s: at rest when the fastest particle stays below it ...
  double rest_time = 0.1;               // s: ... this long
};
struct DepositProfile {
  double front = 0;                      // m, front x
  std::vector<double> distance, height;  // m, per column of width dx behind the front
  double time = 0, largest_speed_end = 0;
  int steps = 0;
  bool at_rest = false;
};
DepositProfile run_deposit(const DepositCase& c) {
  const double g = 9.81, dx = c.dx, W = c.width_cells * dx;
  scene::Scene s = water_scene(dx, 10.0 * std::sqrt(g * c.height), 1.5);
  s.sph.artificial_viscosity = 0.1;
  scene::Material& m = s.materials[0];
  m.rheology = scene::Material::Rheology::bingham;
  m.yield_stress = c.tau_y;
  m.viscosity = c.plastic_viscosity;
  m.yield_shear_rate = c.yield_shear_rate;
  s.fluids.push_back(box_body("slurry", Vec3(0, 0, 0), Vec3(c.length, W, c.height)));
  SphModel model(s);
  // The bed reaches 1.5 times the expected deposit length L: a c = (2/3) L h(L).
  const double expected_length =
      std::pow(1.5 * c.length * c.height / std::sqrt(2.0 * c.tau_y / (1000.0 * g)), 2.0 / 3.0);
  const double bed = std::ceil(1.5 * expected_length / dx) * dx;
  physics::BoundaryParticles walls = container_walls(Vec3(0, 0, 0), Vec3(bed, W, c.height + 2 * dx), dx, 3);
  walls.free_slip.assign(walls.size(), 0);
  for (std::size_t b = 0; b < walls.size(); ++b) {
    const double y = walls.position[b].y();
    if (y < 0 || y > W) walls.free_slip[b] = 1;
  }
  model.set_boundary(walls);
  DepositProfile out;
  double quiet_since = -1;
  run_until(model, c.t_end, [&](double t) {
    out.time = t;
    double fastest = 0;
    for (const Vec3& v : model.velocities()) fastest = std::max(fastest, v.norm());
    out.largest_speed_end = fastest;
    ++out.steps;
    if (fastest >= c.rest_speed) {
      quiet_since = -1;
      return true;
    }
    if (quiet_since < 0) quiet_since = t;
    out.at_rest = t - quiet_since >= c.rest_time;
    return !out.at_rest;
  });
  EXPECT_EQ(model.lost_count(), 0u);
  // Surface: the particles highest within dx along x of themselves, at their centre plus dx/2;
  // front: the farthest particle plus dx/2. Ordered from the front back.
  double front = 0;
  const auto x = model.positions();
  for (const Vec3& p : x) front = std::max(front, p.x() + 0.5 * dx);
  out.front = front;
  std::vector<std::pair<double, double>> surface;  // (distance behind the front, height), m
  for (std::size_t i = 0; i < x.size(); ++i) {
    bool highest = true;
    for (std::size_t j = 0; j < x.size() && highest; ++j) {
      highest = !(std::abs(x[j].x() - x[i].x()) < dx && x[j].z() > x[i].z());
    }
    if (highest) surface.emplace_back(front - x[i].x(), x[i].z() + 0.5 * dx);
  }
  std::stable_sort(surface.begin(), surface.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [distance, height] : surface) {
    out.distance.push_back(distance);
    out.height.push_back(height);
  }
  return out;
}

// Compares the profile with sqrt(2 tau_y d / (rho g)) for 5 dx < d < front - 3 dx (clear of
// the back wall); returns the largest relative error.
double compare_deposit(const DepositCase& c, const DepositProfile& p) {
  const double g = 9.81, rho = 1000;
  std::cout << "deposit at t = " << p.time << " s after " << p.steps
            << " steps (at rest: " << (p.at_rest ? "yes" : "no") << ", fastest particle " << p.largest_speed_end
            << " m/s), front at x = " << p.front << " m\n";
  double worst = 0;
  for (std::size_t k = 0; k < p.distance.size(); ++k) {
    const double d = p.distance[k];
    const double expected = std::sqrt(2.0 * c.tau_y * d / (rho * g));
    const bool held = d > 5 * c.dx && d < p.front - 3 * c.dx;
    std::cout << "  d = " << d / c.dx << " dx: h measured " << p.height[k] << " m, expected " << expected
              << " m, ratio " << p.height[k] / expected << (held ? "" : " (not held)") << "\n";
    if (held) worst = std::max(worst, std::abs(p.height[k] / expected - 1.0));
  }
  std::cout << "largest error for 5 dx < d < front - 3 dx: " << 100 * worst << " % (benchmark 10 %)\n";
  return worst;
}

// Reduced: dx = 0.02 m, the deposit 3-4 dx thick where it is held (d = 5-15 dx). The surface
// is known to about dx/2 there (12-15 % of h), and the regularised law still creeps when the
// run stops (the fastest particle below 0.025 m/s, 2 % of sqrt(g b), for 0.1 s), so it is held
// to 15 % (measured 9.9 %; 18.6 % while the diffusion's full-kernel count took in the wall
// particles). The full case, dx = 0.01 m, is the disabled test below (7 minutes on the loaded
// machine).
TEST(SphValidation, S8BinghamDepositProfileReduced) {
  DepositCase c;
  c.dx = 0.02;
  const DepositProfile p = run_deposit(c);
  const double worst = compare_deposit(c, p);
  std::cout << "reduced case held to 15 % (dx/2 is 12-15 % of h at d = 5-7 dx)\n";
  EXPECT_TRUE(p.at_rest);
  EXPECT_LT(worst, 0.15);
}

// The full case: `build/bin/test_sph_deposit --gtest_also_run_disabled_tests
// --gtest_filter='*DISABLED_S8BinghamDepositProfile'`. Not met when last run (session 14): at rest at
// 2.80 s, 20.8 % off at the front (d = 6.7 dx); with wall_work = "unstored" still creeping when the
// 3 s ran out, 12.4 % off (docs/physics.md, "S8 deposit").
TEST(SphValidation, DISABLED_S8BinghamDepositProfile) {
  DepositCase c;
  const DepositProfile p = run_deposit(c);
  const double worst = compare_deposit(c, p);
  EXPECT_TRUE(p.at_rest);
  EXPECT_LT(worst, 0.10);
}

}  // namespace
}  // namespace sabo::sph
