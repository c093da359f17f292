// Stability and throughput of a dense pile: boulders of the paper's size (diameters 1-2 m, granite
// with intact-rock moduli, Hertz-Mindlin e 0.3, friction 0.5, rolling friction 0.1) filled into a closed box at 25 %
// solid fraction and settling under gravity (tests/support/dem_pile.hpp). Prints one JSON line:
// the largest rise of the total energy over its initial value (<= 0: never above), sphere-steps
// that left the box (tunnelling), and at the end the largest speed and the largest and mean
// overlap over the radius, with the sphere-steps per second of the whole run.
//
//   bench_dem_pile --spheres 10000 --time 10
#include "tests/support/dem_pile.hpp"

#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <chrono>

int main(int argc, char** argv) {
  std::size_t spheres = 10000;
  double duration_s = 10.0;
  double beta = 1.0;
  double height_over_side = 1.0;
  std::uint64_t seed = 11;
  CLI::App app{"A dense pile of boulders settling in a box: stability and throughput."};
  app.add_option("--spheres", spheres, "number of spheres")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--time", duration_s, "simulated time, s")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--beta", beta, "dt = beta * stable dt")->check(CLI::Range(1e-6, 1.0))->capture_default_str();
  app.add_option("--height", height_over_side, "box height over its side")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the fill")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const auto start = std::chrono::steady_clock::now();
  const sabo::dem::PileReport report =
      sabo::dem::settle_pile(sabo::dem::pile_scene(spheres, height_over_side, seed), duration_s, beta);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print(
      "{{\"bench\": \"dem_pile\", \"spheres\": {}, \"threads\": {}, \"simulated_s\": {}, \"steps\": {}, \"dt_s\": "
      "{:.4e}, \"sphere_steps_per_second\": {:.0f}, \"wall_seconds\": {:.2f}, \"initial_energy_J\": {:.6e}, "
      "\"largest_energy_rise_J\": {:.3e}, \"escaped_sphere_steps\": {}, \"final_largest_speed_m_per_s\": {:.3e}, "
      "\"final_largest_overlap_over_radius\": {:.4e}, \"final_mean_overlap_over_radius\": {:.4e}, "
      "\"contacts\": {}}}\n",
      spheres, omp_get_max_threads(), duration_s, report.steps, report.dt,
      static_cast<double>(spheres) * static_cast<double>(report.steps) / seconds, seconds, report.initial_energy,
      report.largest_energy_rise, report.escaped, report.final_largest_speed, report.final_largest_overlap_ratio,
      report.final_mean_overlap_ratio, report.contacts);
  return report.escaped == 0 && report.largest_energy_rise <= 0 ? 0 : 1;
}
