// Particle-steps per second of SphModel alone on a 3-D dam break (a water
// column of a x a x 2a, a = 0.4 m, released in a closed tank 4a long) with
// boundary-particle walls, the neighbour count per particle and the memory per
// particle. Threads: OMP_NUM_THREADS.
//   bench_sph_throughput [--spacing DX] [--steps N] [--kernel wendland_c2|cubic_spline] [--ratio H_OVER_DX]
//                        [--wall-work bounded|stored|unstored] [--rheology inviscid|newtonian|bingham]
//                        [--viscous-operator strain_rate|morris]
// --rheology: the column's material: inviscid water (the default), water of viscosity 1e-3 Pa s,
// or a Bingham slurry (tau_y 100 Pa, mu_p 1 Pa s, gamma_0 1/s); --viscous-operator: sph.viscous_operator.
// Under mpirun (mpirun -n R bench_sph_throughput ...) the model is shared by the R ranks
// (sph_model.hpp, "Ranks"): rank 0 prints, the rate counts every rank's particles over the
// slowest rank's time, and the halo (particles read from other ranks) is reported per step. The
// state after the timed steps is digested (XXH3 of every active particle's position, velocity and
// density, collected to rank 0): the same digest on any rank count is the same bits
// (bench/sph_ranks.py compares them).
#include <fmt/format.h>
#include <omp.h>
#include <xxhash.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <optional>
#include <utility>

#include "libsabo/scene/names.hpp"
#include "sph_solver/parallel/mpi_ranks.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace {

// XXH3 of the active particles' ids, positions, velocities and densities, in id order.
std::uint64_t state_digest(const sabo::sph::SphModel& model) {
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (!model.active()[i]) continue;
    const double values[8] = {static_cast<double>(i),    model.positions()[i].x(),  model.positions()[i].y(),
                              model.positions()[i].z(),  model.velocities()[i].x(), model.velocities()[i].y(),
                              model.velocities()[i].z(), model.densities()[i]};
    XXH3_64bits_update(state, values, sizeof(values));
  }
  const std::uint64_t digest = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  return digest;
}

double resident_megabytes() {
  std::ifstream statm("/proc/self/statm");
  double pages = 0, resident = 0;
  statm >> pages >> resident;
  return resident * 4096.0 / 1e6;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace sabo;
  CLI::App app("SPH throughput on a 3-D dam break (or a periodic slab at rest: --slab)");
  double dx = 0.009, ratio = 1.3;
  int steps = 20;
  std::string kernel = "wendland_c2";
  app.add_option("--spacing", dx, "particle spacing, m (0.009: about 170 000 particles)");
  app.add_option("--steps", steps, "timed steps");
  app.add_option("--kernel", kernel, "wendland_c2 or cubic_spline")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::Kernel>()));
  app.add_option("--ratio", ratio, "h / dx");
  std::string wall_work = "bounded";
  app.add_option("--wall-work", wall_work, "sph.wall_work (the default: bounded)")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::WallWork>()));
  std::string rheology = "inviscid", viscous_operator = "strain_rate";
  app.add_option("--rheology", rheology, "the column's rheology (inviscid water: the default)")
      ->check(CLI::IsMember({"inviscid", "newtonian", "bingham"}));
  app.add_option("--viscous-operator", viscous_operator, "sph.viscous_operator (the default: strain_rate)")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::ViscousOperator>()));
  std::int64_t slab_particles = 0;
  app.add_option("--slab", slab_particles,
                 "instead of the dam break: about this many fluid particles in a layer 20 spacings deep at rest on a "
                 "floor, periodic along x and y (the same share of wall particles at every size: cost against N)")
      ->check(CLI::PositiveNumber);
  std::optional<sph::parallel::MpiSession> mpi;
  std::shared_ptr<sph::parallel::Ranks> ranks;
  if (sph::parallel::launched_by_mpi()) {
    mpi.emplace(argc, argv);
    ranks = std::make_shared<sph::parallel::MpiRanks>();
  }
  CLI11_PARSE(app, argc, argv);
  const bool root = ranks == nullptr || ranks->rank() == 0;

  // What runs: the dam break (a column a x a x 2a in a tank 4a x a x 3a, wall particles under and around it),
  // or the slab (20 spacings of water as wide as it takes to hold slab_particles, periodic along x and y, wall
  // particles under it). lo..hi: the lattice box of the wall particles, less the tank's inside.
  const bool slab = slab_particles > 0;
  const double a = 0.4;
  const int layers = static_cast<int>(std::ceil(2 * ratio));
  Vec3 fluid_max, tank_max, lo, hi;
  if (slab) {
    constexpr int kSlabDepth = 20;
    const double width =
        static_cast<double>(std::max(8L, std::lround(std::sqrt(static_cast<double>(slab_particles) / kSlabDepth)))) *
        dx;
    fluid_max = tank_max = Vec3(width, width, kSlabDepth * dx);
    lo = Vec3(0.0, 0.0, -layers * dx);
    hi = Vec3(width, width, 0.0);
  } else {
    fluid_max = Vec3(a, a, 2 * a);
    tank_max = Vec3(4 * a, a, 3 * a);
    lo = -Vec3::Constant(layers * dx);
    hi = Vec3(tank_max.x() + layers * dx, tank_max.y() + layers * dx, tank_max.z());
  }
  const double sound_speed = 10.0 * std::sqrt(2 * 9.81 * fluid_max.z());
  scene::Scene s = sph::testing::water_scene(dx, sound_speed, ratio);
  s.sph.kernel = scene::value_named<scene::SphSettings::Kernel>(kernel);
  s.sph.wall_work = scene::value_named<scene::SphSettings::WallWork>(wall_work);
  s.sph.viscous_operator = scene::value_named<scene::SphSettings::ViscousOperator>(viscous_operator);
  scene::Material& material = s.materials[0];
  if (rheology == "newtonian") {
    material.rheology = scene::Material::Rheology::newtonian;
    material.viscosity = 1e-3;
  } else if (rheology == "bingham") {
    material.rheology = scene::Material::Rheology::bingham;
    material.viscosity = 1.0;
    material.yield_stress = 100.0;
    material.yield_shear_rate = 1.0;
  }
  if (slab) {
    s.sph.periodic_x = {0.0, fluid_max.x()};
    s.sph.periodic_y = {0.0, fluid_max.y()};
  }
  s.fluids.push_back(sph::testing::box_body(slab ? "slab" : "column", Vec3::Zero(), fluid_max));

  const double memory_before = resident_megabytes();
  sph::SphModel model(s, ranks);
  physics::BoundaryParticles walls;
  const Vec3 min = Vec3::Zero(), max = tank_max;
  const auto count = [&](double e) { return static_cast<int>(std::floor(e / dx + 1e-9)); };
  for (int k = 0; k < count(hi.z() - lo.z()); ++k)
    for (int j = 0; j < count(hi.y() - lo.y()); ++j)
      for (int i = 0; i < count(hi.x() - lo.x()); ++i) {
        const Vec3 p = lo + dx * Vec3(i + 0.5, j + 0.5, k + 0.5);
        if ((p.array() > min.array()).all() && (p.array() < max.array()).all()) continue;
        walls.position.push_back(p);
        walls.velocity.push_back(Vec3::Zero());
        walls.normal.push_back(Vec3::UnitZ());
        walls.acceleration.push_back(Vec3::Zero());
        walls.volume.push_back(dx * dx * dx);
      }
  const std::size_t wall_count = walls.size();
  model.set_boundary(std::move(walls));  // the model keeps the only copy
  double dt_previous = 0;
  const auto step = [&] {
    model.compute_internal_forces(dt_previous);
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    dt_previous = dt;
  };
  step();  // warm-up: buffers sized
  const double memory_after = resident_megabytes();
  std::int64_t halo = 0, most_owned = ranks ? 0 : static_cast<std::int64_t>(model.size());
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < steps; ++k) {
    step();
    halo += static_cast<std::int64_t>(model.halo_count());
    if (ranks) most_owned = std::max(most_owned, static_cast<std::int64_t>(model.owned_count()));
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const int rank_count = ranks ? ranks->size() : 1;
  if (ranks) {
    double slowest[2] = {seconds, static_cast<double>(most_owned)};
    ranks->max(slowest);
    seconds = slowest[0];
    most_owned = static_cast<std::int64_t>(slowest[1]);
    std::int64_t total[1] = {halo};
    ranks->sum(total);
    halo = total[0];
  }
  model.collect_state();  // rank 0: the whole state (alone: nothing to do)
  if (!root) return 0;
  const std::uint64_t digest = state_digest(model);
  const double n = static_cast<double>(model.size());
  fmt::print("{} particles {} walls {} threads {} kernel {} h/dx {} rheology {} viscous operator {}\n",
             slab ? "periodic slab" : "dam break", model.size(), wall_count, omp_get_max_threads(), kernel, ratio,
             rheology, viscous_operator);
  const double rate = n * steps / seconds;
  const double bytes = (memory_after - memory_before) * 1e6 / (n + static_cast<double>(wall_count));
  fmt::print("particle_steps_per_second {:.4g}\n", rate);
  fmt::print("neighbours_per_particle {:.1f}\n", model.mean_neighbours());
  fmt::print("bytes_per_particle {:.0f}\n", bytes);
  const double halo_per_step = static_cast<double>(halo) / steps;
  if (ranks) {
    fmt::print("ranks {}: halo {:.0f} particles a step ({:.3g} of N), the largest rank owned {} ({:.3g} of N / R)\n",
               rank_count, halo_per_step, halo_per_step / n, most_owned,
               static_cast<double>(most_owned) * rank_count / n);
  }
  // The last line: the figures for bench/run.py.
  fmt::print(
      "{{\"particles\": {}, \"walls\": {}, \"particle_steps_per_second\": {:.6g}, \"neighbours_per_particle\": {:.2f}, "
      "\"bytes_per_particle\": {:.1f}, \"seconds\": {:.4g}, \"ranks\": {}, \"halo_per_step\": {:.1f}, "
      "\"largest_rank_particles\": {}, \"state_digest\": \"{:016x}\"}}\n",
      model.size(), wall_count, rate, model.mean_neighbours(), bytes, seconds, rank_count, halo_per_step, most_owned,
      digest);
  return 0;
}
