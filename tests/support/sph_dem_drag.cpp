#include "tests/support/sph_dem_drag.hpp"

namespace sabo::testing {

double schiller_naumann(double re) {
  return 24.0 / re * (1.0 + 0.15 * std::pow(re, 0.687));
}

double di_felice(double lambda, double re) {
  const double a = (3.3 + 0.085 * re) / (1.0 + 0.1 * re);
  return std::pow((1.0 - lambda) / (1.0 - 0.33 * lambda), a);
}

double equivalent_lambda(double diameter, double width) {
  return diameter / (2.0 * width / std::sqrt(std::numbers::pi));
}

namespace {

// A Newtonian fluid of `viscosity` (Pa s) without gravity filling the closed box [0, tank] (m), its pressure
// p = p0 + rho c^2 (rho / rho0 - 1) with the background p0 = `background` (Pa), and one sphere of
// `ball_density` (held in place when `fixed`) coupled through the boundary_particles pair.
scene::Scene sphere_in_fluid(double dx, double sound_speed, double smoothing_ratio, double viscosity, double background,
                             const Vec3& tank, const scene::Sphere& sphere, double ball_density, bool fixed) {
  scene::Scene s = sph::testing::water_scene(dx, sound_speed, smoothing_ratio);
  s.run.gravity = Vec3::Zero();
  scene::Material& fluid = s.materials[0];
  fluid.rheology = scene::Material::Rheology::newtonian;
  fluid.viscosity = viscosity;
  fluid.eos = scene::Material::Eos::polynomial;
  fluid.eos_c0 = background;
  fluid.eos_c1 = 1.0;
  scene::Material ball;
  ball.name = "ball";
  ball.density = ball_density;
  ball.youngs_modulus = 1e5;  // never in contact: soft, so that the DEM step is not the shortest
  ball.poisson_ratio = 0.3;
  s.materials.insert(s.materials.begin(), ball);  // sorted by name: ball, water
  s.fluids.push_back(sph::testing::box_body("water", Vec3::Zero(), tank));
  scene::ParticleSet set;
  set.name = "ball";
  set.material = "ball";
  set.fixed = fixed;
  set.spheres.push_back(sphere);
  s.particle_sets.push_back(set);
  s.sph_dem_default.model = scene::SphDemContact::Model::boundary_particles;
  for (auto role : {sabo::Role::sph, sabo::Role::dem}) s.solvers.emplace_back().role = role;
  return s;
}

}  // namespace

DragResult run_drag(const DragCase& c, double report, const std::function<void(const DragSample&)>& on_sample) {
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

  const Vec3 start(0.5 * r.width, 0.5 * r.width, r.height - c.start_depth * d);
  scene::Scene s = sphere_in_fluid(r.dx, r.sound_speed, c.smoothing_ratio, r.viscosity, r.background,
                                   Vec3(r.width, r.width, r.height), {start, 0.5 * d, Vec3::Zero(), Vec3::Zero()},
                                   r.rho_s, /*fixed=*/false);
  s.sph.cfl = c.cfl;
  s.sph.artificial_viscosity = c.artificial_viscosity;
  s.sph.viscous_operator = c.viscous_operator;
  s.sph.density_diffusion = c.density_diffusion;

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

SpinResult run_spin(const SpinCase& c) {
  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  const double dx = 0.01, d = c.diameter_spacings * dx, radius = 0.5 * d, width = c.box_diameters * d;
  const double rho = 1000, nu = 0.01, mu = rho * nu, omega = c.reynolds * nu / (radius * radius);
  const double smoothing_ratio = 1.5, h = smoothing_ratio * dx;
  // As in run_drag: Mach 0.1 at the surface's speed, and the acoustic step no shorter than the viscous one.
  const double sound_speed = std::max(10 * omega * radius, 8 * nu / h);
  scene::Scene s =
      sphere_in_fluid(dx, sound_speed, smoothing_ratio, mu, 0.05 * rho * sound_speed * sound_speed,
                      Vec3::Constant(width), {Vec3::Constant(0.5 * width), radius, Vec3::Zero(), Vec3::Zero()}, 2000,
                      /*fixed=*/true);  // held in place; its spin is set before every step
  s.sph.cfl = c.cfl;
  s.sph.artificial_viscosity = 0;
  s.sph.viscous_operator = c.viscous_operator;
  SphDemHarness run(s, sph::testing::container_walls(Vec3::Zero(), Vec3::Constant(width), dx, 3, /*lid=*/true));
  const double end = c.end_time * radius * radius / nu;
  double torque_integral = 0, span = 0;
  while (run.time() < end) {
    run.dem().angular_velocities()[0] = Vec3(0, 0, omega);
    const double before = run.time();
    run.step();
    if (run.time() > 0.75 * end) {
      torque_integral -= run.fluid_torque_on_sphere(0).z() * (run.time() - before);
      span += run.time() - before;
    }
  }
  const double outer = std::cbrt(3.0 / (4.0 * std::numbers::pi)) * width;
  SpinResult r;
  r.torque = torque_integral / span;
  r.expected = 8 * std::numbers::pi * mu * std::pow(radius, 3) * omega / (1 - std::pow(radius / outer, 3));
  r.time = run.time();
  r.steps = run.steps();
  r.fluid_particles = run.sph().size();
  r.wall_seconds = std::chrono::duration<double>(Clock::now() - started).count();
  return r;
}

}  // namespace sabo::testing
