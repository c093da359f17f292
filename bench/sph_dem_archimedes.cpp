// Archimedes through an SPH-DEM pair at several resolutions: a sphere resting
// on the floor of a tank of water (the floor's reaction against its weight less
// the buoyancy) or floating (its submerged volume fraction), fluid and sphere
// coupled in one process (tests/support/sph_dem_archimedes.hpp says how).
//   bench_sph_dem_archimedes [--density RHO_S] [--diameter-spacings D_OVER_DX ...] [--model
//                            boundary_particles|penalty] [--depth DIAMETERS] [--width DIAMETERS]
//                            [--end-time S] [--threads N]
// One line per resolution, then the order of the error between successive ones and its first-order
// limit; the last line is JSON.
#include "tests/support/sph_dem_archimedes.hpp"

#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "libsabo/scene/names.hpp"

int main(int argc, char** argv) {
  CLI::App app("SPH-DEM Archimedes: a resting or floating sphere against the buoyancy, at several resolutions");
  sabo::testing::ArchimedesCase c;
  std::vector<double> spacings{10, 20};
  std::string model = "boundary_particles";
  int threads = 0;
  app.add_option("--density", c.density, "sphere density, kg/m^3 (water 1000; below it: floating)")
      ->check(CLI::Range(1.0, 1e5));
  app.add_option("--diameter-spacings", spacings, "sphere diameters / SPH spacing, one run each")
      ->check(CLI::Range(2.0, 200.0));
  app.add_option("--model", model, "the SPH-DEM law (contact.sph_dem.model)")
      ->check(CLI::IsMember(sabo::scene::choice_names<sabo::scene::SphDemContact::Model>()));
  app.add_option("--depth", c.depth_diameters, "water depth / D");
  app.add_option("--width", c.width_diameters, "tank width / D (0: 2 floating, 1.6 resting)");
  app.add_option("--end-time", c.end_time, "simulated time, s (0: 0.5 floating, 0.2 resting)");
  app.add_option("--threads", threads, "OpenMP threads (0: OMP_NUM_THREADS)");
  CLI11_PARSE(app, argc, argv);
  if (threads > 0) omp_set_num_threads(threads);
  c.model = sabo::scene::value_named<sabo::scene::SphDemContact::Model>(model);

  nlohmann::json runs = nlohmann::json::array();
  std::vector<sabo::testing::ArchimedesResult> results;
  for (double d : spacings) {
    c.diameter_spacings = d;
    const auto r = sabo::testing::run_archimedes(c);
    results.push_back(r);
    fmt::print(
        "D = {} dx (dx = {:.4g} m), tank {:.4g} m wide, water {:.4g} m, {} fluid particles, {} steps to {:.3f} s: ", d,
        r.dx, r.width, r.depth, r.fluid_particles, r.steps, r.time);
    if (r.floats) {
      fmt::print("submerged fraction {:.4f} against {:.4f} ({:+.2f} %), centre {:.5f} m, free surface {:.5f} m, ",
                 r.submerged_fraction, r.expected_fraction, 100 * r.error(), r.centre_height, r.surface);
    } else {
      fmt::print("floor reaction {:.5g} N against weight - buoyancy {:.5g} N ({:+.2f} %), centre {:.5f} m, ",
                 r.floor_reaction, r.expected_reaction, 100 * r.error(), r.centre_height);
    }
    fmt::print("speed {:.2e} m/s, wall time {:.1f} s\n", r.speed, r.wall_seconds);
    runs.push_back({{"diameter_dx", d},
                    {"dx", r.dx},
                    {"fluid_particles", r.fluid_particles},
                    {"steps", r.steps},
                    {"error", r.error()},
                    {"measured", r.floats ? r.submerged_fraction : r.floor_reaction},
                    {"expected", r.floats ? r.expected_fraction : r.expected_reaction},
                    {"centre_height", r.centre_height},
                    {"speed", r.speed},
                    {"wall_seconds", r.wall_seconds}});
  }
  for (std::size_t k = 1; k < results.size(); ++k) {
    const auto& a = results[k - 1];
    const auto& b = results[k];
    const auto conv = sabo::testing::convergence(a.dx, a.error(), b.dx, b.error());
    fmt::print("D = {} -> {} dx: error {:+.2f} % -> {:+.2f} %, order {:.2f}, first-order limit {:+.2f} %\n",
               spacings[k - 1], spacings[k], 100 * a.error(), 100 * b.error(), conv.order, 100 * conv.limit);
    runs[k]["order"] = conv.order;
    runs[k]["first_order_limit"] = conv.limit;
  }
  fmt::print("{}\n", nlohmann::json{{"case", results.empty() || !results[0].floats ? "resting" : "floating"},
                                    {"model", model},
                                    {"density", c.density},
                                    {"threads", omp_get_max_threads()},
                                    {"runs", runs}}
                         .dump());
  return 0;
}
