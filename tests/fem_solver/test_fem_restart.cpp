// Restart of deformable state: a FemModel restored from a checkpoint (solid
// and shell parts, plastic, eroding) continues with the same bits as the run
// that wrote it: node positions and velocities, stresses, back stresses,
// plastic strains, eroded flags, energies and the surface.
#include <gtest/gtest.h>

#include <cstring>
#include <iostream>
#include <vector>

#include "fem_solver/fem_model.hpp"
#include "libsabo/core/error.hpp"
#include "tests/fem_solver/fem_test_support.hpp"
#include "tests/support/scratch.hpp"

using sabo::Vec3;
using sabo::fem::FemModel;

namespace {

using Formulation = sabo::scene::Structure::ElementFormulation;

sabo::scene::Scene restart_scene(Formulation formulation = Formulation::one_point) {
  sabo::scene::Scene scene;
  sabo::scene::Material steel = sabo::fem::test::scene_steel();
  steel.yield_stress = 100e6;
  steel.tangent_modulus = 1e9;
  steel.hardening = 0.5;  // mixed: back stresses and a growing yield surface
  steel.failure_strain = 6e-3;
  scene.materials.push_back(steel);
  sabo::scene::Structure bar = sabo::fem::test::deformable_structure("bar", "steel");
  bar.shape = sabo::fem::test::box_shape(sabo::Aabb{Vec3(0, 0, 0), Vec3(0.4, 0.1, 0.1)}, 0.05);
  bar.fixed_faces = {"x-"};
  bar.element_formulation = formulation;
  scene.structures.push_back(bar);
  sabo::scene::Structure panel = bar;
  panel.name = "panel";
  panel.thickness = 0.01;
  panel.element_formulation = formulation;
  panel.shape = sabo::fem::test::plane_shape(Vec3(0.5, 0.25, 1.0), Vec3(0, 0, 1), Vec3(1, 0, 0), 1.0, 0.5, 0.125);
  scene.structures.push_back(panel);
  scene.run.gravity = Vec3(0, 0, -9.81);
  return scene;
}

// The free ends pulled along x and pushed down: yield, then erosion.
std::vector<double> end_load(const FemModel& model) {
  const auto& surface = model.surface();
  std::vector<double> force(3 * surface.node_count(), 0.0);
  for (std::size_t i = 0; i < surface.node_count(); ++i) {
    const Vec3& p = surface.node_position[i];
    const bool bar_end = p.z() < 0.5 && p.x() > 0.4 - 1e-6;
    const bool panel_end = p.z() > 0.5 && p.x() > 1.0 - 1e-6;
    if (bar_end) force[3 * i] = 1.25e5;
    if (panel_end) force[3 * i] = 1.15e5;
    if (bar_end || panel_end) force[3 * i + 2] = -200;
  }
  return force;
}

struct Snapshot {
  std::vector<double> values;
  std::vector<std::uint8_t> active;
  std::uint64_t revision = 0;
  std::size_t eroded = 0;
  double plastic_work = 0;
};

// with_surface: also the surface's node positions and velocities (brought to
// x_n by update_surface() at the next step: after step() they lag a step).
Snapshot snapshot(const FemModel& model, bool with_surface = true) {
  Snapshot s;
  for (std::size_t index = 0; index < model.part_count(); ++index) {
    const auto* part = model.deformable(index);
    const sabo::fem::BodyState state = part->save_state();
    s.values.insert(s.values.end(), state.real.begin(), state.real.end());
    s.active.insert(s.active.end(), state.active.begin(), state.active.end());
    s.eroded += part->eroded_count();
    s.plastic_work += part->solid_energies().plastic_work;
    const auto e = part->energies();
    for (double v : {e.kinetic, e.potential, e.elastic, e.dissipated}) s.values.push_back(v);
  }
  if (with_surface) {
    for (const Vec3& p : model.surface().node_position) {
      for (int d = 0; d < 3; ++d) s.values.push_back(p(d));
    }
    for (const Vec3& v : model.node_velocities()) {
      for (int d = 0; d < 3; ++d) s.values.push_back(v(d));
    }
  }
  s.values.push_back(model.time());
  s.revision = model.surface_revision();
  return s;
}

// One step of the fem_solver's cycle (solver/driver.hpp) under the end load.
double advance(FemModel& model, double dt_previous) {
  model.compute_internal_forces(dt_previous);
  model.update_surface();
  model.apply_node_forces(end_load(model));
  const double dt = 0.9 * model.stable_dt();
  model.step(dt);
  return dt;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

}  // namespace

namespace {

void check_restart(Formulation formulation, const std::string& name) {
  // The loaded end elements yield from the first steps and erode at steps 30-40.
  constexpr int kBefore = 25, kAfter = 300;
  const auto file = sabo::testing::scratch(name);
  FemModel uninterrupted(restart_scene(formulation));
  double dt_previous = 0;
  for (int n = 0; n < kBefore; ++n) dt_previous = advance(uninterrupted, dt_previous);
  {
    auto out = sabo::io::hdf5::File::create(file);
    uninterrupted.save_state(out);
  }
  const Snapshot at_checkpoint = snapshot(uninterrupted, false);
  const double dt_at_checkpoint = dt_previous;
  for (int n = 0; n < kAfter; ++n) dt_previous = advance(uninterrupted, dt_previous);
  const Snapshot expected = snapshot(uninterrupted);

  FemModel restarted(restart_scene(formulation));
  restarted.load_state(sabo::io::hdf5::File::open(file));
  const Snapshot restored = snapshot(restarted, false);
  EXPECT_TRUE(same_bits(restored.values, at_checkpoint.values)) << "the restored state differs from the saved one";
  EXPECT_EQ(restored.active, at_checkpoint.active);
  dt_previous = dt_at_checkpoint;
  for (int n = 0; n < kAfter; ++n) dt_previous = advance(restarted, dt_previous);
  const Snapshot measured = snapshot(restarted);

  std::cout << "at the checkpoint: plastic work " << at_checkpoint.plastic_work << " J, eroded elements "
            << at_checkpoint.eroded << "; at the end: plastic work " << expected.plastic_work << " J, eroded "
            << expected.eroded << ", surface revision " << expected.revision << "\n";
  EXPECT_GT(at_checkpoint.plastic_work, 0.0) << "the checkpoint should hold plastic state";
  EXPECT_GT(expected.eroded, at_checkpoint.eroded) << "erosion should continue after the restart";
  std::cout << "restarted vs uninterrupted: " << measured.values.size() << " values compared bit for bit, "
            << (same_bits(measured.values, expected.values) ? "identical" : "DIFFERENT") << "\n";
  EXPECT_TRUE(same_bits(measured.values, expected.values));
  EXPECT_EQ(measured.active, expected.active);
  EXPECT_EQ(measured.revision, expected.revision);
  EXPECT_EQ(restarted.surface().face_count(), uninterrupted.surface().face_count());
}

}  // namespace

TEST(FemRestart, RestoredModelContinuesWithTheSameBits) {
  check_restart(Formulation::one_point, "checkpoint_fem.h5");
}

// The fully integrated hexahedra's eight material histories per element travel
// too, and the fully integrated shells' Gauss-point histories.
TEST(FemRestart, FullyIntegratedRestoredModelContinuesWithTheSameBits) {
  check_restart(Formulation::fully_integrated, "checkpoint_fem_full.h5");
}

TEST(FemRestart, EnhancedStrainRestoredModelContinuesWithTheSameBits) {
  check_restart(Formulation::enhanced_strain, "checkpoint_fem_enhanced.h5");
}

TEST(FemRestart, CheckpointOfAnotherSceneIsRefused) {
  const auto file = sabo::testing::scratch("checkpoint_other.h5");
  FemModel model(restart_scene());
  {
    auto out = sabo::io::hdf5::File::create(file);
    model.save_state(out);
  }
  sabo::scene::Scene other = restart_scene();
  other.structures[0].shape.element_size = 0.1;  // a coarser bar
  FemModel coarse(other);
  try {
    coarse.load_state(sabo::io::hdf5::File::open(file));
    ADD_FAILURE() << "no exception";
  } catch (const sabo::FileError& error) {
    const std::string text = error.what();
    std::cout << text << "\n";
    EXPECT_NE(text.find("part 'bar'"), std::string::npos) << text;
    EXPECT_NE(text.find("Fix:"), std::string::npos) << text;
  }
}
