// Energy and stability of SphModel with boundary-particle walls (issue 3, "Stability"): the
// walls' work is stored (sph.wall_work = "stored") or held back (the default, "bounded") to
// the float rounding, and with the default a dam break striking a wall and a tank at rest
// never rise above their initial energy. The full-length runs (100 000 steps) are
// bench_sph_stability; these are its cases, shortened.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <vector>

#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::container_walls;
using testing::run_until;
using testing::water_scene;
using WallWork = scene::SphSettings::WallWork;

// The power balance of one step, without gravity, viscosity or density diffusion: only
// pressure acts, and the work of the pressure forces, sum_i m_i v_i.a_i, must equal minus the
// rate of the compression energy, sum_i m_i p_i / rho_i^2 drho_i/dt, for the velocities the
// continuity uses (the leapfrog's v_{n+1/2}; the forces are from x_n, rho_n). The fluid fills
// a 10 x 4 x 10 dx box whose walls (the top open) it is pushed against by a smooth velocity
// field u sin(pi x / L) run for 20 steps first, so that the wall particles carry pressure.
struct PowerBalance {
  double work = 0, compression = 0, held = 0, scale = 0;  // W: the three rates and the sum of |terms|
  double least_held = 0;                                  // J: the smallest per-particle account after the step
  [[nodiscard]] double imbalance() const { return std::abs(work + compression + held) / scale; }
  [[nodiscard]] double imbalance_without_held() const { return std::abs(work + compression) / scale; }
};
PowerBalance wall_power_balance(WallWork wall_work) {
  const double dx = 0.01, L = 0.1, u = 1.0;
  scene::Scene s = water_scene(dx, 20.0, 1.5);
  s.run.gravity = Vec3::Zero();
  s.sph.wall_work = wall_work;
  s.sph.kernel = scene::SphSettings::Kernel::wendland_c2;
  s.sph.artificial_viscosity = 0;
  s.sph.density_diffusion = scene::SphSettings::DensityDiffusion::none;
  s.fluids.push_back(box_body("block", Vec3::Zero(), Vec3(L, 4 * dx, L)));
  s.fluids.back().hydrostatic = false;
  SphModel model(s);
  for (std::size_t i = 0; i < model.size(); ++i) {
    model.velocities()[i] = Vec3(u * std::sin(M_PI * model.positions()[i].x() / L), 0, 0);
  }
  model.set_boundary(container_walls(Vec3::Zero(), Vec3(L, 4 * dx, 2 * L), dx, 3));
  int steps = 0;
  run_until(model, 1.0, [&](double) { return ++steps < 20; });
  model.compute_internal_forces(0);  // the next step as a first step: v_{1/2} = v_0 + dt / 2 a
  const std::vector<Vec3> v0(model.velocities().begin(), model.velocities().end());
  const std::vector<double> rho0(model.densities().begin(), model.densities().end());
  const std::vector<double> p0(model.pressures().begin(), model.pressures().end());
  const std::vector<double> held0(model.wall_work_held().begin(), model.wall_work_held().end());
  const double dt = model.stable_dt();
  model.integrate(0, dt);
  PowerBalance out;
  for (std::size_t i = 0; i < held0.size(); ++i) {
    const double held = model.wall_work_held()[i];
    out.held += (held - held0[i]) / dt;
    out.scale += std::abs(held - held0[i]) / dt;
    out.least_held = std::min(out.least_held, held);
  }
  for (std::size_t i = 0; i < model.size(); ++i) {
    const double m = model.masses()[i];
    const Vec3& v = model.velocities()[i];
    const Vec3 a = (v - v0[i]) / (0.5 * dt);
    const double drho = (model.densities()[i] - rho0[i]) / dt;
    const double work = m * v.dot(a), compression = m * p0[i] / (rho0[i] * rho0[i]) * drho;
    out.work += work;
    out.compression += compression;
    out.scale += std::abs(work) + std::abs(compression);
  }
  return out;
}

// The wall particles' extrapolated pressure p_w does work on the fluid. With wall_work =
// "stored", wall_compression() credits the matching compression to the fluid whose pressures
// p_w averages, so that the balance closes to the float rounding of the sums (measured
// 4.8e-9). With "bounded" the work the fluid loses to the walls is held back in per-particle
// accounts that never go below zero, and what the walls give back is paid from them: the
// balance closes with the accounts' rate (measured 8.7e-9), not without it (the held work,
// 1.4e-2). With "unstored" the work of p_w is left over (1.6e-2 of the terms, measured).
TEST(SphStability, WallWorkIsStoredOrHeldBack) {
  const PowerBalance stored = wall_power_balance(WallWork::stored);
  const PowerBalance bounded = wall_power_balance(WallWork::bounded);
  const PowerBalance unstored = wall_power_balance(WallWork::unstored);
  std::cout << "fluid pressed against walls, one step, |sum of the rates| / sum of |rates|:\n"
            << "  stored: work of the forces " << stored.work << " W, compression " << stored.compression
            << " W; measured " << stored.imbalance() << ", expected below 1e-4 (float sums)\n"
            << "  bounded: work " << bounded.work << " W, compression " << bounded.compression << " W, held back "
            << bounded.held << " W; measured " << bounded.imbalance() << ", expected below 1e-4; without the held "
            << "rate " << bounded.imbalance_without_held() << ", expected above 1e-3; smallest account "
            << bounded.least_held << " J, expected >= 0\n"
            << "  unstored: measured " << unstored.imbalance() << ", expected above 1e-3 (the work of p_w)\n";
  EXPECT_LT(stored.imbalance(), 1e-4);
  EXPECT_LT(bounded.imbalance(), 1e-4);
  EXPECT_GT(bounded.imbalance_without_held(), 1e-3);
  EXPECT_GE(bounded.least_held, 0.0);
  EXPECT_GT(unstored.imbalance(), 1e-3);
}

struct StabilityRun {
  int steps = 0;
  double e0 = 0, e_max = 0, held = 0;    // J; held: the walls' work held back at the end
  double max_speed = 0, late_speed = 0;  // m/s: over the run, its second half
  double rho_min = 1e30, rho_max = 0;    // kg/m^3, at the end
  std::size_t lost = 0;
  bool finite = true;
};

// Steps to t_end or max_steps, whichever comes first; the second half is of that limit.
StabilityRun step_and_record(SphModel& model, double t_end, int max_steps) {
  StabilityRun out;
  out.e0 = out.e_max = model.energies().total();
  run_until(model, t_end, [&](double t) {
    const double e = model.energies().total();
    out.finite = out.finite && std::isfinite(e);
    out.e_max = std::max(out.e_max, e);
    ++out.steps;
    const bool late = t > 0.5 * t_end || 2 * out.steps > max_steps;
    for (const Vec3& v : model.velocities()) {
      out.max_speed = std::max(out.max_speed, v.norm());
      if (late) out.late_speed = std::max(out.late_speed, v.norm());
    }
    return out.steps < max_steps;
  });
  for (double rho : model.densities()) {
    out.rho_min = std::min(out.rho_min, rho);
    out.rho_max = std::max(out.rho_max, rho);
  }
  out.lost = model.lost_count();
  out.held = model.energies().wall_held;
  return out;
}

// bench_sph_stability's wall impact: a column a x 4dx x 2a (a = 0.1 m, dx = a/10) released in
// a tank 2a long, so the surge strikes the end wall at about sqrt(2 g 2a) = 2 m/s and splashes
// up it; to 0.5 s (the bench's full run).
StabilityRun wall_impact(scene::SphSettings::Kernel kernel, double ratio) {
  const double a = 0.1, dx = a / 10, W = 4 * dx;
  scene::Scene s = water_scene(dx, 10 * std::sqrt(2 * 9.81 * 2 * a), ratio);
  s.sph.kernel = kernel;
  s.sph.domain = Aabb{Vec3(-0.05, -0.05, -0.05), Vec3(0.25, W + 0.05, 0.65)};
  s.sph.artificial_viscosity = 0.02;
  s.fluids.push_back(box_body("column", Vec3::Zero(), Vec3(a, W, 2 * a)));
  SphModel model(s);
  model.set_boundary(container_walls(Vec3::Zero(), Vec3(2 * a, W, 0.6), dx, 3));
  return step_and_record(model, 0.5, std::numeric_limits<int>::max());
}

void check_wall_impact(const char* name, const StabilityRun& r) {
  std::cout << "wall impact, " << name << ", to 0.5 s: energy initial " << r.e0 << " J, largest - initial "
            << r.e_max - r.e0 << " J (expected <= 0; with wall_work = \"unstored\": +3.4e-4 to +3.8e-4 J at "
            << "the release), walls' work held back " << r.held << " J; largest speed " << r.max_speed << " m/s ("
            << r.late_speed << " in the second half; expected below 3 sqrt(2 g 2a) = 5.9 m/s), density " << r.rho_min
            << ".." << r.rho_max << " kg/m^3 (expected within 10 % of 1000), left the domain " << r.lost << "\n";
  EXPECT_TRUE(r.finite);
  EXPECT_LE(r.e_max, r.e0);
  EXPECT_LT(r.max_speed, 3 * std::sqrt(2 * 9.81 * 0.2));
  EXPECT_GT(r.rho_min, 900.0);
  EXPECT_LT(r.rho_max, 1100.0);
  EXPECT_EQ(r.lost, 0u);
}

TEST(SphStability, DamBreakStrikingAWallNeverGainsEnergy) {
  check_wall_impact("Wendland C2, h = 1.5 dx (default)", wall_impact(scene::SphSettings::Kernel::wendland_c2, 1.5));
  check_wall_impact("cubic spline, h = 1.3 dx", wall_impact(scene::SphSettings::Kernel::cubic_spline, 1.3));
}

// bench_sph_stability's tank (the reduced S4: H = 0.2 m, dx = H/10, 0.2 x 0.1 m) with the
// default kernel, settling for 4 sqrt(H/g), 10 000 steps (the bench runs 100 000). The S4 tests
// use the cubic spline; with wall_work = "unstored" it rises +2.5e-4 J.
TEST(SphStability, TankAtRestWithTheDefaultKernelNeverGainsEnergy) {
  const double H = 0.2, dx = 0.02, g = 9.81, L = 0.2, W = 0.1;
  scene::Scene s = water_scene(dx, 10 * std::sqrt(g * H), 1.5);
  s.sph.kernel = scene::SphSettings::Kernel::wendland_c2;
  s.sph.domain = Aabb{Vec3(-0.1, -0.1, -0.1), Vec3(0.3, 0.2, 0.4)};
  s.sph.artificial_viscosity = 0.1;
  s.fluids.push_back(box_body("water", Vec3::Zero(), Vec3(L, W, H)));
  s.fluids.back().settle_time = 4 * std::sqrt(H / g);
  SphModel model(s);
  model.set_boundary(container_walls(Vec3::Zero(), Vec3(L, W, H + 4 * dx), dx, 3));
  const StabilityRun r = step_and_record(model, std::numeric_limits<double>::infinity(), 10000);
  const double U = std::sqrt(g * H);
  std::cout << "tank at rest, Wendland C2 h = 1.5 dx, settling 4 sqrt(H/g), " << r.steps << " steps: energy initial "
            << r.e0 << " J, largest - initial " << r.e_max - r.e0 << " J (expected <= 0), walls' work held back "
            << r.held << " J; largest speed " << r.max_speed / U << " sqrt(gH) (" << r.late_speed / U
            << " in the second half; expected <= 1e-3), left the domain " << r.lost << "\n";
  EXPECT_LE(r.e_max, r.e0);
  EXPECT_LT(r.max_speed, 1e-3 * U);
  EXPECT_EQ(r.lost, 0u);
}

}  // namespace
}  // namespace sabo::sph
