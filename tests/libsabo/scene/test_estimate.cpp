// The estimate of what a scene costs (libsabo/scene/estimate.hpp) against what the builders make of the
// test scenes: the fluid lattice, the triangulated surfaces and the coupler's wall particles; and its
// bounds, which must hold whatever the scene (the coupler refuses frames above them).
#include <gtest/gtest.h>

#include <iostream>

#include "libsabo/geometry/primitives.hpp"
#include "libsabo/geometry/surface_sampling.hpp"
#include "libsabo/scene/estimate.hpp"
#include "libsabo/scene/loader.hpp"
#include "scene_test_support.hpp"

namespace sabo::scene {
namespace {

Scene load(const char* relative) {
  return load_scene(testing::source_dir() / relative);
}

// The tank of configs/tests/sph_tank_boundary.toml: 0.4 x 0.4 x 0.3 m at dx = 0.05 m, 8 x 8 x 6 particles.
TEST(SceneEstimate, FluidLatticeOfTheTank) {
  const SceneEstimate e = estimate_scene(load("configs/tests/sph_tank_boundary.toml"));
  std::cout << "fluid particles: " << e.total_fluid_particles() << " (expected 384), bound " << e.fluid_particles_bound
            << "\n";
  EXPECT_EQ(e.total_fluid_particles(), 384.0);
  EXPECT_GE(e.fluid_particles_bound, 384.0);
}

// Rigid surfaces: the estimate's triangles are geometry::triangulate's; the coupler's wall particles (each
// structure sampled on its own) within a factor 1.5 of the estimate and below its bound.
TEST(SceneEstimate, SurfacesAndWallParticlesOfTheTestScenes) {
  for (const char* relative : {"configs/tests/sph_tank_boundary.toml", "configs/sph_dam_break.toml",
                               "configs/tests/chute_small.toml", "configs/boulders_chute.toml"}) {
    SCOPED_TRACE(relative);
    const Scene scene = load(relative);
    const SceneEstimate e = estimate_scene(scene);
    double walls = 0, triangles = 0;
    const double dx = scene.sph.particle_spacing;
    for (std::size_t k = 0; k < scene.structures.size(); ++k) {
      const auto mesh = geometry::triangulate(scene.structures[k].shape, scene.structures[k].name);
      triangles += static_cast<double>(mesh.triangle.size());
      EXPECT_EQ(e.surface_triangles[k], static_cast<double>(mesh.triangle.size())) << scene.structures[k].name;
      if (dx > 0) {
        const auto layers = static_cast<std::size_t>(std::ceil(scene.sph.kernel_support() / dx - 1e-9));
        walls += static_cast<double>(geometry::sample_surface(mesh, dx, layers).size());
      }
    }
    std::cout << relative << ": " << triangles << " triangles; wall particles " << walls << " sampled, "
              << e.wall_particles << " estimated, bound " << e.wall_particles_bound << "\n";
    if (walls > 0) {
      EXPECT_GT(e.wall_particles, walls / 1.5);
      EXPECT_LT(e.wall_particles, walls * 1.5);
      EXPECT_GE(e.wall_particles_bound, walls);
    }
  }
}

// The FEM: hexahedra and shells of the reduced debris flow (a dam of 2 x 4 x 3 one-metre hexahedra and a
// house of five 3 m shells), its step the dam's; steps and memory within what the scene check allows.
TEST(SceneEstimate, ElementsAndStepOfTheDebrisFlow) {
  const Scene scene = load("configs/tests/debris_flow_dam_small.toml");
  const SceneEstimate e = estimate_scene(scene);
  std::cout << "elements " << e.total_elements() << " (expected 29), dt " << e.dt << " s (" << e.dt_what << "), "
            << e.steps << " steps, " << e.memory_bytes / 1e6 << " MB, largest message at most "
            << e.largest_message_bound << " B\n";
  EXPECT_EQ(e.total_elements(), 29.0);
  EXPECT_NE(e.dt_what.find("fem_solver"), std::string::npos);
  EXPECT_LT(e.steps, kMaxSteps);
  EXPECT_LT(e.memory_bytes, physical_memory_bytes());
  EXPECT_GT(max_message_bytes(e), 2 * e.largest_message_bound);
}

}  // namespace
}  // namespace sabo::scene
