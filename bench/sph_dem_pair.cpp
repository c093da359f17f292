// The SPH-DEM pair's cost per step against the sph_solver's own step: N
// boulders (granite, diameter `--diameter`, placed at random without overlap)
// inside a block of water of about `--particles` SPH particles at rest in a
// tank, fluid and boulders coupled in one process as the coupler and the two
// solvers do it (tests/support/sph_dem_harness.hpp). The pair's time is the
// coupler's work for it (compute and scatter: the boulders' wall particles,
// their selection near the fluid, the returned forces summed per boulder; or
// the penalty springs); the SPH time is SphModel's forces and integration with
// those wall particles in its sums. Threads: OMP_NUM_THREADS.
//   bench_sph_dem_pair [--particles N] [--boulders B] [--diameter D_OVER_DX] [--steps S]
//                      [--model boundary_particles|penalty]
// The last line is JSON.
#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <random>

#include "tests/support/sph_dem_harness.hpp"
#include "tests/support/sph_scenes.hpp"

int main(int argc, char** argv) {
  CLI::App app("SPH-DEM pair cost against the SPH step");
  double particles = 1e5, diameter = 3.0;
  int boulders = 200, steps = 10;
  std::string model = "boundary_particles";
  app.add_option("--particles", particles, "SPH particles (about)");
  app.add_option("--boulders", boulders, "boulders inside the water");
  app.add_option("--diameter", diameter, "boulder diameter in SPH spacings (>= 2)");
  app.add_option("--steps", steps, "timed steps (after 2 untimed)");
  app.add_option("--model", model, "the pair's law")->check(CLI::IsMember({"boundary_particles", "penalty"}));
  CLI11_PARSE(app, argc, argv);

  using namespace sabo;
  const double dx = 0.01;
  const double side = std::cbrt(particles / 0.8) * dx;  // a block side x side x 0.8 side
  const Vec3 top(side, side, 0.8 * side);
  scene::Scene s = sph::testing::water_scene(dx, 10.0 * std::sqrt(2 * 9.81 * top.z()), 1.5);
  scene::Material granite;
  granite.name = "granite";
  granite.density = 2650;
  granite.youngs_modulus = 30e9;
  granite.poisson_ratio = 0.3;
  s.materials.insert(s.materials.begin(), granite);
  s.fluids.push_back(sph::testing::box_body("water", Vec3::Zero(), top));
  scene::ParticleSet set;
  set.name = "boulders";
  set.material = "granite";
  // On a lattice of at least `boulders` cells filling the block, each jittered at random within its cell.
  const double radius = 0.5 * diameter * dx;
  const double target = std::cbrt(side * side * top.z() / boulders);
  const auto per_axis = [&](double length) { return std::max(1, static_cast<int>(std::ceil(length / target))); };
  const int nx = per_axis(side), ny = per_axis(side), nz = per_axis(top.z());
  const Vec3 cell(side / nx, side / ny, top.z() / nz);
  const double room = cell.minCoeff() - 2 * radius - dx;  // the jitter that keeps neighbours dx apart
  if (room < 0) {
    fmt::print(stderr, "{} boulders of {} dx do not fit in the block; lower --boulders or --diameter\n", boulders,
               diameter);
    return 2;
  }
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  const int cells = nx * ny * nz;
  for (int k = 0; k < boulders; ++k) {
    const int c = static_cast<int>(static_cast<long>(k) * cells / boulders);  // spread over the block
    const Vec3 centre((c % nx + 0.5) * cell.x(), (c / nx % ny + 0.5) * cell.y(), (c / (nx * ny) + 0.5) * cell.z());
    const Vec3 jitter(u(random), u(random), u(random));
    set.spheres.push_back({centre + room * jitter, radius, Vec3::Zero(), Vec3::Zero()});
  }
  s.particle_sets.push_back(set);
  s.sph_dem_default.model =
      model == "penalty" ? scene::SphDemContact::Model::penalty : scene::SphDemContact::Model::boundary_particles;
  for (auto role : {sabo::Role::sph, sabo::Role::dem}) s.solvers.emplace_back().role = role;

  sabo::testing::SphDemHarness run(s, sph::testing::container_walls(Vec3::Zero(), top + Vec3(0, 0, 0.1), dx, 3));
  run.step();
  run.step();
  const double pair0 = run.pair_seconds(), sph0 = run.sph_seconds(), dem0 = run.dem_seconds();
  for (int k = 0; k < steps; ++k) run.step();
  const double pair = (run.pair_seconds() - pair0) / steps, sph = (run.sph_seconds() - sph0) / steps,
               dem = (run.dem_seconds() - dem0) / steps;
  const auto& effect = run.pair().effect();
  fmt::print(
      "{} SPH particles, {} boulders of {} dx ({}), {} threads: per step SPH {:.4f} s, pair {:.5f} s ({:.1f} % of "
      "the SPH step), DEM {:.5f} s\n",
      run.sph().size(), set.spheres.size(), diameter, model, omp_get_max_threads(), sph, pair, 100 * pair / sph, dem);
  fmt::print("{}\n", nlohmann::json{{"sph_particles", run.sph().size()},
                                    {"boulders", set.spheres.size()},
                                    {"diameter_dx", diameter},
                                    {"model", model},
                                    {"threads", omp_get_max_threads()},
                                    {"sph_seconds_per_step", sph},
                                    {"pair_seconds_per_step", pair},
                                    {"pair_share_of_sph_step", pair / sph},
                                    {"dem_seconds_per_step", dem},
                                    {"effect", effect}}
                         .dump());
  return 0;
}
