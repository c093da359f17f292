// The SPH model on several ranks (sph_model.hpp, "Ranks"): run under mpirun, every rank steps
// its share of a scene and, beside it, the whole scene alone; each particle a rank owns, and
// the state gathered from all ranks, must equal the model alone to the bit. The slabs'
// arithmetic is checked on its own. Registered with ctest for 2 ranks (tests/sph_solver/CMakeLists.txt).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numbers>

#include "libsabo/core/error.hpp"
#include "libsabo/io/hdf5.hpp"
#include "sph_solver/parallel/mpi_ranks.hpp"
#include "sph_solver/parallel/slabs.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::container_walls;
using testing::water_scene;

std::shared_ptr<parallel::Ranks> world() {
  return std::make_shared<parallel::MpiRanks>();
}

TEST(SphSlabs, BalanceTheParticlesAndGiveEveryRankALayer) {
  const std::int64_t counts[] = {0, 10, 10, 10, 10, 0, 0, 40, 0, 0};
  const parallel::Slabs two(counts, 2);
  EXPECT_EQ(two.first(0), 0);
  // Rank 1 starts at the first layer that would take rank 0 past half: 40 particles each.
  EXPECT_EQ(two.first(1), 7);
  EXPECT_EQ(two.owner(6), 0);
  EXPECT_EQ(two.owner(7), 1);
  EXPECT_EQ(two.windows_holding(4), (std::vector<int>{0}));
  EXPECT_EQ(two.windows_holding(6), (std::vector<int>{0, 1}));
  EXPECT_EQ(two.windows_holding(7), (std::vector<int>{0, 1}));
  EXPECT_EQ(two.windows_holding(8), (std::vector<int>{1}));
  const parallel::Slabs four(counts, 4);
  for (int r = 0; r < 4; ++r) EXPECT_LT(four.first(r), four.first(r + 1)) << "rank " << r << " has no layer";
  // All in one layer: still one layer each.
  const std::int64_t lump[] = {0, 0, 80, 0};
  const parallel::Slabs lumped(lump, 4);
  for (int r = 0; r < 4; ++r) EXPECT_EQ(lumped.first(r), r);
  const std::int64_t few[] = {5, 5};
  EXPECT_THROW(parallel::Slabs(few, 3), Error);
}

struct Case {
  scene::Scene scene;
  physics::BoundaryParticles walls;
  double end_time;
};

// Steps a model of the whole scene alone and this rank's share of it with the same steps, compares
// the wall forces and the stable step after every compute and this rank's particles after every
// integrate, and at the end the gathered state, rank 0's collected state and the energies; returns
// the number of steps.
int compare_runs(const Case& c, const char* what) {
  SphModel alone(c.scene), shared(c.scene, world());
  alone.set_boundary(c.walls);
  shared.set_boundary(c.walls);
  int steps = 0, mismatches = 0;
  double dt_previous = 0, time = 0;
  std::size_t most_halo = 0;
  while (time < c.end_time && mismatches == 0) {
    alone.compute_internal_forces(dt_previous);
    shared.compute_internal_forces(dt_previous);
    EXPECT_EQ(alone.stable_dt(), shared.stable_dt()) << what << " step " << steps;
    for (std::size_t b = 0; b < c.walls.size(); ++b) {
      if (alone.boundary_forces()[b] != shared.boundary_forces()[b]) ++mismatches;
    }
    EXPECT_EQ(mismatches, 0) << what << ": wall forces differ at step " << steps;
    most_halo = std::max(most_halo, shared.halo_count());
    const double dt = alone.stable_dt();
    alone.integrate(dt_previous, dt);
    shared.integrate(dt_previous, dt);
    dt_previous = dt;
    time += dt;
    ++steps;
    for (std::size_t i = 0; i < alone.size(); ++i) {
      if (!shared.owned()[i]) continue;
      if (alone.positions()[i] != shared.positions()[i] || alone.velocities()[i] != shared.velocities()[i] ||
          alone.densities()[i] != shared.densities()[i]) {
        ADD_FAILURE() << what << ": particle " << i << " differs at step " << steps;
        ++mismatches;
        break;
      }
    }
  }
  const SphModel::ParticleState all = shared.gather_state();
  std::size_t compared = 0;
  for (std::size_t i = 0; i < alone.size(); ++i) {
    EXPECT_EQ(all.active[i], alone.active()[i]) << what << ": particle " << i;
    if (!alone.active()[i]) continue;
    ++compared;
    EXPECT_EQ(all.position[i], alone.positions()[i]) << what << ": particle " << i;
    EXPECT_EQ(all.velocity[i], alone.velocities()[i]) << what << ": particle " << i;
    EXPECT_EQ(all.density[i], alone.densities()[i]) << what << ": particle " << i;
    EXPECT_EQ(all.pressure[i], alone.pressures()[i]) << what << ": particle " << i;
    for (std::size_t q = 0; q < all.stress.size() / alone.size(); ++q) {
      EXPECT_EQ(all.stress[6 * i + q], alone.deviatoric_stress()[6 * i + q]) << what << ": particle " << i;
    }
  }
  // Rank 0's own accessors after collect_state(): the whole state.
  shared.collect_state();
  if (parallel::MpiRanks().rank() == 0) {
    for (std::size_t i = 0; i < alone.size(); ++i) {
      EXPECT_EQ(shared.active()[i], alone.active()[i]) << what << ": collected particle " << i;
      if (alone.active()[i]) {
        EXPECT_EQ(shared.positions()[i], alone.positions()[i]) << what << ": collected " << i;
      }
    }
  }
  const double energy = alone.energies().total(), shared_energy = shared.energies().total();
  // Exact sums (sph_solver/exact_sum.hpp): the energies too are the same bits.
  EXPECT_EQ(shared.energies().kinetic, alone.energies().kinetic) << what;
  EXPECT_EQ(shared.energies().potential, alone.energies().potential) << what;
  EXPECT_EQ(shared.energies().elastic, alone.energies().elastic) << what;
  EXPECT_EQ(shared.energies().wall_held, alone.energies().wall_held) << what;
  EXPECT_EQ(shared.energies().inflow, alone.energies().inflow) << what;
  std::cout << what << ", " << shared.slabs().ranks() << " ranks: " << steps << " steps, " << compared
            << " particles compared bit for bit, this rank owns " << shared.owned_count() << " and read at most "
            << most_halo << " in its halo (slab axis " << shared.slab_axis() << "); energy " << shared_energy
            << " J against " << energy << " J alone\n";
  EXPECT_GT(steps, 20);
  return steps;
}

// A column collapsing in a closed box (walls of boundary particles; water; the default
// density diffusion and bounded wall work): the flow moves across the slabs.
Case collapse(double end_time) {
  const double dx = 0.02;
  Case c{water_scene(dx, 20.0), container_walls(Vec3(0, 0, 0), Vec3(0.6, 0.12, 0.3), dx, 3), end_time};
  c.scene.fluids.push_back(box_body("column", Vec3(0, 0, 0), Vec3(0.2, 0.12, 0.2)));
  return c;
}

TEST(SphRanks, DamBreakIsTheSameBitsAsOneModel) {
  compare_runs(collapse(0.15), "dam break");
}

TEST(SphRanks, BinghamSlurryWithTheStrainRateOperator) {
  Case c = collapse(0.05);
  scene::Material& m = c.scene.materials[0];
  m.rheology = scene::Material::Rheology::bingham;
  m.viscosity = 0.5;
  m.yield_stress = 20.0;
  m.yield_shear_rate = 5.0;
  compare_runs(c, "Bingham slurry");
}

TEST(SphRanks, ElasticPlasticColumn) {
  Case c = collapse(0.04);
  scene::Material& m = c.scene.materials[0];
  m.rheology = scene::Material::Rheology::elastic_plastic;
  m.yield_stress = 580;
  m.fluid_shear_modulus = 1e5;
  compare_runs(c, "elastic-plastic column");
}

// Water entering through a section ([[inflows]]: 0.01 m^3/s for 0.1 s, down to 0 at 0.125 s) over the floor of a
// container: the buffer's particles move with their owners, the layers it releases cross the slabs, and the buffer
// is taken out when the hydrograph ends (456 steps, 144 particles released). The container stops at x = 0.6 m
// and z = 0.16 m, beyond where the water gets: its walls are most of the particles (the hydrograph twice as long
// in a container to 0.9 m and 0.3 m: 9 times the time).
TEST(SphRanks, InflowReleasesTheSameParticlesAsOneModel) {
  const double dx = 0.02;
  Case c{water_scene(dx, 20.0), container_walls(Vec3(-0.3, -0.06, 0.0), Vec3(0.6, 0.06, 0.16), dx, 3), 0.14};
  c.scene.run.end_time = 0.15;
  c.scene.sph.wall_model = scene::SphSettings::WallModel::boundary_particles;
  scene::FluidBody body;
  body.name = "upstream";
  body.material = "water";
  body.shape = scene::FluidBody::Shape::inflow;
  body.inflow.position = Vec3(0.0, 0.0, 0.0);
  body.inflow.direction = Vec3(1, 0, 0);
  body.inflow.width = 0.12;
  body.inflow.depth = 0.06;
  body.inflow.hydrograph = {{0.0, 0.01}, {0.1, 0.01}, {0.125, 0.0}};
  c.scene.fluids.push_back(body);
  compare_runs(c, "inflow");
}

TEST(SphRanks, ParticlesLeavingTheDomainAreTakenOutOnce) {
  Case c = collapse(0.2);
  // Open on the right: the domain ends at x = 0.3, where the walls keep going.
  c.scene.sph.domain = Aabb{Vec3(-1, -1, -1), Vec3(0.3, 1, 1)};
  SphModel alone(c.scene), shared(c.scene, world());
  alone.set_boundary(c.walls);
  shared.set_boundary(c.walls);
  double dt_previous = 0;
  for (int step = 0; step < 400; ++step) {
    alone.compute_internal_forces(dt_previous);
    shared.compute_internal_forces(dt_previous);
    alone.integrate(dt_previous, alone.stable_dt());
    shared.integrate(dt_previous, alone.stable_dt());
    dt_previous = alone.stable_dt();
  }
  std::cout << "particles taken out: " << shared.lost_count() << " on ranks, " << alone.lost_count() << " alone\n";
  EXPECT_GT(alone.lost_count(), 0u);
  EXPECT_EQ(shared.lost_count(), alone.lost_count());
}

// Steps a model `steps` times from where it stands.
void advance(SphModel& model, int steps, double& dt_previous) {
  for (int k = 0; k < steps; ++k) {
    model.compute_internal_forces(dt_previous);
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    dt_previous = dt;
  }
}

// A checkpoint of one model continues on ranks, and one of the ranks (written by rank 0 after
// collect_state()) continues alone, both the same bits as the model that never stopped.
TEST(SphRanks, CheckpointsMoveBetweenRankCounts) {
  const Case c = collapse(0.1);
  const auto ranks = world();
  std::vector<double> tag{static_cast<double>(::getpid())};
  ranks->broadcast(tag, 0);  // one file name for every rank: rank 0's pid
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / fmt::format("sabo_sph_ranks_{}.h5", static_cast<long>(tag[0]));
  constexpr int kBefore = 60, kAfter = 60;
  SphModel reference(c.scene);
  reference.set_boundary(c.walls);
  double dt_reference = 0;
  advance(reference, kBefore, dt_reference);
  const double dt_at_checkpoint = dt_reference;
  advance(reference, kAfter, dt_reference);
  const auto same_as_reference = [&](const SphModel::ParticleState& state, const char* what) {
    int differing = 0;
    for (std::size_t i = 0; i < reference.size(); ++i) {
      if (state.active[i] != reference.active()[i] ||
          (reference.active()[i] &&
           (state.position[i] != reference.positions()[i] || state.velocity[i] != reference.velocities()[i] ||
            state.density[i] != reference.densities()[i]))) {
        ++differing;
      }
    }
    std::cout << what << ": " << differing << " of " << reference.size()
              << " particles differ from the run that never stopped (expected 0)\n";
    EXPECT_EQ(differing, 0) << what;
  };

  // One model -> ranks.
  {
    if (ranks->rank() == 0) {
      SphModel alone(c.scene);
      alone.set_boundary(c.walls);
      double dt_previous = 0;
      advance(alone, kBefore, dt_previous);
      io::hdf5::File out = io::hdf5::File::create(file);
      io::hdf5::Group group = out.create_group("model");
      alone.save_state(group);
    }
    std::vector<std::int64_t> barrier{0};
    ranks->sum(barrier);  // the file is written
    SphModel shared(c.scene, ranks);
    shared.set_boundary(c.walls);
    if (ranks->rank() == 0) shared.load_state(io::hdf5::File::open(file).group("model"));
    shared.share_loaded_state();
    double dt_previous = dt_at_checkpoint;
    advance(shared, kAfter, dt_previous);
    same_as_reference(shared.gather_state(), "one model's checkpoint continued on ranks");
  }
  // Ranks -> one model.
  {
    SphModel shared(c.scene, ranks);
    shared.set_boundary(c.walls);
    double dt_previous = 0;
    advance(shared, kBefore, dt_previous);
    shared.collect_state();
    if (ranks->rank() == 0) {
      io::hdf5::File out = io::hdf5::File::create(file);
      io::hdf5::Group group = out.create_group("model");
      shared.save_state(group);
    }
    std::vector<std::int64_t> barrier{0};
    ranks->sum(barrier);
    SphModel alone(c.scene);
    alone.set_boundary(c.walls);
    alone.load_state(io::hdf5::File::open(file).group("model"));
    dt_previous = dt_at_checkpoint;
    advance(alone, kAfter, dt_previous);
    same_as_reference(alone.gather_state(), "the ranks' checkpoint continued by one model");
    ranks->sum(barrier);  // every rank has read it
    if (ranks->rank() == 0) std::filesystem::remove(file);
  }
}

// Gauges and fronts on ranks: the sample at a point is taken by the rank whose slab holds it.
TEST(SphRanks, SamplesAreTheSameBitsAsOneModels) {
  const Case c = collapse(0.1);
  SphModel alone(c.scene), shared(c.scene, world());
  alone.set_boundary(c.walls);
  shared.set_boundary(c.walls);
  double dt_alone = 0, dt_shared = 0;
  advance(alone, 80, dt_alone);
  advance(shared, 80, dt_shared);
  alone.compute_internal_forces(dt_alone);
  shared.compute_internal_forces(dt_shared);
  int points = 0, wet = 0, differing = 0;
  for (double x = -0.05; x <= 0.65; x += 0.037) {
    for (double z = 0.0; z <= 0.3; z += 0.029) {
      const Vec3 point(x, 0.06, z);
      const FluidSample one = alone.sample(point), many = shared.sample_on_ranks(point, false);
      const double sum = shared.sample_on_ranks(point, true).kernel_sum;
      ++points;
      wet += one.kernel_sum > kDryKernelSum ? 1 : 0;
      if (one.kernel_sum != many.kernel_sum || one.pressure != many.pressure || one.velocity != many.velocity ||
          one.linear_fit != many.linear_fit || sum != alone.kernel_sum(point)) {
        ++differing;
      }
    }
  }
  std::cout << "samples at " << points << " points (" << wet << " wet): " << differing
            << " differ from one model's (expected 0)\n";
  EXPECT_GT(wet, 10);
  EXPECT_EQ(differing, 0);
}

// The collapse in a channel periodic across its width (the walls along y taken out): the slabs cut x, and each
// rank makes the images of its window's particles.
TEST(SphRanks, DamBreakPeriodicAcrossTheChannel) {
  Case c = collapse(0.12);
  c.scene.sph.periodic_y = std::array<double, 2>{0.0, 0.12};
  physics::BoundaryParticles walls;
  for (std::size_t b = 0; b < c.walls.size(); ++b) {
    const Vec3& p = c.walls.position[b];
    if (p.y() < 0.0 || p.y() >= 0.12) continue;
    walls.position.push_back(p);
    walls.velocity.push_back(c.walls.velocity[b]);
    walls.normal.push_back(c.walls.normal[b]);
    walls.acceleration.push_back(c.walls.acceleration[b]);
    walls.volume.push_back(c.walls.volume[b]);
  }
  c.walls = walls;
  compare_runs(c, "periodic dam break");
}

// A layer sliding down an infinite slope (gravity tilted 10 degrees), periodic along x and y, started at 0.5 m/s
// along x and 0.2 m/s along y so that particles cross both seams: the slabs cut z.
TEST(SphRanks, LayerSlidingOnAPeriodicSlope) {
  const double dx = 0.02, side = 0.16;
  Case c{water_scene(dx, 20.0, 1.5), {}, 0.1};
  const double theta = 10.0 * std::numbers::pi / 180.0;
  c.scene.run.gravity = Vec3(9.81 * std::sin(theta), 0.0, -9.81 * std::cos(theta));
  c.scene.sph.periodic_x = std::array<double, 2>{0.0, side};
  c.scene.sph.periodic_y = std::array<double, 2>{0.0, side};
  c.scene.fluids.push_back(box_body("layer", Vec3(0, 0, 0), Vec3(side, side, 0.24)));
  c.scene.fluids.back().velocity = Vec3(0.5, 0.2, 0.0);
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 8; ++j) {
      for (int i = 0; i < 8; ++i) {
        c.walls.position.emplace_back((i + 0.5) * dx, (j + 0.5) * dx, -(k + 0.5) * dx);
        c.walls.velocity.push_back(Vec3::Zero());
        c.walls.normal.push_back(Vec3::UnitZ());
        c.walls.acceleration.push_back(Vec3::Zero());
        c.walls.volume.push_back(dx * dx * dx);
      }
    }
  }
  compare_runs(c, "periodic slope");
}

}  // namespace
}  // namespace sabo::sph

int main(int argc, char** argv) {
  sabo::sph::parallel::MpiSession session(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  // Every rank reports (a failure on one rank names it); the exit status is any rank's failure.
  const int failed = RUN_ALL_TESTS();
  std::vector<std::int64_t> any{failed};
  sabo::sph::parallel::MpiRanks().sum(any);
  return any[0] != 0 ? 1 : 0;
}
