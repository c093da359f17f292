// The slump of a Bingham column on a rigid floor (tests/support/sph_slump.hpp; docs/physics.md,
// "Viscosity"): the column's height on its axis every 0.05 s, then its final height against the
// slump analysis x (1 - ln x). Threads: OMP_NUM_THREADS.
//   bench_sph_slump [--yield-number X] [--spacing DX] [--height H] [--side A] [--plastic-viscosity MU]
//                   [--yield-shear-rate G0] [--end-time T] [--rest-speed V] [--viscous-operator strain_rate|morris]
#include "tests/support/sph_slump.hpp"

#include <fmt/format.h>

#include <CLI/CLI.hpp>

#include "libsabo/scene/names.hpp"

int main(int argc, char** argv) {
  using namespace sabo;
  CLI::App app("Bingham column slump on a rigid floor");
  sph::testing::SlumpCase c;
  std::string op = "strain_rate";
  app.add_option("--yield-number", c.yield_number, "sqrt(3) tau_y / (rho g H)");
  app.add_option("--spacing", c.dx, "particle spacing, m");
  app.add_option("--height", c.height, "column height H, m");
  app.add_option("--side", c.side, "column side, m");
  app.add_option("--plastic-viscosity", c.plastic_viscosity, "mu_p, Pa s");
  app.add_option("--yield-shear-rate", c.yield_shear_rate, "gamma_0 of the regularisation, 1/s");
  app.add_option("--end-time", c.t_end, "s, at most");
  app.add_option("--rest-speed", c.rest_speed, "m/s: the collapse has ended when the fastest particle stays below it");
  app.add_option("--viscous-operator", op, "sph.viscous_operator")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::ViscousOperator>()));
  CLI11_PARSE(app, argc, argv);
  c.op = scene::value_named<scene::SphSettings::ViscousOperator>(op);
  const sph::testing::SlumpRun run = sph::testing::run_slump(c, [](double t, double top, double fastest) {
    fmt::print("t {:.3f} s  top {:.4f} H  fastest {:.4f} m/s\n", t, top, fastest);
  });
  const double expected = sph::testing::slump_analysis(c.yield_number);
  fmt::print(
      "final height {:.4f} H at t = {:.4f} s ({} steps, {}), slump analysis {:.4f} H, ratio {:.4f}, half-width {:.4f} "
      "m\n",
      run.final_height / c.height, run.time, run.steps, run.stopped ? "collapse ended" : "end time reached", expected,
      run.final_height / c.height / expected, run.spread);
  return 0;
}
