// DEM throughput on spheres settling in a box: the case LIGGGHTS-PUBLIC 3.8 is
// measured on (Hertz-Mindlin with tangential history, 30 000 spheres of 5 mm
// diameter, rho 2500, E 5 MPa, nu 0.45, e 0.3, mu 0.5, no rolling resistance,
// dt 1e-5 s, settled in a box). Prints one JSON line.
//
// The spheres are placed by the scene fill (seeded, no overlap, 25 % solid
// fraction) in a box whose base grows with the count (the layer stays about 20
// sphere diameters deep: the work per sphere does not depend on the count), with
// a floor and four side walls (DemModel walls). Phase 1, "settling": the
// spheres fall and pile up for --settle-time s at --settle-dt (the timed figure
// of this phase is sphere-steps per second while they fall and collide). Phase
// 2, "settled": --steps steps at --dt on the settled pile, the figure to compare
// with LIGGGHTS. Also reported: contacts and Verlet-list pairs per sphere, list
// builds, the largest overlap over the radius, the energy (which never rises) and the
// CPU seconds of both phases (all threads; steadier than wall time on a shared machine) and a hash of the
// final state's bits (to compare builds and thread counts).
//
//   bench_dem_box --spheres 30000
#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <numbers>
#include <span>

#include "dem_solver/dem_model.hpp"

using namespace sabo;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  int spheres = 30000;
  double diameter_m = 5e-3;
  double settle_time_s = 0.3;
  double settle_dt_s = 5e-5;
  double dt_s = 1e-5;
  int steps = 1000;
  std::uint64_t seed = 1;
  CLI::App app{"DEM throughput on spheres settling in a box (the LIGGGHTS comparison case)."};
  app.add_option("--spheres", spheres, "number of spheres")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--diameter", diameter_m, "sphere diameter, m")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--settle-time", settle_time_s, "simulated settling time, s")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--settle-dt", settle_dt_s, "time step while settling, s")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--dt", dt_s, "time step of the timed settled phase, s")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--steps", steps, "timed steps on the settled pile")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the fill")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  scene::Scene scene;
  scene.file = "bench_dem_box (built in code)";
  scene.run.gravity = Vec3(0, 0, -9.81);
  scene::Material glass;
  glass.name = "beads";
  glass.density = 2500;
  glass.youngs_modulus = 5e6;
  glass.poisson_ratio = 0.45;
  scene.materials.push_back(glass);
  scene.dem_contact.model = scene::DemLaw::hertz_mindlin;
  scene.dem_contact.restitution = 0.3;
  scene.dem_contact.friction = 0.5;
  scene.dem_contact.rolling_friction = 0;  // LIGGGHTS' case has none

  // 25 % solid fraction in a box 40 diameters high, base scaled with the count.
  const double sphere_volume = std::numbers::pi / 6 * diameter_m * diameter_m * diameter_m;
  const double height = 40 * diameter_m;
  const double side = std::sqrt(spheres * sphere_volume / 0.25 / height);
  scene::ParticleSet set;
  set.name = "beads";
  set.material = "beads";
  set.kind = scene::ParticleSet::Kind::fill;
  set.region = Aabb{Vec3::Zero(), Vec3(side, side, height)};
  set.count = static_cast<std::size_t>(spheres);
  set.diameter_min = set.diameter_max = diameter_m;
  set.seed = seed;
  scene.particle_sets.push_back(set);

  const auto setup_start = Clock::now();
  dem::DemModel model(scene);
  for (int axis = 0; axis < 3; ++axis) {
    dem::Wall low;
    low.normal = Vec3::Unit(axis);
    model.add_wall(low);
    if (axis == 2) break;  // open top
    dem::Wall high;
    high.point = Vec3(side, side, 0);
    high.normal = -Vec3::Unit(axis);
    model.add_wall(high);
  }
  const double setup_seconds = std::chrono::duration<double>(Clock::now() - setup_start).count();
  const double initial_energy = model.energies().total();

  double dt_previous = 0, largest_energy = initial_energy;
  double cpu_seconds = 0;  // of the last run(), all threads: steadier than the wall time on a shared machine
  auto run = [&](std::int64_t count, double dt) {
    const auto start = Clock::now();
    const std::clock_t cpu_start = std::clock();
    for (std::int64_t k = 0; k < count; ++k) {
      model.compute_internal_forces(dt_previous);
      model.integrate(dt_previous, dt);
      dt_previous = dt;
      largest_energy = std::max(largest_energy, model.energies().total());
    }
    cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    return std::chrono::duration<double>(Clock::now() - start).count();
  };
  const auto settle_steps = static_cast<std::int64_t>(std::ceil(settle_time_s / settle_dt_s));
  const double settle_seconds = run(settle_steps, settle_dt_s);
  const std::size_t builds_before = model.neighbour_builds();
  const double settle_cpu_seconds = cpu_seconds;
  const double settled_seconds = run(steps, dt_s);

  double largest_overlap = 0;  // over the radius
  const auto positions = model.positions();
  const double radius = 0.5 * diameter_m;
  for (const auto& contact : model.contact_histories()) {
    const double overlap = 2 * radius - (positions[contact.a] - positions[contact.b]).norm();
    largest_overlap = std::max(largest_overlap, overlap / radius);
  }
  double largest_speed = 0;
  for (const auto& v : model.velocities()) largest_speed = std::max(largest_speed, v.norm());
  // The final state's bits (positions, velocities, spins, energies), FNV-1a: two builds or thread counts that
  // print the same hash computed the same numbers.
  std::uint64_t state_hash = 14695981039346656037ULL;
  auto hash_bytes = [&](const void* data, std::size_t bytes) {
    const auto* byte = static_cast<const unsigned char*>(data);
    for (std::size_t k = 0; k < bytes; ++k) state_hash = (state_hash ^ byte[k]) * 1099511628211ULL;
  };
  const dem::DemModel& state = model;
  for (const std::span<const Vec3> values : {state.positions(), state.velocities(), state.angular_velocities()}) {
    hash_bytes(values.data(), values.size_bytes());
  }
  const dem::Energies energies = model.energies();
  for (const double value : {energies.kinetic, energies.potential, energies.elastic, energies.dissipated}) {
    hash_bytes(&value, sizeof value);
  }
  const double n = static_cast<double>(model.size());
  fmt::print(
      "{{\"bench\": \"dem_box\", \"spheres\": {}, \"threads\": {}, \"box_side_m\": {:.4f}, \"settle_steps\": {}, "
      "\"settle_dt_s\": {:.2e}, \"settling_sphere_steps_per_second\": {:.0f}, \"steps\": {}, \"dt_s\": {:.2e}, "
      "\"sphere_steps_per_second\": {:.0f}, \"microseconds_per_step\": {:.1f}, \"contacts_per_sphere\": {:.3f}, "
      "\"wall_contacts\": {}, \"neighbour_pairs_per_sphere\": {:.3f}, \"neighbour_builds_settled\": {}, "
      "\"largest_overlap_over_radius\": {:.4e}, \"largest_speed_m_per_s\": {:.3e}, "
      "\"energy_rise_over_initial_J\": {:.3e}, \"setup_seconds\": {:.3f}, \"settle_seconds\": {:.3f}, "
      "\"settle_cpu_seconds\": {:.3f}, \"settled_cpu_seconds\": {:.3f}, \"state_hash\": \"{:016x}\"}}\n",
      model.size(), omp_get_max_threads(), side, settle_steps, settle_dt_s,
      n * static_cast<double>(settle_steps) / settle_seconds, steps, dt_s, n * steps / settled_seconds,
      1e6 * settled_seconds / steps, 2.0 * static_cast<double>(model.contact_count()) / n, model.wall_contact_count(),
      static_cast<double>(model.neighbour_pair_count()) / n, model.neighbour_builds() - builds_before, largest_overlap,
      largest_speed, largest_energy - initial_energy, setup_seconds, settle_seconds, settle_cpu_seconds, cpu_seconds,
      state_hash);
  return 0;
}
