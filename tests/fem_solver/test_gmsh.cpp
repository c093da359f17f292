// Deformable structures from Gmsh msh 4.1 ASCII files (the reader itself:
// tests/libsabo/io/test_gmsh.cpp): solids of hexahedra and shells of quadrangles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include "fem_solver/fem_model.hpp"
#include "libsabo/core/error.hpp"
#include "tests/fem_solver/fem_test_support.hpp"

using sabo::fem::test::deformable_structure;
using sabo::fem::test::scene_steel;

namespace {
std::filesystem::path data(const char* name) {
  return std::filesystem::path(SABO_SOURCE_DIR) / "tests/libsabo/io/data" / name;
}
}  // namespace

TEST(Gmsh, DeformableStructureFromAMshFile) {
  sabo::scene::Scene scene;
  scene.materials.push_back(scene_steel());
  sabo::scene::Structure block = deformable_structure("block", "steel");
  block.shape.type = sabo::scene::Shape::Type::mesh;
  block.shape.file = data("two_hexes.msh");
  block.shape.scale = 2.0;
  block.fixed_faces = {"z-"};
  scene.structures.push_back(block);
  sabo::fem::FemModel model(scene);
  EXPECT_EQ(model.surface().face_count(), 20u);  // 10 exterior quads
  EXPECT_FALSE(model.deformable(0)->is_shell());
  EXPECT_NEAR(model.deformable(0)->solid()->total_mass(), 7850 * 2 * 8.0, 1e-6);
  scene.structures[0].shape.file = data("broken_node_tag.msh");
  EXPECT_THROW(sabo::fem::FemModel broken(scene), sabo::FileError);
}

// Shells from a .msh file of quadrangles (tests/libsabo/io/data/shell_strip.msh:
// the strip 1 m x 0.1 m of Shell.CantileverTipDeflectionAgainstBeamTheory, 20 x
// 2 quads, thickness from the structure) move exactly as the same strip
// generated from a plane panel: same mass, and the same tip history under a
// tip load with the root clamped.
TEST(Gmsh, ShellStripFromAMshFileMatchesTheGeneratedPanel) {
  auto make_scene = [](bool from_file) {
    sabo::scene::Scene scene;
    scene.materials.push_back(scene_steel());
    sabo::scene::Structure strip = deformable_structure("strip", "steel");
    strip.thickness = 0.01;
    if (from_file) {
      strip.shape.type = sabo::scene::Shape::Type::mesh;
      strip.shape.file = data("shell_strip.msh");
    } else {
      strip.shape = sabo::fem::test::plane_shape(sabo::Vec3(0.5, 0.05, 0), sabo::Vec3(0, 0, 1), sabo::Vec3(1, 0, 0),
                                                 1.0, 0.1, 0.05);
    }
    strip.fixed_faces = {"x-"};
    scene.structures.push_back(strip);
    scene.run.gravity = sabo::Vec3::Zero();
    return scene;
  };
  sabo::fem::FemModel from_file(make_scene(true)), generated(make_scene(false));
  const auto* file_shell = from_file.deformable(0)->shell();
  const auto* generated_shell = generated.deformable(0)->shell();
  ASSERT_NE(file_shell, nullptr);
  ASSERT_NE(generated_shell, nullptr);
  EXPECT_EQ(file_shell->element_count(), 40u);
  EXPECT_EQ(file_shell->element_count(), generated_shell->element_count());
  EXPECT_NEAR(file_shell->total_mass(), generated_shell->total_mass(), 1e-12 * generated_shell->total_mass());
  EXPECT_NEAR(file_shell->total_mass(), 7850 * 1.0 * 0.1 * 0.01, 1e-9);
  for (double t : from_file.surface().face_thickness) EXPECT_EQ(t, 0.01);

  // 10 N down at the tip, spread over its three nodes.
  auto tip_load = [](const sabo::fem::FemModel& model) {
    const auto& surface = model.surface();
    std::vector<double> force(3 * surface.node_count(), 0.0);
    for (std::size_t i = 0; i < surface.node_count(); ++i) {
      const sabo::Vec3& p = surface.node_position[i];
      if (p.x() > 1.0 - 1e-9) force[3 * i + 2] = -10.0 * ((p.y() < 1e-9 || p.y() > 0.1 - 1e-9) ? 0.25 : 0.5);
    }
    return force;
  };
  auto tip_nodes = [](const sabo::fem::FemModel& model) {
    std::vector<std::size_t> tip;
    for (std::size_t i = 0; i < model.surface().node_count(); ++i) {
      if (model.surface().node_position[i].x() > 1.0 - 1e-9) tip.push_back(i);
    }
    return tip;
  };
  auto tip_deflection = [](const sabo::fem::FemModel& model, const std::vector<std::size_t>& tip) {
    double sum = 0;
    for (auto i : tip) sum -= model.surface().node_position[i].z();
    return sum / static_cast<double>(tip.size());
  };
  const auto file_tip = tip_nodes(from_file), generated_tip = tip_nodes(generated);
  ASSERT_EQ(file_tip.size(), 3u);
  ASSERT_EQ(generated_tip.size(), 3u);
  const auto file_load = tip_load(from_file), generated_load = tip_load(generated);
  double dt_previous = 0, largest = 0, worst_difference = 0;
  for (int n = 0; n < 3000; ++n) {
    from_file.compute_internal_forces(dt_previous);
    generated.compute_internal_forces(dt_previous);
    from_file.update_surface();
    generated.update_surface();
    from_file.apply_node_forces(file_load);
    generated.apply_node_forces(generated_load);
    const double dt = 0.9 * std::min(from_file.stable_dt(), generated.stable_dt());
    from_file.step(dt);
    generated.step(dt);
    dt_previous = dt;
    const double a = tip_deflection(from_file, file_tip), b = tip_deflection(generated, generated_tip);
    largest = std::max(largest, std::abs(b));
    worst_difference = std::max(worst_difference, std::abs(a - b));
  }
  std::cout << "tip deflection history, .msh vs generated: largest difference " << worst_difference
            << " m of a largest deflection " << largest << " m (expected below 1e-9 of it)\n";
  EXPECT_GT(largest, 1e-4);
  EXPECT_LT(worst_difference, 1e-9 * largest);
}
