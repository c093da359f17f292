#pragma once
// A sphere settling in a closed square tank of Newtonian fluid through the
// boundary_particles SPH-DEM pair, fluid and sphere coupled in one process
// (sph_dem_harness.hpp): its terminal speed and drag coefficient against
// Schiller-Naumann, Cd = 24 / Re (1 + 0.15 Re^0.687), corrected for the tank's
// walls by Di Felice's factor. Used by bench/sph_dem_drag.cpp and
// tests/coupler/test_sph_dem_drag.cpp.
//
// The fluid carries no gravity: the sphere is pushed down by its submerged
// weight (m - m_f) g, and a background pressure p0 keeps the fluid's pressure
// positive behind it. For an incompressible fluid that is the settling sphere
// exactly (the hydrostatic pressure only adds the buoyancy m_f g); it spares the
// weakly compressible fluid the sound speed c >= 10 sqrt(g H) a hydrostatic
// column needs (at Re = 1 that is 14 times the flow's own 10 v) and the tank's
// compression along its height, and keeps the wall pressure's clamp at 0 from
// cutting the suction behind the sphere.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "tests/support/sph_dem_harness.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::testing {

// Schiller-Naumann (1933), 0 < Re < 800.
inline double schiller_naumann(double re) {
  return 24.0 / re * (1.0 + 0.15 * std::pow(re, 0.687));
}

// Di Felice (1996), Int. J. Multiphase Flow 22, 527-533: the terminal speed of a sphere on the axis of a
// cylinder over the unbounded one, ((1 - l) / (1 - 0.33 l))^a, a = (3.3 + 0.085 Re) / (1 + 0.1 Re),
// l = D / D_cylinder (fitted for 0.08 < l < 0.7, 0.1 < Re < 1000 against Haberman-Sayre's creeping flow and
// experiments). The square tank of side W is taken as the cylinder of its area, D_cylinder = 2 W / sqrt(pi).
inline double di_felice(double lambda, double re) {
  const double a = (3.3 + 0.085 * re) / (1.0 + 0.1 * re);
  return std::pow((1.0 - lambda) / (1.0 - 0.33 * lambda), a);
}
inline double equivalent_lambda(double diameter, double width) {
  return diameter / (2.0 * width / std::sqrt(std::numbers::pi));
}

struct DragCase {
  double reynolds = 10;          // target Re = rho_f v D / mu of the sphere in unbounded fluid (Schiller-Naumann)
  double diameter_spacings = 8;  // D / dx
  double tank_diameters = 4;     // tank width / D (square section)
  double tank_height = 8;        // tank height / D
  double start_depth = 1.5;      // the sphere's centre below the lid at the start, D
  double floor_clearance = 2.0;  // the run stops once the centre is this close to the floor, D
  double density_ratio = 2.0;    // rho_s / rho_f
  double mach = 0.1;             // c >= v_inf / mach (and not below what makes the acoustic step the viscous one)
  double background = 0.05;      // background pressure / (rho_f c^2)
  double cfl = 0.25;
  double window = 1.0;      // the steadiness window, in D / v_pred (the time to fall a diameter)
  double tolerance = 0.01;  // steady: the mean speed of the last window within this of the window before
  double max_time = 40.0;   // D / v_pred
  double smoothing_ratio = 1.5;
  double artificial_viscosity = 0.0;
};

struct DragResult {
  // Set-up.
  double dx = 0, diameter = 0, width = 0, height = 0, viscosity = 0, sound_speed = 0, background = 0;
  double rho_f = 1000, rho_s = 0, g = 9.81;
  std::size_t fluid_particles = 0, wall_particles = 0, sphere_particles = 0;
  // Prediction: unbounded Schiller-Naumann speed, wall factor, and in the tank.
  double v_inf = 0, wall_factor = 0, v_pred = 0, lambda = 0;
  // Measured over the last window.
  bool steady = false;
  std::string stop;  // why the run ended
  double time = 0, travel = 0, v = 0, drift = 0, force = 0, submerged_weight = 0;
  std::uint64_t steps = 0;
  double re = 0, cd_balance = 0, cd_force = 0;
  // The measured Cd brought to the unbounded sphere: Re / f and Cd f^2, f at that Re; against SN there.
  double re_unbounded = 0, f_measured = 0, cd_unbounded = 0, cd_sn = 0;
  double wall_seconds = 0, sph_seconds = 0, pair_seconds = 0, dem_seconds = 0;
  [[nodiscard]] double cd_error() const { return cd_unbounded / cd_sn - 1.0; }
  [[nodiscard]] double speed_error() const { return v / v_pred - 1.0; }
};

struct DragSample {
  double t, z, v, force;
};

// Runs the case; on_sample(sample) every `report` D / v_pred (0: never).
inline DragResult run_drag(const DragCase& c, double report = 0,
                           const std::function<void(const DragSample&)>& on_sample = {}) {
  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  DragResult r;
  r.dx = 0.01;
  r.rho_s = c.density_ratio * r.rho_f;
  const double d = r.diameter = c.diameter_spacings * r.dx;
  const double area = 0.25 * std::numbers::pi * d * d, volume = std::numbers::pi * d * d * d / 6.0;
  // The unbounded terminal speed at the target Re: (m - m_f) g = rho_f v^2 A Cd(Re) / 2.
  r.v_inf = std::sqrt(2.0 * (r.rho_s - r.rho_f) * volume * r.g / (r.rho_f * area * schiller_naumann(c.reynolds)));
  r.viscosity = r.rho_f * r.v_inf * d / c.reynolds;
  r.width = c.tank_diameters * d;
  r.height = c.tank_height * d;
  r.lambda = equivalent_lambda(d, r.width);
  r.wall_factor = di_felice(r.lambda, c.reynolds);
  r.v_pred = r.wall_factor * r.v_inf;
  const double h = c.smoothing_ratio * r.dx, nu = r.viscosity / r.rho_f;
  // The acoustic step cfl h / c no shorter than the viscous one cfl rho h^2 / (8 mu): c >= 8 nu / h.
  r.sound_speed = std::max(r.v_inf / c.mach, 8.0 * nu / h);
  r.background = c.background * r.rho_f * r.sound_speed * r.sound_speed;

  scene::Scene s = sph::testing::water_scene(r.dx, r.sound_speed, c.smoothing_ratio);
  s.run.gravity = Vec3::Zero();
  s.sph.cfl = c.cfl;
  s.sph.artificial_viscosity = c.artificial_viscosity;
  scene::Material& fluid = s.materials[0];
  fluid.rheology = scene::Material::Rheology::newtonian;
  fluid.viscosity = r.viscosity;
  fluid.eos = scene::Material::Eos::polynomial;  // p = p0 + rho c^2 (rho / rho0 - 1)
  fluid.eos_c0 = r.background;
  fluid.eos_c1 = 1.0;
  scene::Material ball;
  ball.name = "ball";
  ball.density = r.rho_s;
  ball.youngs_modulus = 1e5;  // never in contact: soft, so that the DEM step is not the shortest
  ball.poisson_ratio = 0.3;
  s.materials.insert(s.materials.begin(), ball);  // sorted by name: ball, water
  s.fluids.push_back(sph::testing::box_body("water", Vec3::Zero(), Vec3(r.width, r.width, r.height)));
  scene::ParticleSet set;
  set.name = "ball";
  set.material = "ball";
  const Vec3 start(0.5 * r.width, 0.5 * r.width, r.height - c.start_depth * d);
  set.spheres.push_back({start, 0.5 * d, Vec3::Zero(), Vec3::Zero()});
  s.particle_sets.push_back(set);
  s.sph_dem_default.model = scene::SphDemContact::Model::boundary_particles;
  for (auto role : {scene::Role::sph, scene::Role::dem}) s.solvers.push_back({role, {}, 1.0, {}});

  auto walls = sph::testing::container_walls(Vec3::Zero(), Vec3(r.width, r.width, r.height), r.dx, 3, /*lid=*/true);
  r.wall_particles = walls.size();
  SphDemHarness run(s, std::move(walls));
  r.fluid_particles = run.sph().size();
  const double mass = run.dem().masses()[0];
  r.submerged_weight = (mass - r.rho_f * volume) * r.g;
  run.set_sphere_body_force(0, Vec3(0, 0, -r.submerged_weight));

  // Time integrals of the speed and of the fluid force, to average over any window.
  std::vector<double> times{0.0}, speed_integral{0.0}, force_integral{0.0};
  const auto integral_at = [&](const std::vector<double>& f, double t) {
    const auto it = std::upper_bound(times.begin(), times.end(), t);
    const std::size_t k = std::max<std::size_t>(1, static_cast<std::size_t>(it - times.begin())) - 1;
    if (k + 1 >= times.size()) return f.back();
    const double w = (t - times[k]) / (times[k + 1] - times[k]);
    return f[k] + w * (f[k + 1] - f[k]);
  };
  const double unit = d / r.v_pred, window = c.window * unit;
  double next_report = 0;
  while (true) {
    run.step();
    const double t = run.time(), dt = t - times.back();
    const double v = -run.dem().velocities()[0].z(), force = run.fluid_force_on_sphere(0).z();
    times.push_back(t);
    speed_integral.push_back(speed_integral.back() + v * dt);
    force_integral.push_back(force_integral.back() + force * dt);
    const double z = run.dem().positions()[0].z();
    if (on_sample && report > 0 && t >= next_report) {
      on_sample({t, z, v, force});
      next_report += report * unit;
    }
    r.stop = "";
    if (t >= 2 * window) {
      const double last = (speed_integral.back() - integral_at(speed_integral, t - window)) / window;
      const double before =
          (integral_at(speed_integral, t - window) - integral_at(speed_integral, t - 2 * window)) / window;
      r.v = last;
      r.drift = last / before - 1.0;
      r.force = (force_integral.back() - integral_at(force_integral, t - window)) / window;
      r.steady = std::abs(r.drift) < c.tolerance;
      if (r.steady) r.stop = "steady";
    }
    if (r.stop.empty() && z < c.floor_clearance * d) r.stop = "reached the floor clearance before steady";
    if (r.stop.empty() && t > c.max_time * unit) r.stop = "reached the time limit before steady";
    if (r.stop.empty() && !std::isfinite(z)) r.stop = "diverged";
    if (!r.stop.empty()) {
      r.time = t;
      r.travel = start.z() - z;
      r.steps = run.steps();
      break;
    }
  }
  r.sphere_particles = run.sph().boundary_forces().size() - r.wall_particles;
  r.sph_seconds = run.sph_seconds(), r.pair_seconds = run.pair_seconds(), r.dem_seconds = run.dem_seconds();
  r.re = r.rho_f * r.v * d / r.viscosity;
  r.cd_balance = 2.0 * r.submerged_weight / (r.rho_f * r.v * r.v * area);
  r.cd_force = 2.0 * r.force / (r.rho_f * r.v * r.v * area);
  // In the tank at speed v the sphere has the drag of the unbounded one at v / f, f = f(Re / f).
  double f = r.wall_factor;
  for (int k = 0; k < 50; ++k) f = di_felice(r.lambda, r.re / f);
  r.f_measured = f;
  r.re_unbounded = r.re / f;
  r.cd_unbounded = r.cd_balance * f * f;
  r.cd_sn = schiller_naumann(r.re_unbounded);
  r.wall_seconds = std::chrono::duration<double>(Clock::now() - started).count();
  return r;
}

}  // namespace sabo::testing
