// Belytschko-Lin-Tsay shells: a shell cantilever against beam theory, the
// membrane wave speed, and a panel loaded past its failure strain erodes.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "fem_solver/shell_body.hpp"
#include "tests/fem_solver/fem_test_support.hpp"

using sabo::Aabb;
using sabo::Vec3;
using namespace sabo::fem;

using test::steel;

// Strip 1 m x 0.1 m x 10 mm clamped at x = 0, 10 N at the tip:
// P L^3 / (3 E I) = 1.905 mm with I = b t^3 / 12.
TEST(Shell, CantileverTipDeflectionAgainstBeamTheory) {
  const double length = 1.0, width = 0.1, thickness = 0.01, load = 10.0;
  ShellMesh mesh;
  add_panel(mesh, Vec3::Zero(), Vec3(length, 0, 0), Vec3(0, width, 0), 20, 2, thickness, 0);
  ShellBody body(mesh, {steel()});
  body.fix_in_box(Aabb{Vec3(-1e-9, -1, -1), Vec3(1e-9, 1, 1)}, dof_all | rotations_all);
  std::vector<Vec3> force(body.node_count(), Vec3::Zero());
  std::vector<std::size_t> tip;
  for (std::size_t i = 0; i < body.node_count(); ++i) {
    if (body.reference_positions()[i].x() > length - 1e-9) tip.push_back(i);
  }
  ASSERT_EQ(tip.size(), 3u);
  for (auto i : tip) {
    const double y = body.reference_positions()[i].y();
    force[i] = Vec3(0, 0, -load * ((y < 1e-9 || y > width - 1e-9) ? 0.25 : 0.5));
  }
  const double inertia = width * thickness * thickness * thickness / 12.0;
  const double expected = load * length * length * length / (3 * 210e9 * inertia);
  const double omega = 1.8751 * 1.8751 * std::sqrt(210e9 * inertia / (7850 * width * thickness)) / (length * length);
  body.set_damping(2 * omega);
  const double dt = 0.9 * body.stable_dt();
  double dt_previous = 0;
  for (double t = 0; t < 14.0 / omega; t += dt) {
    body.compute_internal_forces(dt_previous);
    body.integrate(dt_previous, dt, force);
    dt_previous = dt;
  }
  double deflection = 0;
  for (auto i : tip) deflection -= body.positions()[i].z() / static_cast<double>(tip.size());
  std::cout << "shell cantilever tip deflection: measured " << deflection * 1e3 << " mm expected " << expected * 1e3
            << " mm\n";
  EXPECT_NEAR(deflection, expected, 0.02 * expected);
  const SolidEnergies e = body.energies();
  std::cout << "hourglass/internal energy: measured " << e.hourglass / e.internal << " limit 0.1\n";
  EXPECT_LT(std::abs(e.hourglass), 0.1 * e.internal);
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
