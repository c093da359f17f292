// Inflows (sph_solver/inflow.hpp, docs/scene.md [[inflows]]): the hydrograph's discharge and volume, the
// volume released against the integral of Q, the buffer's velocity, the energy account that closes the
// fluid's energy audit, the buffer taken out when the hydrograph ends, and a checkpoint mid-run.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <iostream>
#include <vector>

#include "libsabo/io/hdf5.hpp"
#include "sph_solver/energy_audit.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/scratch.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::container_walls;
using testing::water_scene;

constexpr double kDx = 0.02, kSoundSpeed = 20.0;
constexpr double kWidth = 0.2, kDepth = 0.1;  // m: 10 x 5 particles a layer
// A plateau of 0.03 m^3/s (U = 1.5 m/s through 0.02 m^2) for 0.8 s, then down to 0 at 1 s: 0.027 m^3,
// 67.5 layers.
const std::vector<std::array<double, 2>> kHydrograph{{0.0, 0.03}, {0.8, 0.03}, {1.0, 0.0}};
constexpr double kVolume = 0.03 * 0.8 + 0.5 * 0.03 * 0.2;
constexpr double kEnd = 1.05;  // s, the scene's end
// The run the volume and energy tests measure: the same plateau for 0.4 s, down to 0 at 0.5 s (0.0135 m^3,
// 33.75 layers; Q = 0.015 m^3/s, U = 0.75 m/s, at 0.45 s), the run 0.55 s long: 16 s on this machine, where
// the 1 s hydrograph into a container reaching x = 1.5 m (3 807 steps to 1.05 s) took 60 s.
const std::vector<std::array<double, 2>> kRunHydrograph{{0.0, 0.03}, {0.4, 0.03}, {0.5, 0.0}};
constexpr double kRunVolume = 0.03 * 0.4 + 0.5 * 0.03 * 0.1;
constexpr double kRunEnd = 0.55, kRampTime = 0.45;  // s

scene::InflowSection section(const std::vector<std::array<double, 2>>& hydrograph = kHydrograph) {
  scene::InflowSection s;
  s.position = Vec3(0.0, 0.0, 0.0);
  s.direction = Vec3(1, 0, 0);
  s.width = kWidth;
  s.depth = kDepth;
  s.hydrograph = hydrograph;
  return s;
}

// Water entering at x = 0 over the floor of a container [-0.3, 0.9] x [-0.15, 0.15] x [0, 0.25] m of wall
// particles: the front reaches the far wall at 0.42 s and runs up it.
scene::Scene inflow_scene(const std::vector<std::array<double, 2>>& hydrograph = kHydrograph, double end = kEnd) {
  scene::Scene scene = water_scene(kDx, kSoundSpeed);
  scene.run.end_time = end;
  scene.sph.wall_model = scene::SphSettings::WallModel::boundary_particles;
  scene::FluidBody body;
  body.name = "upstream";
  body.material = "water";
  body.shape = scene::FluidBody::Shape::inflow;
  body.inflow = section(hydrograph);
  scene.fluids.push_back(body);
  return scene;
}

physics::BoundaryParticles walls() {
  return container_walls(Vec3(-0.3, -0.15, 0.0), Vec3(0.9, 0.15, 0.25), kDx, 3);
}

std::size_t count_state(const SphModel& model, ParticleState state) {
  return static_cast<std::size_t>(std::count(model.active().begin(), model.active().end(), state));
}

TEST(InflowSection, DischargeAndVolumeFollowTheLinearHydrograph) {
  const scene::InflowSection s = section();
  EXPECT_DOUBLE_EQ(s.discharge(0.1), 0.03);
  EXPECT_DOUBLE_EQ(s.discharge(0.9), 0.015);
  EXPECT_DOUBLE_EQ(s.discharge(1.0), 0.0);
  EXPECT_DOUBLE_EQ(s.discharge(1.5), 0.0);
  EXPECT_NEAR(s.volume(0.0, 2.0), kVolume, 1e-15);
  EXPECT_NEAR(s.volume(0.7, 0.9), 0.1 * 0.03 + 0.1 * 0.0225, 1e-15);
  EXPECT_EQ(s.up(), Vec3(0, 0, 1));
  EXPECT_EQ(s.across(), Vec3(0, 1, 0));
  scene::SphSettings sph;
  sph.particle_spacing = kDx;
  sph.smoothing_ratio = 1.3;
  const scene::InflowLattice lattice = s.lattice(sph, kEnd);
  EXPECT_EQ(lattice.across, 10u);
  EXPECT_EQ(lattice.up, 5u);
  EXPECT_EQ(lattice.buffer_layers, 4u);  // ceil(2.6) + 1
  EXPECT_NEAR(lattice.area, kWidth * kDepth, 1e-15);
  // The advance 1.35 m is 67.5 layers: the buffer's 4, 68 and one more.
  EXPECT_EQ(lattice.layers, 4u + 68u + 1u);
}

struct InflowRun {
  double released_volume = 0;  // m^3
  double released_mass = 0;    // kg, the particles that are free fluid
  double dissipated = 0;       // J, the audit's at the end
  double inflow_energy = 0;    // J, the account at the end
  double buffer_speed = 0;     // m/s, a buffer particle's speed in the step across kRampTime
  std::size_t buffer_after_end = 0, out_after_end = 0;
};

InflowRun run_inflow() {
  const scene::Scene scene = inflow_scene(kRunHydrograph, kRunEnd);
  SphModel model(scene);
  EnergyAudit audit(model);
  const physics::BoundaryParticles wall_particles = walls();
  InflowRun out;
  double t = 0, dt_previous = 0;
  while (t < kRunEnd) {
    model.set_boundary(wall_particles);
    model.compute_internal_forces(dt_previous);
    audit.before_integrate(model, {}, {});
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    audit.after_integrate(model, dt_previous, dt);
    if (t < kRampTime && t + dt >= kRampTime) {
      for (std::size_t i = 0; i < model.size(); ++i) {
        if (model.active()[i] == kBuffer) out.buffer_speed = model.velocities()[i].norm();
      }
    }
    t += dt;
    dt_previous = dt;
  }
  out.released_volume = model.inflows()[0].released_volume();
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (model.active()[i] == kFree) out.released_mass += model.masses()[i];
  }
  out.dissipated = audit.dissipated();
  out.inflow_energy = model.energies().inflow;
  out.buffer_after_end = count_state(model, kBuffer) + count_state(model, kEntering);
  out.out_after_end = count_state(model, kOut);
  return out;
}

// The run the tests below measure, once.
const InflowRun& inflow_run() {
  static const InflowRun run = run_inflow();
  return run;
}

// Measured: 34 layers released for the hydrograph's 33.75 (0.0136 m^3, +0.74 %), 13.617 kg of water; the buffer
// at 0.7495 m/s across 0.45 s.
TEST(SphInflow, ReleasesTheHydrographsVolumeAtTheSectionsVelocity) {
  const InflowRun& run = inflow_run();
  const double per_particle = 1000.0 * kDx * kDx * kDx;
  std::cout << "released volume " << run.released_volume << " m^3, the hydrograph's " << kRunVolume
            << " m^3 (to within half a layer, " << 0.5 * kWidth * kDepth * kDx << " m^3, and 1 %); released mass "
            << run.released_mass << " kg, at least rho0 V = " << 1000.0 * kRunVolume << " kg less a particle's "
            << per_particle << " kg, at most 1 % above it\n";
  EXPECT_NEAR(run.released_volume, kRunVolume, 0.5 * kWidth * kDepth * kDx + 1e-12);
  EXPECT_NEAR(run.released_volume / kRunVolume, 1.0, 0.01);
  // Hydrostatic densities: a little above rho0 (every particle's mass is its lattice cell at its density).
  EXPECT_GT(run.released_mass, 1000.0 * kRunVolume - per_particle);
  EXPECT_LT(run.released_mass, 1000.0 * kRunVolume * 1.01);
  const double discharge = section(kRunHydrograph).discharge(kRampTime);
  std::cout << "buffer speed across t = " << kRampTime << " s: " << run.buffer_speed << " m/s, Q / A there "
            << discharge / (kWidth * kDepth) << " m/s (to the step's midpoint; held to 0.01 m/s)\n";
  EXPECT_NEAR(run.buffer_speed, discharge / (kWidth * kDepth), 0.01);
  std::cout << "after the hydrograph's end: " << run.buffer_after_end << " particles in the buffer, "
            << run.out_after_end << " out\n";
  EXPECT_EQ(run.buffer_after_end, 0u);
}

TEST(SphInflow, TheInflowAccountClosesTheEnergyAudit) {
  // What the audit holds is what the fluid lost beyond the work done on it: viscosity, the walls, the
  // time integration. Without the account of the buffer's work it would be about -inflow (energy from
  // nowhere); with it, small and not below 0 by more than the integration's error. Measured: 4.99 J of the
  // account's 24.1 J (20.7 %; 31.4 % of 49.1 J with the 1 s hydrograph, which hit the far wall at 0.72 s).
  const InflowRun& run = inflow_run();
  std::cout << "inflow account " << run.inflow_energy << " J, the audit's dissipated " << run.dissipated << " J ("
            << 100.0 * run.dissipated / run.inflow_energy << " % of it)\n";
  EXPECT_GT(run.inflow_energy, 0.0);
  EXPECT_GT(run.dissipated, -0.01 * run.inflow_energy);
  EXPECT_LT(run.dissipated, 0.5 * run.inflow_energy);
}

TEST(SphInflow, AJetInEmptySpaceLosesNothing) {
  // Without gravity and walls the fluid leaves the section as a jet at the speed it had there, and the
  // buffer slows with the hydrograph: nothing dissipates, so the audit must hold (almost) nothing while the
  // account holds the jet's kinetic energy; the buffer taken out at the end takes its energy with it.
  scene::Scene scene = inflow_scene();
  scene.run.gravity = Vec3::Zero();
  scene.run.end_time = 0.3;
  scene.fluids[0].inflow.hydrograph = {{0.0, 0.03}, {0.2, 0.015}, {0.25, 0.0}};
  double t = 0, dt_previous = 0;
  SphModel jet(scene);
  EnergyAudit jet_audit(jet);
  while (t < 0.3) {
    jet.compute_internal_forces(dt_previous);
    jet_audit.before_integrate(jet, {}, {});
    const double dt = jet.stable_dt();
    jet.integrate(dt_previous, dt);
    jet_audit.after_integrate(jet, dt_previous, dt);
    t += dt;
    dt_previous = dt;
  }
  double kinetic = 0;
  for (std::size_t i = 0; i < jet.size(); ++i) {
    if (jet.active()[i] == kFree) kinetic += 0.5 * jet.masses()[i] * jet.velocities()[i].squaredNorm();
  }
  std::cout << "jet: kinetic energy " << kinetic << " J, inflow account " << jet.energies().inflow
            << " J, the audit's dissipated " << jet_audit.dissipated() << " J\n";
  EXPECT_EQ(count_state(jet, kBuffer) + count_state(jet, kEntering), 0u);
  EXPECT_NEAR(jet.energies().total(), kinetic, 0.01 * kinetic);
  EXPECT_NEAR(jet_audit.dissipated(), 0.0, 1e-3 * jet.energies().inflow);
}

std::vector<double> state_bits(const SphModel& model) {
  std::vector<double> values;
  for (std::size_t i = 0; i < model.size(); ++i) {
    values.insert(values.end(), {model.positions()[i].x(), model.positions()[i].y(), model.positions()[i].z(),
                                 model.velocities()[i].x(), model.velocities()[i].y(), model.velocities()[i].z(),
                                 model.densities()[i], static_cast<double>(model.active()[i])});
  }
  values.push_back(model.energies().inflow);
  return values;
}

TEST(SphInflow, ACheckpointMidRunContinuesWithTheSameBits) {
  const scene::Scene scene = inflow_scene();
  const physics::BoundaryParticles wall_particles = walls();
  const auto step = [&](SphModel& model, double dt_previous) {
    model.set_boundary(wall_particles);
    model.compute_internal_forces(dt_previous);
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    return dt;
  };
  SphModel uninterrupted(scene);
  double dt_previous = 0;
  for (int n = 0; n < 300; ++n) dt_previous = step(uninterrupted, dt_previous);
  const auto file = sabo::testing::scratch("sph_inflow_checkpoint.h5");
  {
    auto out = io::hdf5::File::create(file);
    uninterrupted.save_state(out);
  }
  const double dt_at_checkpoint = dt_previous;
  for (int n = 0; n < 300; ++n) dt_previous = step(uninterrupted, dt_previous);

  SphModel restarted(scene);
  restarted.load_state(io::hdf5::File::open(file));
  dt_previous = dt_at_checkpoint;
  for (int n = 0; n < 300; ++n) dt_previous = step(restarted, dt_previous);
  const std::vector<double> a = state_bits(uninterrupted), b = state_bits(restarted);
  std::cout << "released layers " << uninterrupted.inflows()[0].released << " and " << restarted.inflows()[0].released
            << "\n";
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0) << "the restarted run differs";
  EXPECT_GT(uninterrupted.inflows()[0].released, 5u);
}

}  // namespace
}  // namespace sabo::sph
