// Drag of the boundary_particles SPH-DEM pair: a sphere released at rest in a
// closed square tank of Newtonian fluid at rest settles to its terminal speed,
// compared with Schiller-Naumann corrected for the tank's walls (Di Felice),
// fluid and sphere coupled in one process (tests/support/sph_dem_drag.hpp says
// how: the fluid carries no gravity, the sphere its submerged weight).
//   bench_sph_dem_drag [--reynolds RE] [--diameter-spacings D_OVER_DX] [--tank-diameters W_OVER_D]
//                      [--tank-height H_OVER_D] [--density-ratio RHO_S_OVER_RHO_F] [--mach M]
//                      [--window DIAMETERS] [--tolerance T] [--viscous-operator strain_rate|morris]
//                      [--density-diffusion fourtakas|molteni|none] [--threads N]
//   bench_sph_dem_drag --spin [--diameter-spacings D_OVER_DX] [--tank-diameters SIDE_OVER_D]
//                      [--spin-reynolds RE] [--spin-time VISCOUS_TIMES]
// --spin measures the curved surface's no-slip alone: the sphere held at the centre of a closed cube and spun,
// its torque against Stokes' rotlet (tests/support/sph_dem_drag.hpp).
// Steady: the mean speed over the last window (the time to fall `--window` diameters at the predicted
// speed) within `--tolerance` of the window before. The last line is JSON.
#include "tests/support/sph_dem_drag.hpp"

#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>

#include "libsabo/scene/names.hpp"

int main(int argc, char** argv) {
  CLI::App app("SPH-DEM drag: a settling sphere's terminal speed against Schiller-Naumann");
  sabo::testing::DragCase c;
  int threads = 0;
  double report = 0.5;
  app.add_option("--reynolds", c.reynolds, "target particle Reynolds number (unbounded, Schiller-Naumann)");
  app.add_option("--diameter-spacings", c.diameter_spacings, "sphere diameter / SPH spacing");
  app.add_option("--tank-diameters", c.tank_diameters, "tank width / sphere diameter (square section)");
  app.add_option("--tank-height", c.tank_height, "tank height / sphere diameter");
  app.add_option("--start-depth", c.start_depth, "the sphere's centre below the lid at the start, diameters");
  app.add_option("--floor-clearance", c.floor_clearance, "stop once the centre is this close to the floor, diameters");
  app.add_option("--density-ratio", c.density_ratio, "sphere density / fluid density")->check(CLI::Range(1.01, 100.0));
  app.add_option("--mach", c.mach, "v_inf / c at most");
  app.add_option("--background", c.background, "background pressure / (rho c^2)");
  app.add_option("--cfl", c.cfl, "SPH step factor");
  app.add_option("--window", c.window, "steadiness window, diameters fallen at the predicted speed");
  app.add_option("--tolerance", c.tolerance, "steady: change of the window mean speed below this");
  app.add_option("--max-time", c.max_time, "time limit, in diameters fallen at the predicted speed");
  app.add_option("--artificial-viscosity", c.artificial_viscosity, "Monaghan alpha (0: none)");
  app.add_option("--report", report, "speed history every this many diameters-fallen times (0: none)");
  app.add_option("--threads", threads, "OpenMP threads (0: OMP_NUM_THREADS)");
  std::string viscous_operator = "strain_rate", density_diffusion = "fourtakas";
  app.add_option("--viscous-operator", viscous_operator, "the SPH viscous term (sph.viscous_operator)")
      ->check(CLI::IsMember(sabo::scene::choice_names<sabo::scene::SphSettings::ViscousOperator>()));
  app.add_option("--density-diffusion", density_diffusion, "delta-SPH's density diffusion (sph.density_diffusion)")
      ->check(CLI::IsMember(sabo::scene::choice_names<sabo::scene::SphSettings::DensityDiffusion>()));
  bool spin = false;
  sabo::testing::SpinCase spin_case;
  app.add_flag("--spin", spin, "the spinning-sphere torque instead of the settling sphere");
  app.add_option("--spin-reynolds", spin_case.reynolds, "Omega R^2 / nu of the spinning sphere");
  app.add_option("--spin-time", spin_case.end_time, "run length in viscous times R^2 / nu");
  CLI11_PARSE(app, argc, argv);
  if (threads > 0) omp_set_num_threads(threads);
  c.viscous_operator = sabo::scene::value_named<sabo::scene::SphSettings::ViscousOperator>(viscous_operator);
  c.density_diffusion = sabo::scene::value_named<sabo::scene::SphSettings::DensityDiffusion>(density_diffusion);

  if (spin) {
    spin_case.diameter_spacings = c.diameter_spacings;
    spin_case.box_diameters = c.tank_diameters;
    spin_case.cfl = c.cfl;
    spin_case.viscous_operator = c.viscous_operator;
    const auto r = sabo::testing::run_spin(spin_case);
    fmt::print(
        "spinning sphere: D = {} dx, closed cube {} D ({} fluid particles), Omega R^2 / nu = {}, {} steps to t = "
        "{:.4f} s: torque {:.5g} N m against the rotlet's {:.5g} N m ({:+.1f} %), wall time {:.1f} s, {} threads\n",
        spin_case.diameter_spacings, spin_case.box_diameters, r.fluid_particles, spin_case.reynolds, r.steps, r.time,
        r.torque, r.expected, 100 * r.error(), r.wall_seconds, omp_get_max_threads());
    fmt::print("{}\n", nlohmann::json{{"case", "spin"},
                                      {"diameter_dx", spin_case.diameter_spacings},
                                      {"box_diameters", spin_case.box_diameters},
                                      {"reynolds", spin_case.reynolds},
                                      {"torque", r.torque},
                                      {"torque_rotlet", r.expected},
                                      {"torque_error", r.error()},
                                      {"steps", r.steps},
                                      {"wall_seconds", r.wall_seconds}}
                           .dump());
    return 0;
  }

  bool header = false;
  const auto r = sabo::testing::run_drag(c, report, [&](const sabo::testing::DragSample& s) {
    if (!header) fmt::print("{:>10} {:>10} {:>10} {:>12}\n", "t, s", "z, m", "v, m/s", "F_fluid, N"), header = true;
    fmt::print("{:10.4f} {:10.4f} {:10.5f} {:12.5f}\n", s.t, s.z, s.v, s.force);
    std::fflush(stdout);
  });
  fmt::print(
      "setup: D = {} m = {} dx (dx = {} m), tank {} x {} x {} m ({} x {} D, closed), rho_s / rho_f = {}, mu = {:.4g} "
      "Pa s, c = {:.3g} m/s, p0 = {:.3g} Pa, {} fluid + {} wall particles, {} threads\n",
      r.diameter, c.diameter_spacings, r.dx, r.width, r.width, r.height, c.tank_diameters, c.tank_height,
      c.density_ratio, r.viscosity, r.sound_speed, r.background, r.fluid_particles, r.wall_particles,
      omp_get_max_threads());
  fmt::print(
      "prediction: unbounded v = {:.5f} m/s at Re = {}; Di Felice wall factor {:.4f} (lambda = D / D_eq = {:.4f}, "
      "D_eq = 2 W / sqrt(pi)) -> v = {:.5f} m/s in the tank; sound speed {:.1f} x v_inf\n",
      r.v_inf, c.reynolds, r.wall_factor, r.lambda, r.v_pred, r.sound_speed / r.v_inf);
  fmt::print("run: {} ({} steps to t = {:.4f} s, fell {:.3f} m = {:.2f} D, last-window drift {:+.2f} %)\n", r.stop,
             r.steps, r.time, r.travel, r.travel / r.diameter, 100 * r.drift);
  fmt::print(
      "terminal: v = {:.5f} m/s ({:+.1f} % against the prediction in the tank), Re = {:.3f}; Cd from the force "
      "balance {:.4f}, from the mean fluid force {:.4f}\n",
      r.v, 100 * r.speed_error(), r.re, r.cd_balance, r.cd_force);
  fmt::print(
      "unbounded: wall factor {:.4f} at Re = {:.3f}: Cd f^2 = {:.4f} against Schiller-Naumann {:.4f} ({:+.1f} %)\n",
      r.f_measured, r.re_unbounded, r.cd_unbounded, r.cd_sn, 100 * r.cd_error());
  fmt::print("wall time {:.1f} s (SPH {:.1f} s, pair {:.1f} s, DEM {:.2f} s; {:.3g} fluid particle-steps/s)\n",
             r.wall_seconds, r.sph_seconds, r.pair_seconds, r.dem_seconds,
             static_cast<double>(r.fluid_particles * r.steps) / r.wall_seconds);
  fmt::print("{}\n", nlohmann::json{{"reynolds_target", c.reynolds},
                                    {"diameter_dx", c.diameter_spacings},
                                    {"tank_diameters", c.tank_diameters},
                                    {"tank_height_diameters", c.tank_height},
                                    {"density_ratio", c.density_ratio},
                                    {"fluid_particles", r.fluid_particles},
                                    {"wall_particles", r.wall_particles},
                                    {"threads", omp_get_max_threads()},
                                    {"stop", r.stop},
                                    {"steady", r.steady},
                                    {"steps", r.steps},
                                    {"time", r.time},
                                    {"v_predicted", r.v_pred},
                                    {"v", r.v},
                                    {"re", r.re},
                                    {"re_unbounded", r.re_unbounded},
                                    {"cd_balance", r.cd_balance},
                                    {"cd_force", r.cd_force},
                                    {"cd_unbounded", r.cd_unbounded},
                                    {"cd_schiller_naumann", r.cd_sn},
                                    {"cd_error", r.cd_error()},
                                    {"wall_seconds", r.wall_seconds}}
                         .dump());
  return r.steady ? 0 : 1;
}
