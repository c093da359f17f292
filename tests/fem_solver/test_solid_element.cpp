// One hexahedron alone: the zero-energy modes of its small-strain stiffness
// (the six rigid-body modes and nothing else for the 2 x 2 x 2 formulations),
// the constant strain patch test of the enhanced-strain element on a
// distorted shape, and its exact pure bending of a rectangular element.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <iostream>
#include <utility>
#include <vector>

#include "fem_solver/elements/hex8.hpp"
#include "fem_solver/solid_body.hpp"
#include "tests/fem_solver/fem_test_support.hpp"

using sabo::Mat3;
using sabo::Vec3;
using namespace sabo::fem;

namespace {

// A distorted hexahedron (no face parallel to another), about 0.1 m.
HexNodes distorted() {
  return {Vec3(0, 0, 0),          Vec3(0.11, 0.01, -0.005), Vec3(0.1, 0.09, 0.01),  Vec3(-0.01, 0.1, 0),
          Vec3(0.01, 0.005, 0.1), Vec3(0.1, -0.01, 0.12),   Vec3(0.12, 0.1, 0.095), Vec3(0, 0.11, 0.1)};
}

// One step of `formulation` from a stress-free state with nodal velocities v
// over dt = 1 s: the nodes move from x - v/2 (mid-step) to x.
HexNodes one_step_force(HexFormulation formulation, const HexNodes& reference, const HexNodes& velocity,
                        Hex8GaussPoints& gauss) {
  HexNodes x, force;
  for (std::size_t a = 0; a < 8; ++a) x[a] = reference[a] + velocity[a];
  Hex8State state;
  gauss = Hex8GaussPoints{};
  const MaterialParameters material = test::steel();
  bool ok = false;
  switch (formulation) {
    case HexFormulation::one_point: ok = hex8_internal_force(material, 1.0, x, velocity, 1.0, state, force); break;
    case HexFormulation::fully_integrated:
      ok = hex8_full_internal_force(material, x, velocity, 1.0, state, gauss, force);
      break;
    case HexFormulation::enhanced_strain:
      ok = hex8_enhanced_internal_force(material, x, velocity, 1.0, state, gauss, force);
      break;
  }
  EXPECT_TRUE(ok);
  return force;
}

// Small-strain stiffness (N/m) by unit displacements of 1e-9 m, symmetrised.
Eigen::Matrix<double, 24, 24> stiffness(HexFormulation formulation, const HexNodes& reference) {
  const double step = 1e-9;
  Eigen::Matrix<double, 24, 24> k;
  Hex8GaussPoints gauss;
  for (Eigen::Index column = 0; column < 24; ++column) {
    HexNodes velocity;
    for (auto& v : velocity) v.setZero();
    velocity[static_cast<std::size_t>(column / 3)](column % 3) = step;
    const HexNodes force = one_step_force(formulation, reference, velocity, gauss);
    for (Eigen::Index row = 0; row < 24; ++row)
      k(row, column) = force[static_cast<std::size_t>(row / 3)](row % 3) / step;
  }
  return 0.5 * (k + k.transpose());
}

int zero_modes(HexFormulation formulation, const HexNodes& reference) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 24, 24>> solver(stiffness(formulation, reference));
  const Eigen::VectorXd values = solver.eigenvalues();
  int zeros = 0;
  for (Eigen::Index i = 0; i < values.size(); ++i) zeros += std::abs(values(i)) < 1e-6 * values.maxCoeff();
  std::cout << "smallest non-zero / largest eigenvalue: " << values(zeros) / values.maxCoeff() << "\n";
  return zeros;
}

}  // namespace

TEST(HexElement, OnlyRigidBodyZeroEnergyModes) {
  const HexNodes cube = {Vec3(0, 0, 0),   Vec3(0.1, 0, 0),   Vec3(0.1, 0.1, 0),   Vec3(0, 0.1, 0),
                         Vec3(0, 0, 0.1), Vec3(0.1, 0, 0.1), Vec3(0.1, 0.1, 0.1), Vec3(0, 0.1, 0.1)};
  for (const HexNodes& shape : {cube, distorted()}) {
    for (HexFormulation formulation :
         {HexFormulation::one_point, HexFormulation::fully_integrated, HexFormulation::enhanced_strain}) {
      const int zeros = zero_modes(formulation, shape);
      std::cout << "formulation " << static_cast<int>(formulation) << ": zero-energy modes measured " << zeros
                << " expected 6\n";
      EXPECT_EQ(zeros, 6);
    }
  }
}

// A linear velocity field on a distorted element: every Gauss point of the
// enhanced element gets the same stress C : sym(A) dt (the incompatible modes
// stay at rest), and the forces balance.
TEST(HexElement, EnhancedStrainPassesThePatchTest) {
  Mat3 gradient;
  gradient << 1e-9, 2e-10, -3e-10, 0.5e-10, -4e-10, 1e-10, 3e-10, -1e-10, 2e-9;
  const HexNodes reference = distorted();
  HexNodes velocity;
  for (std::size_t a = 0; a < 8; ++a) velocity[a] = gradient * (reference[a] + 0.5 * gradient * reference[a]);
  Hex8GaussPoints gauss;
  const HexNodes force = one_step_force(HexFormulation::enhanced_strain, reference, velocity, gauss);
  const MaterialParameters m = test::steel();
  const Mat3 strain = 0.5 * (gradient + gradient.transpose());
  const Mat3 expected = m.lame_lambda() * strain.trace() * Mat3::Identity() + 2 * m.shear_modulus() * strain;
  double worst = 0;
  for (const MaterialPoint& point : gauss) worst = std::max(worst, (point.stress - expected).norm() / expected.norm());
  Vec3 resultant = Vec3::Zero();
  double scale = 0;
  for (const Vec3& f : force) {
    resultant += f;
    scale += f.norm();
  }
  std::cout << "patch test: worst relative stress error measured " << worst << " limit 1e-6; force resultant "
            << resultant.norm() / scale << " of the force sum\n";
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(resultant.norm(), 1e-12 * scale);
}

// A 0.2 x 0.05 x 0.05 m element in pure bending about y, curvature k: nodal
// u_x = k x z, u_y = -nu k y z (the beam's Poisson contraction): the enhanced
// element's strain energy is the beam's E I k^2 L / 2 (the fully integrated
// one's is printed beside it: parasitic shear).
TEST(HexElement, EnhancedStrainIsExactInPureBending) {
  const double lx = 0.2, lz = 0.05;
  HexNodes reference;
  const std::array<std::array<double, 3>, 8> natural{
      {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, {-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}}};
  for (std::size_t a = 0; a < 8; ++a)
    reference[a] = Vec3(0.5 * lx * natural[a][0], 0.5 * lz * natural[a][1], 0.5 * lz * natural[a][2]);
  const double curvature = 1e-6;  // 1/m
  const MaterialParameters m = test::steel();
  Eigen::Matrix<double, 24, 1> u;
  for (std::size_t a = 0; a < 8; ++a)
    u.segment<3>(static_cast<Eigen::Index>(3 * a)) =
        curvature *
        Vec3(reference[a].x() * reference[a].z(), -m.poisson_ratio * reference[a].y() * reference[a].z(), 0);
  const double inertia = lz * lz * lz * lz / 12.0;
  const double expected = 0.5 * m.youngs_modulus * inertia * curvature * curvature * lx;
  for (HexFormulation formulation : {HexFormulation::enhanced_strain, HexFormulation::fully_integrated}) {
    const double energy = 0.5 * u.dot(stiffness(formulation, reference) * u);
    std::cout << "pure bending energy (formulation " << static_cast<int>(formulation) << "): measured " << energy
              << " J expected " << expected << " J, ratio " << energy / expected << "\n";
    if (formulation == HexFormulation::enhanced_strain) {
      EXPECT_NEAR(energy, expected, 1e-4 * expected);
    }
  }
}

// The stable step the body reports, hex8_characteristic_length / c (eq. 7's FEM
// term), against the element's own critical step 2 / omega_max with lumped
// masses (rho V / 8 per node): it must not exceed it for any shape or
// formulation, or a run at beta = 1 diverges; nor be needlessly small.
TEST(HexElement, StableStepIsBelowTheCriticalStepOfEveryShape) {
  const auto box = [](double a, double b, double c) {
    return HexNodes{Vec3(0, 0, 0), Vec3(a, 0, 0), Vec3(a, b, 0), Vec3(0, b, 0),
                    Vec3(0, 0, c), Vec3(a, 0, c), Vec3(a, b, c), Vec3(0, b, c)};
  };
  const MaterialParameters material = test::steel();
  const std::vector<std::pair<const char*, HexNodes>> shapes = {{"cube", box(0.1, 0.1, 0.1)},
                                                                {"bar 4:1", box(0.4, 0.1, 0.1)},
                                                                {"plate 1:4", box(0.1, 0.1, 0.025)},
                                                                {"distorted", distorted()}};
  for (const auto& [name, shape] : shapes) {
    const double node_mass = material.density * hex8_volume(shape) / 8.0;
    const double estimate = hex8_characteristic_length(shape) / material.wave_speed();
    for (HexFormulation formulation :
         {HexFormulation::one_point, HexFormulation::fully_integrated, HexFormulation::enhanced_strain}) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 24, 24>> solver(stiffness(formulation, shape));
      const double critical = 2.0 / std::sqrt(solver.eigenvalues().maxCoeff() / node_mass);
      std::cout << name << ", formulation " << static_cast<int>(formulation) << ": stable step " << estimate
                << " s, critical " << critical << " s, ratio " << estimate / critical << " (expected in [0.5, 1])\n";
      EXPECT_LE(estimate, critical) << name;
      EXPECT_GE(estimate, 0.5 * critical) << name;
    }
  }
}

// Instability detection of the fem_solver (libsabo/solver/stability.hpp): a hexahedron whose node has been
// driven through the opposite face is found inside out at that step; its neighbours are not.
TEST(HexElement, AnElementDrivenInsideOutIsFoundAtThatStep) {
  using namespace sabo::fem;
  SolidBody body(structured_box(sabo::Aabb{sabo::Vec3(0, 0, 0), sabo::Vec3(2, 1, 1)}, {2, 1, 1}), test::steel());
  EXPECT_TRUE(body.inverted_elements().empty());
  // Node (0, 0, 0) belongs to element 0 only (the unit cube [0, 1]^3): push it along +x by 0.105 m a step. The
  // element's centre volume 8 det J is then 1 - d/4 m^3 for a displacement d: not positive from d = 4 m on, at
  // step 39 (d = 4.095 m); step 38 (d = 3.99 m) is still positive.
  std::size_t corner = 0;
  for (std::size_t i = 0; i < body.node_count(); ++i) {
    if (body.positions()[i].norm() < 1e-12) corner = i;
  }
  std::size_t found_at = 0;
  for (std::size_t step = 1; step <= 100 && found_at == 0; ++step) {
    body.set_node_velocity(corner, sabo::Vec3(1.05, 0, 0));
    body.integrate(0.1, 0.1);
    if (!body.inverted_elements().empty()) {
      found_at = step;
      EXPECT_EQ(body.inverted_elements(), (std::vector<std::size_t>{0}));  // not its neighbour
    }
  }
  std::cout << "element 0 found inside out at step " << found_at
            << " (expected 39), corner at x = " << body.positions()[corner].x() << " m\n";
  EXPECT_EQ(found_at, 39u);
}
