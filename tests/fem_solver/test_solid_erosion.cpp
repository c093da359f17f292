// Erosion: a cantilever loaded past failure breaks where the strain peaks
// (the root's tension fibre); the exterior surface then holds the faces the
// eroded elements exposed, and the FEM model hands the coupler a new topology.
#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <set>

#include "fem_solver/fem_model.hpp"
#include "fem_solver/solid_body.hpp"
#include "tests/fem_solver/fem_test_support.hpp"

using sabo::Aabb;
using sabo::Vec3;
using namespace sabo::fem;

namespace {

MaterialParameters brittle_steel() {
  MaterialParameters m = test::steel();
  m.failure_principal_strain = 1e-3;
  return m;
}

}  // namespace

// One-point elements, 4 through the depth; enhanced-strain ones (no hourglass
// share, accurate in bending with fewer), 2 through the depth.
struct ErodedBeam {
  HexFormulation formulation;
  std::size_t section;
};

class SolidErosion : public ::testing::TestWithParam<ErodedBeam> {};

TEST_P(SolidErosion, CantileverBreaksAtTheRootTensionFibre) {
  const double length = 1.0, side = 0.05;
  const std::size_t section = GetParam().section;
  SolidBody body(structured_box(Aabb{Vec3(0, 0, 0), Vec3(length, side, side)}, {20, section, section}), brittle_steel(),
                 GetParam().formulation);
  // Beam-theory clamp (as in test_solid_elastic.cpp): the root section stays
  // plane, held at its centre lines.
  body.fix_in_box(Aabb{Vec3(-1e-9, -1, -1), Vec3(1e-9, 1, 1)}, dof_x);
  body.fix_in_box(Aabb{Vec3(-1e-9, -1, side / 2 - 1e-9), Vec3(1e-9, 1, side / 2 + 1e-9)}, dof_z);
  body.fix_in_box(Aabb{Vec3(-1e-9, side / 2 - 1e-9, -1), Vec3(1e-9, side / 2 + 1e-9, 1)}, dof_y);
  // 10 kN down at the tip: the static root strain F L (h/2) / (E I) = 2.3e-3 exceeds 1e-3.
  std::vector<Vec3> load(body.node_count(), Vec3::Zero());
  std::size_t tip = 0;
  for (std::size_t i = 0; i < body.node_count(); ++i) tip += body.reference_positions()[i].x() > length - 1e-9;
  for (std::size_t i = 0; i < body.node_count(); ++i) {
    if (body.reference_positions()[i].x() > length - 1e-9) load[i] = Vec3(0, 0, -1e4 / static_cast<double>(tip));
  }
  const double mass = body.total_mass();
  const double dt = 0.9 * body.stable_dt();
  double dt_previous = 0;
  std::size_t first_failed = body.element_count();
  std::vector<std::uint8_t> before;
  test::HourglassMonitor hourglass;
  for (int n = 0; n < 40000 && first_failed == body.element_count(); ++n) {
    before.assign(body.active().begin(), body.active().end());
    body.compute_internal_forces(dt_previous);
    hourglass.observe(body.energies());
    for (std::size_t e = 0; e < body.element_count(); ++e) {
      if (body.eroded(e)) {
        first_failed = e;
        break;
      }
    }
    body.integrate(dt_previous, dt, load);
    dt_previous = dt;
  }
  ASSERT_LT(first_failed, body.element_count()) << "no element failed";
  Vec3 centre = Vec3::Zero();
  for (auto n : body.mesh().element[first_failed]) centre += body.reference_positions()[n] / 8.0;
  std::cout << "first eroded element centre: measured (" << centre.transpose()
            << ") expected x < 0.05 m (root), z > 0.025 m (tension fibre)\n";
  EXPECT_LT(centre.x(), 0.05);
  EXPECT_GT(centre.z(), side / 2);
  // One-point: 4 elements through the depth keep the stabilised share of the
  // bending energy small (test_solid_elastic.cpp); enhanced strain: none.
  std::cout << "hourglass/internal energy up to the failure: measured " << hourglass.worst() << " limit 0.1\n";
  EXPECT_LT(hourglass.worst(), 0.1);
  EXPECT_DOUBLE_EQ(body.total_mass(), mass);  // nodes keep their mass
  EXPECT_GT(body.topology_revision(), 0u);
  // The faces the eroded elements exposed are now exterior.
  const auto old_faces = exterior_faces(body.mesh(), before);
  const auto new_faces = exterior_faces(body.mesh(), body.active());
  std::set<std::array<std::uint32_t, 4>> old_set;
  for (const auto& f : old_faces) {
    auto key = f.node;
    std::sort(key.begin(), key.end());
    old_set.insert(key);
  }
  std::size_t exposed = 0;
  for (const auto& f : new_faces) {
    auto key = f.node;
    std::sort(key.begin(), key.end());
    if (!old_set.count(key)) ++exposed;
    EXPECT_FALSE(body.eroded(f.element));
  }
  std::cout << "faces exposed by the erosion: " << exposed << " (expected > 0)\n";
  EXPECT_GT(exposed, 0u);
}

INSTANTIATE_TEST_SUITE_P(Formulations, SolidErosion,
                         ::testing::Values(ErodedBeam{HexFormulation::one_point, 4},
                                           ErodedBeam{HexFormulation::enhanced_strain, 2}));

TEST(FemModelErosion, NewTopologyReachesTheCombinedSurface) {
  sabo::scene::Scene scene;
  sabo::scene::Material steel = test::scene_steel();
  steel.failure_strain = 1e-3;
  scene.materials.push_back(steel);
  sabo::scene::Structure bar = test::deformable_structure("bar", "steel");
  bar.shape = test::box_shape(Aabb{Vec3(0, 0, 0), Vec3(0.4, 0.1, 0.1)}, 0.1);
  bar.fixed_faces = {"x-"};
  bar.velocity = Vec3(0, 0, 0);
  scene.structures.push_back(bar);
  scene.run.gravity = Vec3::Zero();
  FemModel model(scene);
  const std::size_t faces_before = model.surface().face_count();
  EXPECT_EQ(faces_before, 2u * (4 * 4 + 2));  // 4 x 1 x 1 hexahedra: 18 quads
  EXPECT_TRUE(model.moved());
  // Pull the free end hard through the surface node forces until an element fails.
  const auto& surface = model.surface();
  std::vector<double> force(3 * surface.node_count(), 0.0);
  for (std::size_t i = 0; i < surface.node_count(); ++i) {
    if (surface.node_position[i].x() > 0.4 - 1e-9) force[3 * i] = 5e6;
  }
  bool changed = false;
  double dt_previous = 0;
  for (int n = 0; n < 5000 && !changed; ++n) {
    model.compute_internal_forces(dt_previous);
    model.apply_node_forces(force);
    const double dt = 0.9 * model.stable_dt();
    model.step(dt);
    dt_previous = dt;
    changed = model.update_surface();
  }
  ASSERT_TRUE(changed) << "no element eroded";
  std::cout << "surface faces: before " << faces_before << ", after erosion " << model.surface().face_count()
            << ", revision " << model.surface_revision() << "\n";
  EXPECT_EQ(model.surface_revision(), 1u);
  EXPECT_NE(model.surface().face_count(), faces_before);
  model.surface().validate("eroded surface");
}
