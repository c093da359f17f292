// DEM throughput: sphere-steps per second of DemModel alone (no protocol, no
// output), on a resting pile of the paper's boulders. Prints one JSON line.
//
// The pile: spheres of one diameter (the paper's boulders are 1-2 m; 1.5 m by
// default) in a simple cubic stack `layers` high on a floor of fixed spheres,
// under gravity, each given a small random velocity. Neighbours start touching
// (centres one diameter apart, less 0.5e-6 of it, within DemModel's tolerance
// for touching spheres), so the contacts exist from the first step without
// seconds of simulated settling: the vertical ones carry the weight, the
// lateral ones open and close as the unconfined stack relaxes. The JSON line
// reports the contacts per sphere measured (a settled pile has about 4-6, a
// flowing one fewer); a sphere-step costs more the more contacts it has.
// Material and contact law are the paper's (docs/model.md): granite rho 3000,
// E 30 GPa, nu 0.3; damping ratios 0.7 / 0.4, friction 1.0, rolling friction
// 0.1, normal stiffness scale 0.01. dt = beta * DemModel::stable_dt(), beta 0.25.
//
//   bench_dem_throughput --spheres 10000 --steps 100
#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>

#include "dem_solver/dem_model.hpp"
#include "libsabo/geometry/sphere_fill.hpp"

using namespace sabo;
using Clock = std::chrono::steady_clock;

namespace {

struct PileSize {
  int side = 0;    // spheres along x and along y
  int layers = 0;  // free layers above the fixed floor
};

scene::Scene pile_scene(const PileSize& size, double diameter_m, double speed_m_per_s, std::uint64_t seed) {
  scene::Scene scene;
  scene.file = "bench_dem_throughput (built in code)";
  scene.run.gravity = Vec3(0, 0, -9.81);
  scene::Material granite;
  granite.name = "granite";
  granite.density = 3000.0;
  granite.youngs_modulus = 30e9;
  granite.poisson_ratio = 0.3;
  scene.materials.push_back(granite);
  // docs/model.md "DEM-DEM" (also the defaults; stated so that the bench does not depend on them).
  scene.dem_contact.normal_damping_ratio = 0.7;
  scene.dem_contact.tangential_damping_ratio = 0.4;
  scene.dem_contact.friction = 1.0;
  scene.dem_contact.rolling_friction = 0.1;
  scene.dem_contact.normal_stiffness_scale = 0.01;

  scene::ParticleSet floor;
  floor.name = "floor";
  floor.material = "granite";
  scene::ParticleSet pile;
  pile.name = "pile";
  pile.material = "granite";

  const double spacing = diameter_m * (1.0 - 0.5e-6);
  std::mt19937_64 random(seed);
  const auto uniform_velocity = [&] { return speed_m_per_s * (2.0 * geometry::unit_uniform(random()) - 1.0); };
  for (int layer = 0; layer <= size.layers; ++layer) {
    for (int iy = 0; iy < size.side; ++iy) {
      for (int ix = 0; ix < size.side; ++ix) {
        scene::Sphere sphere;
        sphere.center = Vec3(spacing * ix, spacing * iy, spacing * layer);
        sphere.radius = 0.5 * diameter_m;
        if (layer == 0) {
          floor.spheres.push_back(sphere);
        } else {
          const double vx = uniform_velocity(), vy = uniform_velocity(), vz = uniform_velocity();
          sphere.velocity = Vec3(vx, vy, vz);
          pile.spheres.push_back(sphere);
        }
      }
    }
  }
  scene.particle_sets.push_back(floor);  // ids 0 .. side^2 - 1
  scene.particle_sets.push_back(pile);
  return scene;
}

}  // namespace

int main(int argc, char** argv) {
  int spheres = 10000;
  int layers = 10;
  int steps = 100;
  int warmup = 20;
  double diameter_m = 1.5;
  double speed_m_per_s = 0.1;
  double beta = 0.25;
  std::uint64_t seed = 1;
  CLI::App app{"DEM throughput: sphere-steps per second of DemModel on a resting pile of boulders."};
  app.add_option("--spheres", spheres, "free spheres, about (a square stack: side = round(sqrt(N / layers)))")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--layers", layers, "layers of free spheres above the fixed floor")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--steps", steps, "timed steps")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--warmup", warmup, "steps run before timing")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--diameter", diameter_m, "sphere diameter, m")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--speed", speed_m_per_s, "largest initial velocity component, m/s")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--beta", beta, "dt = beta * stable dt (paper eq. 7)")
      ->check(CLI::Range(1e-6, 1.0))
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the initial velocities")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  PileSize size;
  size.layers = layers;
  size.side = std::max(1, static_cast<int>(std::lround(std::sqrt(static_cast<double>(spheres) / layers))));

  const auto setup_start = Clock::now();
  dem::DemModel model(pile_scene(size, diameter_m, speed_m_per_s, seed));
  const auto floor_count = static_cast<std::uint32_t>(size.side * size.side);
  for (std::uint32_t id = 0; id < floor_count; ++id) model.set_fixed(id, true);
  const double setup_seconds = std::chrono::duration<double>(Clock::now() - setup_start).count();
  const std::size_t free_spheres = model.size() - floor_count;
  const double dt = beta * model.stable_dt();

  double dt_previous = 0;
  const auto step = [&] {
    model.compute_internal_forces(dt_previous);
    model.integrate(dt_previous, dt);
    dt_previous = dt;
  };
  for (int k = 0; k < warmup; ++k) step();

  // Only the steps are timed; the contacts are counted between them. Contacts per free
  // sphere: a pair of free spheres counts for both, a pair with a fixed floor sphere for one.
  double wall_seconds = 0;
  std::size_t contact_ends = 0, contact_pairs = 0;
  for (int k = 0; k < steps; ++k) {
    const auto start = Clock::now();
    step();
    wall_seconds += std::chrono::duration<double>(Clock::now() - start).count();
    contact_pairs += model.contact_count();
  }
  for (const auto& contact : model.contact_histories()) {
    contact_ends += (model.is_fixed(contact.a) ? 0 : 1) + (model.is_fixed(contact.b) ? 0 : 1);
  }
  const double contacts_per_sphere = static_cast<double>(contact_ends) / static_cast<double>(free_spheres);
  const double mean_pairs = static_cast<double>(contact_pairs) / steps;
  const double sphere_steps = static_cast<double>(free_spheres) * steps;
  fmt::print(
      "{{\"bench\": \"dem_throughput\", \"spheres\": {}, \"fixed_spheres\": {}, \"layers\": {}, \"steps\": {}, "
      "\"threads\": {}, \"dt_s\": {:.4e}, \"sphere_steps_per_second\": {:.0f}, \"microseconds_per_step\": {:.1f}, "
      "\"contacts_per_sphere\": {:.3f}, \"contact_pairs\": {:.0f}, \"wall_seconds\": {:.3f}, "
      "\"setup_seconds\": {:.3f}, \"neighbour_pairs\": {}, \"neighbour_builds\": {}}}\n",
      free_spheres, floor_count, layers, steps, omp_get_max_threads(), dt, sphere_steps / wall_seconds,
      1e6 * wall_seconds / steps, contacts_per_sphere, mean_pairs, wall_seconds, setup_seconds,
      model.neighbour_pair_count(), model.neighbour_builds());
  return 0;
}
