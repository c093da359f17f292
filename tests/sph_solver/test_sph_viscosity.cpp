// The viscous stress of SphModel (docs/physics.md, "Viscosity"): 2 eta D through
// sph.viscous_operator = "strain_rate" against Morris's pair term alone ("morris"), in the flows
// that tell them apart (a uniaxial extension with free surfaces, a rigid rotation), in a
// Couette flow whose viscosity varies across the gap, the Herschel-Bulkley law, and a Bingham
// column slumping on a rigid floor against the slump-test analysis.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <string>
#include <vector>

#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"
#include "tests/support/sph_slump.hpp"

namespace sabo::sph {
namespace {

using scene::SphSettings;
using testing::box_body;
using testing::water_scene;
using Operator = SphSettings::ViscousOperator;
using Rheology = scene::Material::Rheology;

const char* name_of(Operator op) {
  return op == Operator::strain_rate ? "strain_rate" : "morris";
}

// ---------------------------------------------------------------------------------------------
// S9 (benchmarks): uniaxial extension (Trouton). A block of Newtonian fluid, free surfaces all round, no gravity,
// 30 x 10 x 10 particles, is stretched along x at the constant rate eps_dot by its ends: the
// particles within `clamp` of either end move along x with the homogeneous extension
// x = X exp(eps_dot t), v_x = eps_dot x (set after every step); across they move freely, so that
// the ends take the lateral contraction the flow gives them. The whole block starts with
// v = eps_dot (x, -y/2, -z/2) at p = 0. Its steady state is the homogeneous extension with
// p = -eta eps_dot (the lateral surfaces free of traction), so the tensile stress across the
// middle is sigma_xx = 2 eta eps_dot - p = 3 eta eps_dot: Trouton's extensional viscosity
// 3 eta. The inertia of the stretching changes it by about rho eps_dot l^2 / (24 eta) (l the
// free length), 0.4 % here.
//
// Measured: the x-force on the half x > 0 (its own pairs cancel: the traction of the other half
// across x = 0) over the section kappa A0 exp(-eps_dot t). kappa is the SPH free surface's:
// a uniform stress in this lattice is transmitted across a section as over kappa times its
// lattice area (about 0.26 dx short of it on each side), kappa measured on the same block at
// rest under a uniform pressure p0 (polynomial EOS, C0 = p0): kappa = F_half / (p0 A0).
scene::Scene extension_scene(double dx, int nx, int nw, double eta, Operator op) {
  const double length = nx * dx, width = nw * dx;
  scene::Scene s = water_scene(dx, 20.0, 1.5);
  s.run.gravity = Vec3::Zero();
  s.sph.artificial_viscosity = 0;
  s.sph.viscous_operator = op;
  scene::Material& m = s.materials[0];
  m.rheology = Rheology::newtonian;
  m.viscosity = eta;
  s.fluids.push_back(
      box_body("block", Vec3(-0.5 * length, -0.5 * width, -0.5 * width), Vec3(0.5 * length, 0.5 * width, 0.5 * width)));
  s.fluids[0].hydrostatic = false;
  return s;
}

// Force along x on the particles with x > 0 in the last compute, N.
double half_force(const SphModel& model) {
  double force = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (model.positions()[i].x() > 0) force += model.masses()[i] * model.accelerations()[i].x();
  }
  return force;
}

struct ExtensionRun {
  double kappa = 0;       // the section factor of the SPH free surface
  double stress = 0;      // Pa, mean sigma_xx over the second half of the run
  double stress_min = 0;  // Pa, its range over the second half
  double stress_max = 0;
  double pressure = 0;  // Pa, mean pressure of the particles within 2 dx of the axis and of x = 0, second half
  double rate = 0;      // 1/s, the least-squares dv_x/dx of the free middle at the end
};

ExtensionRun stretch_block(Operator op) {
  const double dx = 0.01, eta = 100, rate = 0.5, p0 = 100;
  const int nx = 30, nw = 10, clamp_cells = 5;
  const double length = nx * dx, width = nw * dx, clamp = clamp_cells * dx, area = width * width;
  ExtensionRun out;
  {
    scene::Scene s = extension_scene(dx, nx, nw, eta, op);
    s.materials[0].eos = scene::Material::Eos::polynomial;
    s.materials[0].eos_c0 = p0;
    s.materials[0].eos_c1 = 1;
    SphModel at_rest(s);
    at_rest.compute_internal_forces(0);
    out.kappa = half_force(at_rest) / (p0 * area);
  }
  SphModel model(extension_scene(dx, nx, nw, eta, op));
  const std::vector<Vec3> start(model.positions().begin(), model.positions().end());
  const Vec3 g_diag(rate, -0.5 * rate, -0.5 * rate);
  std::vector<std::size_t> clamped, middle, centre;
  for (std::size_t i = 0; i < model.size(); ++i) {
    const Vec3& x = start[i];
    (std::abs(x.x()) > 0.5 * length - clamp ? clamped : middle).push_back(i);
    if (std::abs(x.x()) < 2 * dx && std::abs(x.y()) < 2 * dx && std::abs(x.z()) < 2 * dx) centre.push_back(i);
    model.velocities()[i] = g_diag.cwiseProduct(x);
  }
  const double t_end = 0.1 / rate;  // 10 % strain
  double t = 0, dt_previous = 0, sum = 0, pressure_sum = 0;
  int samples = 0;
  out.stress_min = 1e30;
  out.stress_max = -1e30;
  while (t < t_end) {
    model.compute_internal_forces(dt_previous);
    if (t > 0.5 * t_end) {
      const double stress = -half_force(model) / (out.kappa * area * std::exp(-rate * t));
      sum += stress;
      out.stress_min = std::min(out.stress_min, stress);
      out.stress_max = std::max(out.stress_max, stress);
      double p = 0;
      for (std::size_t i : centre) p += model.pressures()[i];
      pressure_sum += p / static_cast<double>(centre.size());
      ++samples;
    }
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    t += dt;
    dt_previous = dt;
    for (std::size_t i : clamped) {
      model.positions()[i].x() = std::exp(rate * t) * start[i].x();
      model.velocities()[i].x() = rate * model.positions()[i].x();
    }
  }
  out.stress = sum / samples;
  out.pressure = pressure_sum / samples;
  double sxx = 0, sxv = 0;
  for (std::size_t i : middle) {
    sxx += std::pow(model.positions()[i].x(), 2);
    sxv += model.positions()[i].x() * model.velocities()[i].x();
  }
  out.rate = sxv / sxx;
  return out;
}

// One test per operator, so that ctest runs them side by side (each takes about 40 s on one thread).
void check_extension(Operator op) {
  const double eta = 100, rate = 0.5, expected = 3 * eta * rate;
  const ExtensionRun run = stretch_block(op);
  std::cout << "S9 uniaxial extension, " << name_of(op) << ": sigma_xx across the middle measured " << run.stress
            << " Pa (range " << run.stress_min << " .. " << run.stress_max << " over the second half), expected 3 "
            << "eta eps_dot = " << expected << " Pa (ratio " << run.stress / expected << ", held to 5 %); "
            << "section factor kappa " << run.kappa << "; pressure at the centre " << run.pressure
            << " Pa (-eta eps_dot = " << -eta * rate << " Pa); extension rate of the free middle " << run.rate
            << " 1/s (clamps " << rate << " 1/s)\n";
  if (op == Operator::strain_rate) {
    EXPECT_NEAR(run.stress, expected, 0.05 * expected);
    EXPECT_NEAR(run.rate, rate, 0.02 * rate);
  } else {
    // Morris's pair term carries eta eps_dot of the normal stress, half of 2 eta eps_dot.
    EXPECT_LT(run.stress, 0.7 * expected);
  }
}

TEST(SphValidation, S9UniaxialExtensionCarriesTroutonsStress) {
  check_extension(Operator::strain_rate);
}

TEST(SphValidation, S9MorrisPairTermCarriesLessThanTroutonsStress) {
  check_extension(Operator::morris);
}

// ---------------------------------------------------------------------------------------------
// A rigid rotation has D = 0: no viscous stress, no force on any particle. A free cube of
// Newtonian fluid at rest density (p = 0) spun rigidly about its centre, no gravity, no
// artificial viscosity: every acceleration of the first compute is viscous. Morris's pair term
// alone pulls the surface particles against the rotation (its pair force is along v_ij, and a
// surface particle's neighbours are all on one side) and brakes the spin; with the eta L~^T term
// (the kernel-gradient-corrected L~ is exact for a rotation) the two cancel pair by pair.
struct RotationForces {
  double largest = 0;  // m/s^2, largest |a| of a particle
  double torque = 0;   // N m, |sum m x  a| about the centre, along the spin axis
  double scale = 0;    // N m, eta Omega times the cube's volume: the torque a surface stress eta Omega gives
};

RotationForces spin_cube(Operator op) {
  const double dx = 0.01, eta = 10, side = 10 * dx;
  const Vec3 omega(0.3, -0.5, 2.0);  // rad/s, not along a lattice axis
  scene::Scene s = water_scene(dx, 20.0, 1.5);
  s.run.gravity = Vec3::Zero();
  s.sph.artificial_viscosity = 0;
  s.sph.viscous_operator = op;
  s.materials[0].rheology = Rheology::newtonian;
  s.materials[0].viscosity = eta;
  s.fluids.push_back(box_body("cube", Vec3::Constant(-0.5 * side), Vec3::Constant(0.5 * side)));
  s.fluids[0].hydrostatic = false;
  SphModel model(s);
  for (std::size_t i = 0; i < model.size(); ++i) model.velocities()[i] = omega.cross(model.positions()[i]);
  model.compute_internal_forces(0);
  RotationForces out;
  Vec3 torque = Vec3::Zero();
  for (std::size_t i = 0; i < model.size(); ++i) {
    out.largest = std::max(out.largest, model.accelerations()[i].norm());
    torque += model.masses()[i] * model.positions()[i].cross(model.accelerations()[i]);
  }
  out.torque = torque.dot(omega.normalized());
  out.scale = eta * omega.norm() * std::pow(side, 3);
  return out;
}

TEST(SphViscosity, RigidRotationFeelsNoViscousForce) {
  const RotationForces strain = spin_cube(Operator::strain_rate), morris = spin_cube(Operator::morris);
  std::cout << "rigid rotation of a free cube: largest viscous acceleration strain_rate " << strain.largest
            << " m/s^2, morris " << morris.largest << " m/s^2 (expected 0; held below 1e-4 of morris's); torque "
            << "about the spin axis strain_rate " << strain.torque << " N m, morris " << morris.torque
            << " N m (eta Omega V = " << strain.scale << " N m; expected 0, held below 1e-5 of it)\n";
  EXPECT_GT(morris.largest, 0.1);
  EXPECT_LT(morris.torque, -0.1 * morris.scale);  // brakes the spin
  EXPECT_LT(strain.largest, 1e-4 * morris.largest);
  EXPECT_LT(std::abs(strain.torque), 1e-5 * strain.scale);
}

// ---------------------------------------------------------------------------------------------
// S10 (benchmarks): Couette flow between a floor at rest and a ceiling moving at U, periodic along
// x and y, with a viscosity growing across the gap, eta(z) = eta_0 (1 + z/H) (one Newtonian
// material per row of particles, at the row's height). The shear stress is uniform at steady
// state, so du/dz = tau / eta(z) and
//   u(z) = U ln(1 + z/H) / ln 2,
// against the linear profile of a uniform viscosity. Started from that linear profile, the flow
// relaxes to the curved one; the L2 error of the particles' velocities against it, of U, is held
// to 2 % (the benchmark's tolerance) after 6 relaxation times rho H^2 / (pi^2 eta_mean).
// Background pressure rho c^2 (polynomial EOS, C0) as in S5: no free surface, the wall
// particles wetted. Morris's pair term alone is exact here too (simple shear: div(eta L^T) = 0);
// both are run.
physics::BoundaryParticles plates(double side, double dx, int layers, double gap, double ceiling_speed) {
  physics::BoundaryParticles walls;
  const auto n = static_cast<int>(std::lround(side / dx));
  const auto add = [&](double z, const Vec3& normal, const Vec3& velocity) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        walls.position.emplace_back((i + 0.5) * dx, (j + 0.5) * dx, z);
        walls.velocity.push_back(velocity);
        walls.normal.push_back(normal);
        walls.acceleration.push_back(Vec3::Zero());
        walls.volume.push_back(dx * dx * dx);
      }
    }
  };
  for (int k = 0; k < layers; ++k) {
    add(-(k + 0.5) * dx, Vec3(0, 0, 1), Vec3::Zero());
    add(gap + (k + 0.5) * dx, Vec3(0, 0, -1), Vec3(ceiling_speed, 0, 0));
  }
  return walls;
}

struct CouetteRun {
  double error = 0;                  // L2 of u - u_analytic, of U
  double error_linear = 0;           // L2 of u - U z / H (the uniform-viscosity profile), of U
  std::vector<double> row_z, row_u;  // mean u per row
  double time = 0;
  int steps = 0;
};

CouetteRun varying_viscosity_couette(Operator op) {
  const double dx = 1e-3, rho = 1000, eta0 = 1.0, U = 0.01, c = 0.1;
  const int rows = 16;
  const double H = rows * dx, side = 7 * dx;
  scene::Scene s = water_scene(dx, c, 1.5);
  s.run.gravity = Vec3::Zero();
  s.sph.artificial_viscosity = 0;
  s.sph.viscous_operator = op;
  const scene::Material base = s.materials[0];
  s.materials.clear();
  double inverse_eta_sum = 0;
  for (int r = 0; r < rows; ++r) {
    scene::Material m = base;
    m.name = "row" + std::to_string(r);
    m.rheology = Rheology::newtonian;
    m.viscosity = eta0 * (1.0 + (r + 0.5) / rows);
    m.eos = scene::Material::Eos::polynomial;
    m.eos_c0 = rho * c * c;
    m.eos_c1 = 1;
    inverse_eta_sum += 1.0 / m.viscosity;
    s.materials.push_back(m);
    scene::FluidBody body = box_body(m.name, Vec3(0, 0, r * dx), Vec3(side, side, (r + 1) * dx));
    body.material = m.name;
    body.hydrostatic = false;
    s.fluids.push_back(body);
  }
  const double eta_mean = rows / inverse_eta_sum;
  s.sph.periodic_x = std::array<double, 2>{0.0, side};
  s.sph.periodic_y = std::array<double, 2>{0.0, side};
  SphModel model(s);
  model.set_boundary(plates(side, dx, 3, H, U));
  for (std::size_t i = 0; i < model.size(); ++i) model.velocities()[i] = Vec3(U * model.positions()[i].z() / H, 0, 0);
  const double t_end = 6.0 * rho * H * H / (std::pow(std::numbers::pi, 2) * eta_mean);
  CouetteRun out;
  out.steps = testing::run_until(model, t_end, [&](double t) { out.time = t; });
  const auto analytic = [&](double z) { return U * std::log1p(z / H) / std::log(2.0); };
  double e2 = 0, l2 = 0;
  out.row_z.assign(rows, 0.0);
  out.row_u.assign(rows, 0.0);
  std::vector<int> count(rows, 0);
  for (std::size_t i = 0; i < model.size(); ++i) {
    const double z = model.positions()[i].z(), u = model.velocities()[i].x();
    e2 += std::pow(u - analytic(z), 2);
    l2 += std::pow(u - U * z / H, 2);
    const int r = std::clamp(static_cast<int>(z / dx), 0, rows - 1);
    out.row_z[r] += z;
    out.row_u[r] += u;
    ++count[r];
  }
  for (int r = 0; r < rows; ++r) {
    out.row_z[r] /= count[r];
    out.row_u[r] /= count[r];
  }
  out.error = std::sqrt(e2 / static_cast<double>(model.size())) / U;
  out.error_linear = std::sqrt(l2 / static_cast<double>(model.size())) / U;
  return out;
}

TEST(SphValidation, S10CouetteWithViscosityVaryingAcrossTheGap) {
  const double U = 0.01;
  for (const Operator op : {Operator::strain_rate, Operator::morris}) {
    const CouetteRun run = varying_viscosity_couette(op);
    std::cout << "S10 Couette, eta = eta_0 (1 + z/H), " << name_of(op) << ", t = " << run.time << " s (" << run.steps
              << " steps): L2 error against U ln(1 + z/H) / ln 2 " << 100 * run.error
              << " % of U (held to 2 %); against the linear profile " << 100 * run.error_linear << " %\n";
    for (std::size_t r = 0; r < run.row_z.size(); r += 3) {
      const double H = 16e-3, z = run.row_z[r];
      std::cout << "  z = " << z * 1e3 << " mm: u measured " << run.row_u[r] << " m/s, expected "
                << U * std::log1p(z / H) / std::log(2.0) << " m/s\n";
    }
    EXPECT_LT(run.error, 0.02);
    EXPECT_GT(run.error_linear, 0.03);  // the profile did leave the uniform-viscosity one
  }
}

// ---------------------------------------------------------------------------------------------
// Herschel-Bulkley: tau = tau_y + K gamma_dot^n, the yield term regularised as bingham's
// (Papanastasiou), the power law held at its value at gamma_0 below it. The law itself: flow_index
// 1 is bingham's law to the bit; above a few gamma_0 the stress eta gamma_dot is the regularised
// tau_y (1 - exp(-gamma_dot / gamma_0)) + K gamma_dot^n; at rest the viscosity is bounded for n < 1.
FluidMaterial herschel_bulkley(double tau_y, double K, double n, double gamma0) {
  FluidMaterial m;
  m.rheology = Rheology::herschel_bulkley;
  m.yield_stress = tau_y;
  m.consistency_index = K;
  m.flow_index = n;
  m.yield_shear_rate = gamma0;
  return m;
}

TEST(SphViscosity, HerschelBulkleyLaw) {
  FluidMaterial bingham;
  bingham.rheology = Rheology::bingham;
  bingham.viscosity = 1.5;
  bingham.yield_stress = 40;
  bingham.yield_shear_rate = 0.5;
  const FluidMaterial linear = herschel_bulkley(40, 1.5, 1.0, 0.5);
  int differing = 0;
  for (const double rate : {0.0, 1e-9, 0.01, 0.3, 0.5, 2.0, 17.0, 400.0}) {
    differing += linear.viscosity_at(rate) == bingham.viscosity_at(rate) ? 0 : 1;
  }
  const FluidMaterial thinning = herschel_bulkley(40, 3.0, 0.4, 0.5);
  double worst = 0;
  for (const double rate : {5.0, 20.0, 80.0, 320.0}) {
    const double expected = 40 * -std::expm1(-rate / 0.5) + 3.0 * std::pow(rate, 0.4);
    worst = std::max(worst, std::abs(thinning.viscosity_at(rate) * rate / expected - 1.0));
  }
  const double at_rest = 3.0 * std::pow(0.5, 0.4 - 1.0) + 40 / 0.5;
  std::cout << "herschel_bulkley: flow index 1 against bingham at 8 rates, values differing: " << differing
            << " (expected 0); n = 0.4, stress against tau_y (1 - exp(-rate/gamma_0)) + K rate^n at 5..320 1/s, "
            << "largest relative difference " << worst << " (expected 0 to rounding, held to 1e-12); viscosity at "
            << "rest " << thinning.viscosity_at(0.0) << " Pa s, K gamma_0^(n-1) + tau_y / gamma_0 = " << at_rest
            << " Pa s, max_viscosity " << thinning.max_viscosity() << " Pa s\n";
  EXPECT_EQ(differing, 0);
  EXPECT_LT(worst, 1e-12);
  EXPECT_NEAR(thinning.viscosity_at(0.0), at_rest, 1e-12 * at_rest);
  EXPECT_NEAR(thinning.max_viscosity(), at_rest, 1e-12 * at_rest);
  EXPECT_NEAR(thinning.viscosity_at(0.1), 3.0 * std::pow(0.5, -0.6) + 40 * -std::expm1(-0.2) / 0.1, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// The slump test: a square Bingham column (H = side = 0.1 m) released on a no-slip floor
// (tests/support/sph_slump.hpp) against the slump analysis h_f / H = x (1 - ln x), x =
// sqrt(3) tau_y / (rho g H) (slump_analysis(): Pashias et al. 1996's cylinder analysis with the
// von Mises yield in compression of this Bingham law). The analysis is static and
// one-dimensional: an ideal yield stress, no inertia, a base free to spread. The SPH slump
// (mu_p = 5 Pa s, gamma_0 = 1/s) is inertial (the collapse reaches 0.35 sqrt(gH)), regularised (it
// creeps at about gamma_0 near yield) and on a no-slip floor; it is taken when the collapse ends
// (the fastest particle below 5 % of sqrt(g H) for 0.02 s). Measured (docs/physics.md,
// "Viscosity"): 9-12 % below the analysis at dx = H/10, 15 % at H/15 (inertia and creep both
// lower it: gamma_0 = 0.25/s raises it by 1.4 % of H); Morris's pair term alone, 25-28 % below
// (its uniaxial yield is about half: the twice-as-far slump). Held: within 15 % with the
// default operator, and Morris's outside it (what the fix changed). The step is the viscous one,
// cfl rho h^2 / (8 eta), eta about tau_y / gamma_0 where the column is unyielded: at cfl 0.5, half the
// steps of the default 0.25 (1735, 1501 and 2456 steps), the final heights are those at 0.25 to 6e-5 H:
// 0.528 H (ratio 0.885) and 0.651 H (0.907) at x = 0.25 and 0.35, Morris's 0.454 H (0.761).
TEST(SphValidation, BinghamColumnSlumpReduced) {
  for (const double x : {0.25, 0.35}) {
    const double expected = testing::slump_analysis(x);
    for (const Operator op : {Operator::strain_rate, Operator::morris}) {
      if (op == Operator::morris && x != 0.25) continue;
      testing::SlumpCase c;
      c.yield_number = x;
      c.op = op;
      c.cfl = 0.5;
      const testing::SlumpRun run = testing::run_slump(c);
      const double measured = run.final_height / c.height;
      std::cout << "Bingham column slump, sqrt(3) tau_y / (rho g H) = " << x << ", dx = H/10, " << name_of(op)
                << ": final height measured " << measured << " H at t = " << run.time << " s (" << run.steps
                << " steps; collapse ended: " << (run.stopped ? "yes" : "no") << "), slump analysis " << expected
                << " H, ratio " << measured / expected << (op == Operator::strain_rate ? " (held to 15 %)" : "")
                << "; half-width of the deposit " << run.spread << " m\n";
      EXPECT_TRUE(run.stopped);
      if (op == Operator::strain_rate) {
        EXPECT_NEAR(measured, expected, 0.15 * expected);
      } else {
        EXPECT_LT(measured, 0.85 * expected);
      }
    }
  }
}

// The full case: `build/bin/test_sph_viscosity --gtest_also_run_disabled_tests
// --gtest_filter='*DISABLED_BinghamColumnSlump'` (dx = H/15, both yield numbers and operators;
// 10 minutes on one thread); bench_sph_slump runs any other case.
TEST(SphValidation, DISABLED_BinghamColumnSlump) {
  for (const double x : {0.25, 0.35}) {
    const double expected = testing::slump_analysis(x);
    for (const Operator op : {Operator::strain_rate, Operator::morris}) {
      testing::SlumpCase c;
      c.dx = c.height / 15;
      c.yield_number = x;
      c.op = op;
      const testing::SlumpRun run = testing::run_slump(c);
      const double measured = run.final_height / c.height;
      std::cout << "Bingham column slump, x = " << x << ", dx = H/15, " << name_of(op) << ": final height measured "
                << measured << " H at t = " << run.time << " s, slump analysis " << expected << " H, ratio "
                << measured / expected << "\n";
      EXPECT_TRUE(run.stopped);
      if (op == Operator::strain_rate) {
        EXPECT_NEAR(measured, expected, 0.2 * expected);
      }
    }
  }
}

}  // namespace
}  // namespace sabo::sph
