// 4-node shells, Belytschko-Lin-Tsay and fully integrated (MITC4): shell
// cantilevers against beam theory (a thin coarse one for shear locking), the
// zero-energy modes of one element, the same bits on 1 and 2 threads, and a
// panel loaded past its failure strain erodes.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <fstream>
#include <iostream>

#include "fem_solver/fem_model.hpp"
#include "fem_solver/shell_body.hpp"
#include "libsabo/scene/loader.hpp"
#include "tests/fem_solver/fem_test_support.hpp"
#include "tests/support/scratch.hpp"

using sabo::Aabb;
using sabo::Vec3;
using namespace sabo::fem;

using test::steel;

namespace {

struct CantileverResult {
  double deflection = 0, expected = 0;  // m
  SolidEnergies energies;
};

// Strip `length` x 0.1 m x `thickness` of n1 x n2 shells clamped at x = 0,
// 10 N at the tip, solved by dynamic relaxation: P L^3 / (3 E I) with
// I = b t^3 / 12.
CantileverResult cantilever(ShellFormulation formulation, double thickness, std::size_t n1, std::size_t n2) {
  const double length = 1.0, width = 0.1, load = 10.0;
  ShellMesh mesh;
  add_panel(mesh, Vec3::Zero(), Vec3(length, 0, 0), Vec3(0, width, 0), n1, n2, thickness, 0);
  ShellBody body(mesh, {steel()}, formulation);
  body.fix_in_box(Aabb{Vec3(-1e-9, -1, -1), Vec3(1e-9, 1, 1)}, dof_all | rotations_all);
  std::vector<Vec3> force(body.node_count(), Vec3::Zero());
  std::vector<std::size_t> tip;
  for (std::size_t i = 0; i < body.node_count(); ++i) {
    if (body.reference_positions()[i].x() > length - 1e-9) tip.push_back(i);
  }
  EXPECT_EQ(tip.size(), n2 + 1);
  for (auto i : tip) {
    const double y = body.reference_positions()[i].y();
    force[i] = Vec3(0, 0, -load / static_cast<double>(n2) * ((y < 1e-9 || y > width - 1e-9) ? 0.5 : 1.0));
  }
  const double inertia = width * thickness * thickness * thickness / 12.0;
  const double omega = 1.8751 * 1.8751 * std::sqrt(210e9 * inertia / (7850 * width * thickness)) / (length * length);
  body.set_damping(2 * omega);
  const double dt = 0.9 * body.stable_dt();
  double dt_previous = 0;
  for (double t = 0; t < 14.0 / omega; t += dt) {
    body.compute_internal_forces(dt_previous);
    body.integrate(dt_previous, dt, force);
    dt_previous = dt;
  }
  CantileverResult result;
  for (auto i : tip) result.deflection -= body.positions()[i].z() / static_cast<double>(tip.size());
  result.expected = load * length * length * length / (3 * 210e9 * inertia);
  result.energies = body.energies();
  return result;
}

}  // namespace

// Strip 1 m x 0.1 m x 10 mm, 20 x 2 shells: P L^3 / (3 E I) = 1.905 mm.
TEST(Shell, CantileverTipDeflectionAgainstBeamTheory) {
  const CantileverResult r = cantilever(ShellFormulation::one_point, 0.01, 20, 2);
  std::cout << "shell cantilever tip deflection: measured " << r.deflection * 1e3 << " mm expected " << r.expected * 1e3
            << " mm\n";
  EXPECT_NEAR(r.deflection, r.expected, 0.02 * r.expected);
  std::cout << "hourglass/internal energy: measured " << r.energies.hourglass / r.energies.internal << " limit 0.1\n";
  EXPECT_LT(std::abs(r.energies.hourglass), 0.1 * r.energies.internal);
}

TEST(Shell, FullyIntegratedCantileverTipDeflectionAgainstBeamTheory) {
  const CantileverResult r = cantilever(ShellFormulation::fully_integrated, 0.01, 20, 2);
  std::cout << "fully integrated shell cantilever tip deflection: measured " << r.deflection * 1e3 << " mm expected "
            << r.expected * 1e3 << " mm\n";
  EXPECT_NEAR(r.deflection, r.expected, 0.02 * r.expected);
  std::cout << "hourglass energy: measured " << r.energies.hourglass << " J expected 0\n";
  EXPECT_EQ(r.energies.hourglass, 0.0);
}

// Shear locking: 1 m x 0.1 m x 5 mm (length / thickness = 200) with only
// 8 x 1 shells. Fully integrated transverse shear would lock (the tip moves a
// small fraction of P L^3 / (3 E I)); the MITC4 assumed shear does not.
TEST(Shell, ThinCoarseFullyIntegratedCantileverDoesNotLock) {
  const CantileverResult r = cantilever(ShellFormulation::fully_integrated, 0.005, 8, 1);
  std::cout << "thin coarse (L/t = 200, 8 x 1) fully integrated cantilever tip deflection: measured "
            << r.deflection * 1e3 << " mm expected " << r.expected * 1e3 << " mm (ratio " << r.deflection / r.expected
            << ")\n";
  EXPECT_NEAR(r.deflection, r.expected, 0.03 * r.expected);
}

namespace {

// Stiffness of one elastic element, 24 x 24 over the local-frame rates
// (v_x, v_y, v_z, w_x, w_y, w_z per node): column j is the force after a unit
// rate of DOF j over dt = 1 from the unstressed state.
MaterialParameters unit_material() {
  MaterialParameters unit;
  unit.density = 1;
  unit.youngs_modulus = 1;
  unit.poisson_ratio = 0.3;
  return unit;
}

const QuadNodes kDistorted{Vec3(0, 0, 0), Vec3(1.1, 0.1, 0), Vec3(1.2, 0.9, 0), Vec3(-0.1, 1.0, 0)};

Eigen::Matrix<double, 24, 24> element_stiffness(ShellFormulation formulation, double hourglass_scale,
                                                const QuadNodes& x = kDistorted, double thickness = 0.1) {
  const MaterialParameters unit = unit_material();
  Eigen::Matrix<double, 24, 24> k;
  for (int j = 0; j < 24; ++j) {
    QuadNodes v{}, w{}, force, moment;
    for (auto* field : {&v, &w}) {
      for (auto& value : *field) value.setZero();
    }
    const auto node = static_cast<std::size_t>(j / 6);
    if (j % 6 < 3) {
      v[node](j % 6) = 1;
    } else {
      w[node](j % 6 - 3) = 1;
    }
    Shell4State state;
    if (formulation == ShellFormulation::fully_integrated) {
      Shell4GaussPoints gauss;
      EXPECT_TRUE(shell4_full_internal_force(unit, thickness, x, v, w, 1.0, state, gauss, force, moment));
    } else {
      EXPECT_TRUE(shell4_internal_force(unit, thickness, hourglass_scale, x, v, w, 1.0, state, force, moment));
    }
    for (std::size_t a = 0; a < 4; ++a) {
      k.block<3, 1>(static_cast<Eigen::Index>(6 * a), j) = force[a];
      k.block<3, 1>(static_cast<Eigen::Index>(6 * a + 3), j) = moment[a];
    }
  }
  return k;
}

int zero_energy_modes(const Eigen::Matrix<double, 24, 24>& k) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 24, 24>> solver(0.5 * (k + k.transpose()));
  const double largest = solver.eigenvalues().cwiseAbs().maxCoeff();
  int zero = 0;
  for (Eigen::Index i = 0; i < 24; ++i) zero += std::abs(solver.eigenvalues()(i)) < 1e-9 * largest ? 1 : 0;
  return zero;
}

}  // namespace

// A distorted element's stiffness has exactly the 6 rigid-body modes as zero
// eigenvalues when fully integrated (drilling included); the one-point
// element without its hourglass control has the spurious ones too.
TEST(Shell, FullyIntegratedElementHasOnlyRigidBodyZeroEnergyModes) {
  const auto full = element_stiffness(ShellFormulation::fully_integrated, 0);
  const double asymmetry = (full - full.transpose()).cwiseAbs().maxCoeff() / full.cwiseAbs().maxCoeff();
  const int full_zero = zero_energy_modes(full);
  const int one_point_zero = zero_energy_modes(element_stiffness(ShellFormulation::one_point, 0));
  std::cout << "zero-energy modes of one element: fully integrated measured " << full_zero
            << " expected 6 (rigid body); one-point without hourglass control " << one_point_zero
            << "; stiffness asymmetry " << asymmetry << "\n";
  EXPECT_EQ(full_zero, 6);
  EXPECT_GT(one_point_zero, 6);
  EXPECT_LT(asymmetry, 1e-12);
}

// The explicit step: the fully integrated element takes the BLT element's
// stable step (area / longest side or diagonal / plate speed), so its highest
// frequency must not exceed the one-point element's; and that step must not
// exceed either element's own critical step. 2 / omega_max of one free element
// with ShellBody's lumped masses rho t A / 4 and rotational inertias
// m (t^2 + A) / 12 (the element bound, below the mesh's critical step),
// thin and thick, square and distorted.
TEST(Shell, FullyIntegratedCriticalStepAsOnePoint) {
  const MaterialParameters unit = unit_material();
  const QuadNodes square{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  for (const QuadNodes& x : {square, kDistorted}) {
    for (double thickness : {0.01, 0.3, 1.0}) {
      const double area = shell4_area(x), mass = unit.density * thickness * area / 4.0;
      Eigen::Matrix<double, 24, 1> inverse_sqrt_mass;
      for (Eigen::Index i = 0; i < 24; ++i) {
        inverse_sqrt_mass(i) = 1.0 / std::sqrt(i % 6 < 3 ? mass : mass * (thickness * thickness + area) / 12.0);
      }
      const double step = shell4_characteristic_length(x) / unit.plate_wave_speed();
      std::array<double, 2> critical{};
      for (ShellFormulation formulation : {ShellFormulation::one_point, ShellFormulation::fully_integrated}) {
        const auto k = element_stiffness(formulation, 1.0, x, thickness);
        const Eigen::Matrix<double, 24, 24> scaled =
            inverse_sqrt_mass.asDiagonal() * (0.5 * (k + k.transpose())) * inverse_sqrt_mass.asDiagonal();
        const double omega_max =
            std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 24, 24>>(scaled).eigenvalues().maxCoeff());
        critical[static_cast<std::size_t>(formulation)] = 2.0 / omega_max;
      }
      std::cout << (x == square ? "square" : "distorted") << " t/L " << thickness
                << ": element critical step / stable step, one-point " << critical[0] / step
                << ", fully integrated measured " << critical[1] / step << " limit 0.98 of one-point\n";
      EXPECT_GT(critical[1], 0.98 * critical[0]);
      EXPECT_GE(critical[0], step) << "the stable step must not exceed the element's critical step";
      EXPECT_GE(critical[1], step) << "the stable step must not exceed the element's critical step";
    }
  }
}

// A plastic panel under gravity with an initial velocity field, 40 steps:
// the same bits on 1 and 2 threads, for both formulations.
TEST(Shell, SameBitsOnOneAndTwoThreads) {
  auto run = [](int threads, ShellFormulation formulation) {
    omp_set_num_threads(threads);
    MaterialParameters material = steel();
    material.yield_stress = 50e6;
    material.tangent_modulus = 1e9;
    ShellMesh mesh;
    add_panel(mesh, Vec3::Zero(), Vec3(1, 0, 0), Vec3(0, 0.5, 0.1), 8, 4, 0.01, 0);
    ShellBody body(mesh, {material}, formulation);
    body.set_parallel_minimum(0);  // parallel even for this small mesh
    body.fix_in_box(Aabb{Vec3(-1e-9, -1, -1), Vec3(1e-9, 1, 1)}, dof_all | rotations_all);
    body.set_gravity(Vec3(0, 0, -9.81));
    body.set_velocity(Vec3(0.5, -1.0, 20.0));
    const double dt = 0.9 * body.stable_dt();
    double dt_previous = 0;
    for (int n = 0; n < 40; ++n) {
      body.compute_internal_forces(dt_previous);
      body.integrate(dt_previous, dt);
      dt_previous = dt;
    }
    EXPECT_GT(body.energies().plastic_work, 0.0);
    std::vector<Vec3> out(body.positions().begin(), body.positions().end());
    out.insert(out.end(), body.angular_velocities().begin(), body.angular_velocities().end());
    return out;
  };
  for (ShellFormulation formulation : {ShellFormulation::one_point, ShellFormulation::fully_integrated}) {
    const auto one = run(1, formulation), two = run(2, formulation);
    omp_set_num_threads(2);
    ASSERT_EQ(one.size(), two.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < one.size(); ++i) differing += one[i] == two[i] ? 0 : 1;
    std::cout << "shell formulation " << static_cast<int>(formulation)
              << ": node vectors differing on 1 vs 2 threads: " << differing << " of " << one.size() << " expected 0\n";
    EXPECT_EQ(differing, 0u);
  }
}

// element_formulation = "fully_integrated" from a scene file reaches the
// shells of a building (box with a thickness) and of a plane panel; the
// default stays one-point.
TEST(Shell, FormulationFromTheSceneAndAHouseSettlingUnderGravity) {
  const auto file = sabo::testing::scratch("shell_formulation.toml");
  {
    std::ofstream out(file);
    out << "format_version = 1\n[run]\nend_time = 1.0\noutput_interval = 0.1\n"
           "[materials.brick]\ndensity = 2300.0\nyoungs_modulus = 8e9\npoisson_ratio = 0.23\n"
           "[[structures]]\nname = \"house\"\nmaterial = \"brick\"\nrigid = false\nshape = \"box\"\n"
           "min = [0.0, 0.0, 0.0]\nmax = [6.0, 4.0, 3.0]\nthickness = 0.24\nelement_size = 1.0\n"
           "fixed = [\"z-\"]\nelement_formulation = \"fully_integrated\"\n"
           "[[structures]]\nname = \"wall\"\nmaterial = \"brick\"\nrigid = false\nshape = \"plane\"\n"
           "origin = [10.0, 0.0, 1.5]\nnormal = [0.0, -1.0, 0.0]\ndirection = [1.0, 0.0, 0.0]\nlength = 4.0\n"
           "width = 3.0\nthickness = 0.24\nelement_size = 0.5\nelement_formulation = \"fully_integrated\"\n"
           "[[structures]]\nname = \"shed\"\nmaterial = \"brick\"\nrigid = false\nshape = \"plane\"\n"
           "origin = [20.0, 0.0, 1.5]\nnormal = [0.0, -1.0, 0.0]\ndirection = [1.0, 0.0, 0.0]\nlength = 2.0\n"
           "width = 2.0\nthickness = 0.1\nelement_size = 0.5\n";
  }
  FemModel model(sabo::scene::load_scene(file));
  ASSERT_EQ(model.part_count(), 3u);
  for (std::size_t part = 0; part < 3; ++part) ASSERT_TRUE(model.deformable(part)->is_shell());
  EXPECT_EQ(model.deformable(0)->shell()->formulation(), ShellFormulation::fully_integrated);
  EXPECT_EQ(model.deformable(1)->shell()->formulation(), ShellFormulation::fully_integrated);
  EXPECT_EQ(model.deformable(2)->shell()->formulation(), ShellFormulation::one_point);
  // The house (walls welded at the corners, slab and roof: there the drilling
  // rotations of one panel are the bending rotations of the next) settles
  // under gravity on its fixed base: bounded, no spurious mode growing.
  double dt_previous = 0, fastest = 0;
  for (int n = 0; n < 1000; ++n) {
    model.compute_internal_forces(dt_previous);
    model.update_surface();
    const double dt = 0.9 * model.stable_dt();
    model.step(dt);
    dt_previous = dt;
  }
  for (const Vec3& v : model.deformable(0)->shell()->velocities()) fastest = std::max(fastest, v.norm());
  const SolidEnergies e = model.deformable(0)->solid_energies();
  std::cout << "house of fully integrated shells under gravity after 1000 steps: fastest node " << fastest
            << " m/s, energy balance " << e.total() << " J (limit 3%) of external work " << e.external_work
            << " J, drilling energy " << model.deformable(0)->shell()->drilling_energy() << " J\n";
  EXPECT_TRUE(std::isfinite(fastest));
  EXPECT_LT(fastest, 0.1);
  // 0.46 J here; the same house of BLT shells misses by 0.49 J of 50 J (1.0%): the central-difference
  // accounting of a sudden load, not the element.
  EXPECT_LT(std::abs(e.total()), 0.03 * e.external_work);
}

// A panel pulled in its plane past the failure strain erodes.
TEST(Shell, PanelErodesAtItsFailureStrain) {
  MaterialParameters brick = steel();
  brick.density = 2300;
  brick.youngs_modulus = 8e9;
  brick.poisson_ratio = 0.23;
  brick.yield_stress = 8e6;
  brick.failure_principal_strain = 0.0033;
  ShellMesh mesh;
  add_panel(mesh, Vec3::Zero(), Vec3(1, 0, 0), Vec3(0, 0.5, 0), 4, 2, 0.24, 0);
  ShellBody body(mesh, {brick});
  body.fix_in_box(Aabb{Vec3(-1e-9, -1, -1), Vec3(1e-9, 1, 1)}, dof_all | rotations_all);
  for (std::size_t i = 0; i < body.node_count(); ++i) {
    if (body.reference_positions()[i].x() > 1 - 1e-9) body.fix(i, dof_y | dof_z);
  }
  std::vector<Vec3> pull(body.node_count(), Vec3::Zero());
  for (std::size_t i = 0; i < body.node_count(); ++i) {
    if (body.reference_positions()[i].x() > 1 - 1e-9) pull[i] = Vec3(2e6, 0, 0);
  }
  const double dt = 0.9 * body.stable_dt();
  double dt_previous = 0;
  for (int n = 0; n < 20000 && body.topology_revision() == 0; ++n) {
    body.compute_internal_forces(dt_previous);
    body.integrate(dt_previous, dt, pull);
    dt_previous = dt;
  }
  std::size_t eroded = 0;
  for (std::size_t e = 0; e < body.element_count(); ++e) eroded += body.eroded(e) ? 1 : 0;
  std::cout << "eroded shell elements: " << eroded << " of " << body.element_count() << "\n";
  EXPECT_GT(eroded, 0u);
}
