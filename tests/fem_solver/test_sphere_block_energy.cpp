// Energy balance of a sphere striking a deformable hexahedral block through the
// coupler's penalty contact (SurfaceContact), stepped in one loop the way the
// coupler steps the solvers: at step n both sides get the contact forces of
// x_n and advance to x_{n+1}. The scene is configs/tests/sphere_on_block.toml
// with the stiff penalty scale k1 = 1.0 (docs/physics.md, FEM, "coupling").
// Before the fix the plastic block's total rose 25 %: two faces of the dent
// passing the smooth angle added a second full-stiffness contact at once, and
// the face stiffness followed the deformed face area.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <numbers>
#include <sstream>
#include <vector>

#include "fem_solver/fem_model.hpp"
#include "libsabo/contact/surface_contact.hpp"
#include "tests/fem_solver/fem_test_support.hpp"

using sabo::Vec3;

namespace {

using Formulation = sabo::scene::Structure::ElementFormulation;

sabo::scene::Scene block_scene(double element_size, bool plastic, Formulation formulation) {
  sabo::scene::Scene scene;
  sabo::scene::Material concrete = sabo::fem::test::scene_material("soft_concrete", 2000, 1e9, 0.3);
  if (plastic) {
    concrete.yield_stress = 5e6;
    concrete.tangent_modulus = 1e8;
    concrete.hardening = 1.0;
  }
  scene.materials.push_back(concrete);
  sabo::scene::Structure block = sabo::fem::test::deformable_structure("block", "soft_concrete");
  block.shape = sabo::fem::test::box_shape(sabo::Aabb{Vec3(0, 0, 0), Vec3(1, 1, 0.5)}, element_size);
  block.fixed_faces = {"z-"};
  block.element_formulation = formulation;
  scene.structures.push_back(block);
  scene.run.gravity = Vec3::Zero();
  return scene;
}

struct ImpactResult {
  double initial = 0;                // J
  double largest = 0;                // J, largest total energy over the run
  double final_total = 0;            // J
  double rebound_speed = 0;          // m/s
  double plastic_work = 0;           // J, at the end
  double deepest = 0;                // m, largest depth of the sphere's lowest point below the block's top (z = 0.5)
  double worst_hourglass_share = 0;  // largest hourglass / internal energy once internal > 1 % of the impact energy
};

// Sphere r = 0.25 m, 196 kg (granite), 10 m/s down onto the block's top; 0.07 s.
// dt_factor: of the block's stable step (cubic elements need less than 0.9,
// docs/physics.md "FEM solids"); the run's max_dt bounds the step too.
ImpactResult impact(double penalty_scale, double element_size, bool plastic,
                    Formulation formulation = Formulation::one_point, double dt_factor = 0.9) {
  const double max_dt = 5e-5;  // s, the scene's run.max_dt
  sabo::fem::FemModel model(block_scene(element_size, plastic, formulation));
  sabo::scene::SurfaceContact settings;
  settings.friction = 0.0;
  settings.penalty_scale = penalty_scale;
  sabo::contact::SurfaceContact contact({"sphere"}, [&](const std::string&, const std::string&) { return settings; });
  contact.set_surface(model.surface());

  const double radius = 0.25, density = 3000;
  const double mass = density * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  Vec3 centre(0.5, 0.5, 0.8), velocity(0, 0, -10.0);
  std::vector<std::uint64_t> id{1};
  std::vector<double> position(3), vel(3), angular(3, 0.0), radii{radius}, masses{mass};

  ImpactResult result;
  result.initial = 0.5 * mass * velocity.squaredNorm();
  result.largest = result.initial;
  double dt_previous = 0, t = 0;
  sabo::contact::ContactOutput out;
  std::vector<double> node_position, node_velocity;
  std::uint64_t step = 0;
  while (t < 0.07) {
    // As fem_solver's fill_state(): the surface nodes at x_n (and a new topology, none here).
    if (model.update_surface()) contact.set_surface(model.surface());
    model.compute_internal_forces(dt_previous);
    const auto& surface = model.surface();
    node_position.assign(3 * surface.node_count(), 0.0);
    node_velocity.assign(3 * surface.node_count(), 0.0);
    for (std::size_t i = 0; i < surface.node_count(); ++i) {
      for (int d = 0; d < 3; ++d) {
        node_position[3 * i + static_cast<std::size_t>(d)] = surface.node_position[i](d);
        node_velocity[3 * i + static_cast<std::size_t>(d)] = model.node_velocities()[i](d);
      }
    }
    contact.update_nodes(node_position, node_velocity);
    for (int d = 0; d < 3; ++d) {
      position[static_cast<std::size_t>(d)] = centre(d);
      vel[static_cast<std::size_t>(d)] = velocity(d);
    }
    const sabo::contact::ParticleView view{id, position, vel, angular, radii, masses, {}, {}};
    contact.compute(view, dt_previous, out);
    model.apply_node_forces(out.node_force);
    const double dt = std::min({dt_factor * model.stable_dt(), contact.stable_dt(), max_dt});
    // The sphere as dem_solver steps it: v_{n+1/2} = v_{n-1/2} + dt_avg F_n / m.
    const Vec3 force(out.particle_force[0], out.particle_force[1], out.particle_force[2]);
    const Vec3 old_velocity = velocity;
    velocity += 0.5 * (dt_previous + dt) * force / mass;
    centre += dt * velocity;
    model.step(dt);
    const auto e = model.deformable(0)->solid_energies();
    // Kinetic energies at x_n from the mean of the half-step velocities, as the solvers report them.
    const double sphere_kinetic = 0.5 * mass * (0.5 * (old_velocity + velocity)).squaredNorm();
    const double total = sphere_kinetic + e.kinetic + e.internal + e.hourglass + out.elastic_energy;
    if (step > 0) result.largest = std::max(result.largest, total);
    result.deepest = std::max(result.deepest, 0.5 - (centre.z() - radius));
    if (e.internal > 0.01 * result.initial)
      result.worst_hourglass_share = std::max(result.worst_hourglass_share, e.hourglass / e.internal);
    result.plastic_work = e.plastic_work;
    result.final_total = total;
    dt_previous = dt;
    t += dt;
    ++step;
  }
  result.rebound_speed = velocity.z();
  return result;
}

}  // namespace

TEST(FemSphereBlockEnergy, StiffPenaltyCreatesNoEnergy) {
  const ImpactResult r = impact(1.0, 0.125, false);
  const double rise = (r.largest - r.initial) / r.initial;
  std::cout << "elastic block, k1 = 1.0, 0.125 m hexahedra: largest total energy rise over initial: measured "
            << 100 * rise << " % limit 1 %; final total " << r.final_total << " J of " << r.initial
            << " J; sphere rebound " << r.rebound_speed << " m/s\n";
  EXPECT_LT(rise, 0.01);
}

TEST(FemSphereBlockEnergy, StiffPenaltyOnPlasticBlockCreatesNoEnergy) {
  // The e2e scene's material (it dents); plastic work is dissipated, so the
  // kept energy must stay below the start as well.
  const ImpactResult r = impact(1.0, 0.125, true);
  const double rise = (r.largest - r.initial) / r.initial;
  std::cout << "plastic block, k1 = 1.0, 0.125 m hexahedra: largest energy rise over initial: measured " << 100 * rise
            << " % limit 2 % (25 % before the fix); sphere rebound " << r.rebound_speed << " m/s\n";
  EXPECT_LT(rise, 0.02);
}

// On 0.0625 m hexahedra the dent under the sphere turns concave: the faces
// around the first (vertex) contact become contacts of their own, each with
// the overlap it has then. With full springs there the total rose 75 %
// (one-point) and 50 % (fully integrated); the normal offset of the coupler's
// contact (surface_contact.hpp) starts them slack.
TEST(FemSphereBlockEnergy, ContactsBornInADentCreateNoEnergy) {
  const ImpactResult r = impact(1.0, 0.0625, true);
  const double rise = (r.largest - r.initial) / r.initial;
  std::cout << "plastic block, k1 = 1.0, 0.0625 m hexahedra: largest energy rise over initial: measured " << 100 * rise
            << " % limit 2 % (75 % before the fix); sphere rebound " << r.rebound_speed << " m/s, depth "
            << 1e3 * r.deepest << " mm\n";
  EXPECT_LT(rise, 0.02);
}

// Fully integrated hexahedra under the sphere's concentrated load: no
// hourglass energy (the one-point block's hourglass/internal is 0.86 here),
// the impact energy-bounded, and the dent close to the one-point block's.
// The mesh study is the enhanced-strain one (DISABLED_...PlasticWorkConvergence).
TEST(FemSphereBlockEnergy, FullyIntegratedImpactHasNoHourglassEnergyAndIsBounded) {
  const ImpactResult full = impact(1.0, 0.125, true, Formulation::fully_integrated);
  const ImpactResult one_point = impact(1.0, 0.125, true, Formulation::one_point);
  const double rise = (full.largest - full.initial) / full.initial;
  std::cout << "fully integrated, 0.125 m hexahedra, k1 = 1.0: energy rise measured " << 100 * rise
            << " % limit 1 %; hourglass/internal measured " << full.worst_hourglass_share << " expected 0 (one-point "
            << one_point.worst_hourglass_share << "); depth " << 1e3 * full.deepest << " mm (one-point "
            << 1e3 * one_point.deepest << "); rebound " << full.rebound_speed << " m/s (one-point "
            << one_point.rebound_speed << "); plastic work " << full.plastic_work << " J (one-point "
            << one_point.plastic_work << ") of " << full.initial << " J\n";
  EXPECT_LT(rise, 0.01);
  EXPECT_EQ(full.worst_hourglass_share, 0.0);
  EXPECT_GT(one_point.worst_hourglass_share, 0.1);  // the case the formulation is for
  EXPECT_NEAR(full.deepest, one_point.deepest, 0.15 * one_point.deepest);
  EXPECT_NEAR(full.rebound_speed, one_point.rebound_speed, 0.1 * std::abs(one_point.rebound_speed));
}

// Enhanced-strain hexahedra (the e2e scene's formulation): no hourglass energy,
// the impact energy-bounded, and the dent close to the fully integrated
// block's (both free of hourglass modes).
TEST(FemSphereBlockEnergy, EnhancedStrainImpactHasNoHourglassEnergyAndIsBounded) {
  const ImpactResult enhanced = impact(1.0, 0.125, true, Formulation::enhanced_strain);
  const ImpactResult full = impact(1.0, 0.125, true, Formulation::fully_integrated);
  const double rise = (enhanced.largest - enhanced.initial) / enhanced.initial;
  std::cout << "enhanced strain, 0.125 m hexahedra, k1 = 1.0: energy rise measured " << 100 * rise
            << " % limit 1 %; hourglass/internal measured " << enhanced.worst_hourglass_share << " expected 0; depth "
            << 1e3 * enhanced.deepest << " mm (fully integrated " << 1e3 * full.deepest << "); rebound "
            << enhanced.rebound_speed << " m/s (fully integrated " << full.rebound_speed << "); plastic work "
            << enhanced.plastic_work << " J (fully integrated " << full.plastic_work << ") of " << enhanced.initial
            << " J\n";
  EXPECT_LT(rise, 0.01);
  EXPECT_EQ(enhanced.worst_hourglass_share, 0.0);
  EXPECT_NEAR(enhanced.deepest, full.deepest, 0.15 * full.deepest);
  EXPECT_NEAR(enhanced.rebound_speed, full.rebound_speed, 0.1 * std::abs(full.rebound_speed));
}

// Mesh convergence of the dent's plastic work (enhanced strain, 0.125 /
// 0.0625 / 0.03125 m): the observed order p = log2((W1 - W2) / (W2 - W3)) and
// the Richardson extrapolation W3 + (W3 - W2) / (2^p - 1). The finest mesh
// takes minutes: outside the suite (--gtest_also_run_disabled_tests; the
// element sizes can be overridden with SABO_BLOCK_SIZES="0.125 0.0625").
// The step is 0.6 of the stable one: the 0.03125 m cubes at 0.9 of it gain
// 15.7 % energy (the cube's step estimate is not conservative); the coarser
// blocks run at max_dt, below 0.7 of theirs, either way.
// It FAILS today (measured 2096 / 2539 / 3821 J, depth 34 / 44 / 145 mm,
// energy rise 0.20 / 0.40 / 0.24 %: the change grows as the mesh is halved):
// the eq. 6 face stiffness k1 K s^2 / V falls with the element size, so the
// sphere sinks deeper on finer blocks and the contact, not only the element,
// changes with the mesh (docs/physics.md "FEM solids").
TEST(FemSphereBlockEnergy, DISABLED_EnhancedStrainPlasticWorkConvergence) {
  std::vector<double> sizes{0.125, 0.0625, 0.03125};
  if (const char* text = std::getenv("SABO_BLOCK_SIZES")) {
    sizes.clear();
    std::istringstream in(text);
    for (double size = 0; in >> size;) sizes.push_back(size);
  }
  std::vector<double> work;
  for (double size : sizes) {
    const ImpactResult r = impact(1.0, size, true, Formulation::enhanced_strain, 0.6);
    work.push_back(r.plastic_work);
    std::cout << "enhanced strain, " << size << " m hexahedra: plastic work " << r.plastic_work << " J, depth "
              << 1e3 * r.deepest << " mm, rebound " << r.rebound_speed << " m/s, energy rise "
              << 100 * (r.largest - r.initial) / r.initial << " %, hourglass/internal " << r.worst_hourglass_share
              << std::endl;
    EXPECT_LT((r.largest - r.initial) / r.initial, 0.02);
  }
  ASSERT_GE(work.size(), 3u);
  const double ratio = (work[0] - work[1]) / (work[1] - work[2]);
  const double order = std::log2(std::abs(ratio));
  std::cout << "plastic work change ratio (W1 - W2) / (W2 - W3): " << ratio << ", observed order " << order
            << ", Richardson estimate " << work[2] + (work[2] - work[1]) / (std::pow(2.0, order) - 1) << " J\n";
  EXPECT_GT(ratio, 1.0);  // converging: the change shrinks as the mesh is halved
}
