// SphModel: kernels, EOS, filling, and the reduced S4 (hydrostatic tank) and
// S1 (dam break, Martin & Moyce 1952) validations with boundary-particle walls.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <numeric>
#include <random>
#include <utility>

#include "libsabo/contact/surface_contact.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "sph_solver/exact_sum.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::sph {
namespace {

using testing::box_body;
using testing::container_walls;
using testing::hydrostatic_pressure_error;
using testing::run_until;
using testing::water_scene;

TEST(SphKernel, IntegratesToOneAndGradientMatchesValue) {
  for (auto kind : {scene::SphSettings::Kernel::wendland_c2, scene::SphSettings::Kernel::cubic_spline}) {
    const double dx = 0.1, h = 1.3 * dx;
    const Kernel kernel(kind, h);
    double sum = 0;
    for (int i = -6; i <= 6; ++i)
      for (int j = -6; j <= 6; ++j)
        for (int k = -6; k <= 6; ++k) sum += kernel.value(dx * Vec3(i, j, k).norm()) * dx * dx * dx;
    std::cout << "kernel sum over lattice: measured " << sum << " expected 1 (+-1%)\n";
    EXPECT_NEAR(sum, 1.0, 0.01);
    for (double r : {0.3 * h, 0.9 * h, 1.1 * h, 1.7 * h}) {
      const double e = 1e-7 * h;
      const double derivative = (kernel.value(r + e) - kernel.value(r - e)) / (2 * e);
      EXPECT_NEAR(kernel.gradient_factor(r) * r, derivative, 1e-5 * std::abs(derivative) + 1e-9);
    }
    EXPECT_EQ(kernel.value(2.0 * h), 0.0);
  }
}

// The energies' sums (exact_sum.hpp): any order of the terms, any split among ranks (joined through
// their limbs), the same bits; and within a double's rounding of the exact sum.
TEST(SphExactSum, OrderAndSplitDoNotChangeTheBits) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> magnitude(-12.0, 8.0);
  std::vector<double> terms;
  for (int k = 0; k < 20000; ++k) {
    const double term = std::pow(10.0, magnitude(random)) * (k % 3 == 0 ? -1.0 : 1.0);
    terms.push_back(term);
  }
  const auto sum_of = [](const std::vector<double>& values) {
    ExactSum sum;
    for (double v : values) sum.add(v);
    return sum;
  };
  const double forward = sum_of(terms).value();
  std::vector<double> shuffled = terms;
  std::shuffle(shuffled.begin(), shuffled.end(), random);
  EXPECT_EQ(sum_of(shuffled).value(), forward);
  // Three "ranks" of unequal shares, joined through their limbs as integer sums.
  ExactSum::Limbs total{};
  for (const auto& [begin, end] : {std::pair{0, 5000}, std::pair{5000, 5001}, std::pair{5001, 20000}}) {
    ExactSum part;
    for (int k = begin; k < end; ++k) part.add(shuffled[static_cast<std::size_t>(k)]);
    const ExactSum::Limbs limbs = part.limbs();
    for (std::size_t q = 0; q < 4; ++q) total[q] += limbs[q];
  }
  EXPECT_EQ(ExactSum::from_limbs(total).value(), forward);
  // A negative total survives the limbs (two's complement through the carries).
  ExactSum negative;
  negative.add(-3.25e6);
  negative.add(1e-9);
  EXPECT_EQ(ExactSum::from_limbs(negative.limbs()).value(), negative.value());
  // Against a long-double sum of the terms sorted by size: within 1e-14 of the sum of their magnitudes
  // (the long double's own rounding over 20000 terms stays far inside).
  std::vector<double> sorted = terms;
  std::sort(sorted.begin(), sorted.end(), [](double a, double b) { return std::abs(a) < std::abs(b); });
  long double reference = 0, magnitudes = 0;
  for (double v : sorted) {
    reference += v;
    magnitudes += std::abs(v);
  }
  std::cout << "exact sum of 20000 terms from 1e-12 to 1e8: " << forward << ", long double " << double(reference)
            << " (expected within " << 1e-14 * double(magnitudes) << ")\n";
  EXPECT_NEAR(forward, double(reference), 1e-14 * double(magnitudes));
}

TEST(SphEos, InverseOfTaitAndPolynomial) {
  scene::Material m;
  m.density = 2000;
  EquationOfState tait(m, 40.0);
  EXPECT_NEAR(tait.density(tait.pressure(2010.0)), 2010.0, 1e-9);
  EXPECT_NEAR(tait.pressure(2000.0), 0.0, 1e-9);
  m.eos = scene::Material::Eos::polynomial;
  m.eos_c0 = 100;
  m.eos_c1 = 20e9;
  m.eos_c2 = 5e9;
  EquationOfState poly(m, 40.0);
  // Initial stiffness dp/drho = c^2 at rest.
  EXPECT_NEAR((poly.pressure(2000.001) - poly.pressure(1999.999)) / 0.002, 1600.0, 1e-3);
  EXPECT_NEAR(poly.density(poly.pressure(2030.0)), 2030.0, 1e-9);
}

// The compression energy's derivative is p / rho^2 (the work the symmetric pressure force does).
TEST(SphEos, CompressionEnergyDerivativeIsPressureOverDensitySquared) {
  scene::Material m;
  m.density = 2000;
  const EquationOfState tait(m, 40.0);
  m.eos = scene::Material::Eos::polynomial;
  m.eos_c0 = 100;
  m.eos_c1 = 20e9;
  m.eos_c2 = 5e9;
  m.eos_c3 = 2e9;
  const EquationOfState poly(m, 40.0);
  for (const EquationOfState* eos : {&tait, &poly}) {
    EXPECT_DOUBLE_EQ(eos->specific_energy(2000.0), 0.0);
    for (double rho : {1990.0, 2004.0, 2060.0}) {
      const double d = 1e-4;
      const double derivative = (eos->specific_energy(rho + d) - eos->specific_energy(rho - d)) / (2 * d);
      const double expected = eos->pressure(rho) / (rho * rho);
      std::cout << "de/drho at " << rho << ": measured " << derivative << " expected " << expected << "\n";
      EXPECT_NEAR(derivative, expected, 1e-6 * std::abs(expected) + 1e-9);
    }
  }
}

TEST(SphFill, BoxAndExtrudedPolygonWithHydrostaticPressure) {
  scene::Scene s = water_scene(0.1, 20.0);
  s.fluids.push_back(box_body("tank", Vec3(0, 0, 0), Vec3(1.0, 0.5, 0.4)));
  scene::FluidBody wedge;
  wedge.name = "wedge";
  wedge.material = "water";
  wedge.shape = scene::FluidBody::Shape::extruded_polygon;
  wedge.profile = {{0.0, 0.0}, {2.0, 0.0}, {0.0, 1.0}};  // right triangle, area 1 m^2
  wedge.profile_origin = Vec3(5, 0, 0);
  wedge.direction = Vec3(1, 0, 0);
  wedge.width = 0.4;
  s.fluids.push_back(wedge);
  const SphModel model(s);
  std::size_t tank = 0, wedge_count = 0;
  for (std::size_t i = 0; i < model.size(); ++i) (model.body_index()[i] == 0 ? tank : wedge_count)++;
  EXPECT_EQ(tank, 10u * 5u * 4u);
  // The triangle's area over dx^2 times the 4 rows across: 100 * 4 = 400, within the boundary cells.
  std::cout << "wedge particles: measured " << wedge_count << " expected about 400 (+-10%)\n";
  EXPECT_NEAR(static_cast<double>(wedge_count), 400.0, 40.0);
  // Bottom row of the tank, depth d = 0.35 m: dp/dd = rho(p) g with Tait's rho(p), in closed form
  // p = B ((1 + (gamma - 1) rho0 g d / (gamma B))^(gamma / (gamma - 1)) - 1), B = rho0 c^2 / gamma.
  const double gamma = 7, tait_b = 1000 * 20.0 * 20.0 / gamma, depth = 0.35;
  const double expected =
      tait_b * (std::pow(1 + (gamma - 1) * 1000 * 9.81 * depth / (gamma * tait_b), gamma / (gamma - 1)) - 1);
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (model.body_index()[i] != 0 || model.positions()[i].z() > 0.06) continue;
    EXPECT_NEAR(model.pressures()[i], expected, 1e-7 * expected);
  }
  std::cout << "bottom-row pressure: expected " << expected << " Pa (rho0 g d = " << 1000 * 9.81 * depth << " Pa)\n";
}

TEST(SphFill, SpacingWrittenToNineDigitsKeepsItsLayers) {
  // h = 0.04 m at dx = h / 6 written as 0.00666666667: 6 layers deep (the fill once gave 5, a sixth of the water).
  scene::Scene s = water_scene(0.00666666667, 20.0);
  s.fluids.push_back(box_body("layer", Vec3(0, 0, 0), Vec3(0.04, 0.04, 0.04)));
  const SphModel model(s);
  std::cout << "particles: measured " << model.size() << ", expected 6^3 = 216\n";
  EXPECT_EQ(model.size(), 216u);
}

// Density diffusion at rest, measured through one step of dt = 2e-10 s (the continuity term of
// the velocities a_n dt / 2 is then 1e-5 of the diffusion): a hydrostatic column 0.2 m deep at
// c = 3 sqrt(gH), compressed 8 % at the bottom so that Tait is far from linear, no walls.
// Molteni & Colagrossi: delta-SPH's 2 delta h c sum (rho_j - rho_i) (-F r^2 / (r^2 + eta^2)) V_j,
// summed here in double, nonzero where the column's kernel is cut off (top, sides).
// Fourtakas (the dynamic difference, p_j - p_i + rho_mean g.(x_i - x_j)) / c^2): zero at rest,
// where the static form (rho_j - rho_i) + rho0 g.(x_i - x_j) / c^2 would not be. Tolerances: the
// pair terms are single precision (p to 6e-8 relative, about 1e-4 Pa here).
TEST(SphValidation, DensityDiffusionRatesOfAHydrostaticColumn) {
  const double H = 0.2, dx = 0.02, g = 9.81, c = 3.0 * std::sqrt(g * H), dt = 2e-10;
  const auto rates = [&](scene::SphSettings::DensityDiffusion mode) {
    scene::Scene s = water_scene(dx, c);
    s.sph.density_diffusion = mode;
    s.fluids.push_back(box_body("column", Vec3(0, 0, 0), Vec3(0.1, 0.1, H)));
    SphModel model(s);
    const std::vector<double> before(model.densities().begin(), model.densities().end());
    model.compute_internal_forces(0);
    model.integrate(0, dt);
    std::vector<double> rate(model.size());
    for (std::size_t i = 0; i < model.size(); ++i) rate[i] = (model.densities()[i] - before[i]) / dt;
    return std::make_pair(SphModel(s), rate);
  };
  auto [model, molteni] = rates(scene::SphSettings::DensityDiffusion::molteni);
  const auto fourtakas = rates(scene::SphSettings::DensityDiffusion::fourtakas).second;
  const Kernel& kernel = model.kernel();
  const double h = kernel.h, eta2 = 0.01 * h * h, scale = 2.0 * model.settings().density_diffusion_delta * h * c;
  double largest = 0, molteni_error = 0, fourtakas_largest = 0, static_largest = 0;
  std::size_t largest_at = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    double expected = 0, static_form = 0;
    for (std::size_t j = 0; j < model.size(); ++j) {
      const Vec3 r = model.positions()[i] - model.positions()[j];
      const double r2 = r.squaredNorm();
      if (j == i || r2 >= 4 * h * h) continue;
      const double weight =
          -kernel.gradient_factor(std::sqrt(r2)) * r2 / (r2 + eta2) * model.masses()[j] / model.densities()[j];
      const double drho = model.densities()[j] - model.densities()[i];
      expected += drho * weight;
      static_form += (drho - 1000.0 * g * r.z() / (c * c)) * weight;
    }
    expected *= scale;
    static_form *= scale;
    if (std::abs(expected) > largest) {
      largest = std::abs(expected);
      largest_at = i;
    }
    molteni_error = std::max(molteni_error, std::abs(molteni[i] - expected));
    fourtakas_largest = std::max(fourtakas_largest, std::abs(fourtakas[i]));
    static_largest = std::max(static_largest, std::abs(static_form));
  }
  std::cout << "Molteni drho/dt, largest (particle " << largest_at << ", z = " << model.positions()[largest_at].z()
            << " m): measured " << molteni[largest_at] << " expected " << (molteni[largest_at] > 0 ? largest : -largest)
            << " kg/m^3/s; largest difference over the column " << molteni_error << " (<= 1e-4 of the largest)\n";
  std::cout << "Fourtakas drho/dt at rest, largest: measured " << fourtakas_largest
            << " kg/m^3/s, expected 0 (<= 3e-4 of Molteni's largest: the pair terms' single-precision pressures); the "
               "static difference with rho0 would give "
            << static_largest << "\n";
  EXPECT_GT(largest, 1.0);
  EXPECT_LT(molteni_error, 1e-4 * largest);
  EXPECT_LT(fourtakas_largest, 3e-4 * largest);
  EXPECT_GT(static_largest, 1e-2 * largest);
}

// With boundary-particle walls, density diffusion acts only between particles whose kernel
// held at least 0.9 of a lattice's neighbours in fluid in the previous compute (docs/physics.md,
// "Continuity"): none across the free surface or beside a wall, where the cut-off sum makes the
// diffusion a one-sided difference. A hydrostatic column on a floor between walls on x (its
// y sides are free surfaces), Molteni's form; the second step's rate, over dt = 2e-10 s, is
// compared with the sum over the pairs of particles that had a full kernel of fluid at the
// first step, summed here in double (counting the wall particles would make the rows beside
// the walls full).
TEST(SphValidation, DensityDiffusionActsOnlyWhereTheKernelIsFull) {
  const double H = 0.2, dx = 0.02, g = 9.81, c = 3.0 * std::sqrt(g * H), dt = 2e-10;
  scene::Scene s = water_scene(dx, c);
  s.sph.density_diffusion = scene::SphSettings::DensityDiffusion::molteni;
  s.fluids.push_back(box_body("column", Vec3(0, 0, 0), Vec3(0.2, 0.2, H)));
  SphModel model(s);
  physics::BoundaryParticles walls = container_walls(Vec3::Zero(), Vec3(0.2, 0.2, H), dx, 3);
  physics::BoundaryParticles floor_and_x_walls;  // the y walls left out: free sides
  for (std::size_t k = 0; k < walls.size(); ++k) {
    if (walls.position[k].y() < 0 || walls.position[k].y() > 0.2) continue;
    floor_and_x_walls.position.push_back(walls.position[k]);
    floor_and_x_walls.velocity.push_back(walls.velocity[k]);
    floor_and_x_walls.normal.push_back(walls.normal[k]);
    floor_and_x_walls.acceleration.push_back(walls.acceleration[k]);
    floor_and_x_walls.volume.push_back(walls.volume[k]);
  }
  model.set_boundary(floor_and_x_walls);
  const std::vector<Vec3> x0(model.positions().begin(), model.positions().end());
  model.compute_internal_forces(0);
  model.integrate(0, dt);
  const std::vector<double> before(model.densities().begin(), model.densities().end());
  model.compute_internal_forces(dt);
  model.integrate(dt, dt);
  const Kernel& kernel = model.kernel();
  const double h = kernel.h, support2 = 4 * h * h, eta2 = 0.01 * h * h;
  const double scale = 2.0 * model.settings().density_diffusion_delta * h * c;
  int lattice = 0;  // neighbours of a lattice point within 2h
  for (int a = -3; a <= 3; ++a) {
    for (int b = -3; b <= 3; ++b) {
      for (int d = -3; d <= 3; ++d) lattice += (a * a + b * b + d * d) * dx * dx < support2 ? 1 : 0;
    }
  }
  const double threshold = std::ceil(0.9 * (lattice - 1));
  const std::size_t n = model.size();
  std::vector<char> full(n);
  for (std::size_t i = 0; i < n; ++i) {
    int count = 0;
    for (std::size_t j = 0; j < n; ++j) count += j != i && (x0[i] - x0[j]).squaredNorm() < support2 ? 1 : 0;
    full[i] = count >= threshold ? 1 : 0;
  }
  double largest = 0, largest_error = 0, surface_largest = 0;
  std::size_t full_count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double expected = 0;
    for (std::size_t j = 0; j < n && full[i]; ++j) {
      const Vec3 r = model.positions()[i] - model.positions()[j];
      const double r2 = r.squaredNorm();
      if (j == i || r2 >= support2 || !full[j]) continue;
      expected += (before[j] - before[i]) * -kernel.gradient_factor(std::sqrt(r2)) * r2 / (r2 + eta2) *
                  model.masses()[j] / before[j];
    }
    expected *= scale;
    const double measured = (model.densities()[i] - before[i]) / dt;
    largest = std::max(largest, std::abs(expected));
    largest_error = std::max(largest_error, std::abs(measured - expected));
    if (!full[i]) surface_largest = std::max(surface_largest, std::abs(measured));
    full_count += full[i];
  }
  std::cout << "particles with a full kernel: " << full_count << " of " << n << " (threshold " << threshold << " of "
            << lattice - 1 << " lattice neighbours)\n";
  std::cout << "drho/dt, full-kernel pairs only: largest expected " << largest
            << " kg/m^3/s, largest difference measured - expected " << largest_error
            << " (<= 1e-3 of the largest); largest |drho/dt| at particles with a cut-off kernel " << surface_largest
            << " (expected 0 but for the continuity term of v ~ g dt: <= 1e-3 of the largest)\n";
  EXPECT_GT(full_count, n / 10);
  EXPECT_LT(full_count, n);
  EXPECT_GT(largest, 1.0);
  EXPECT_LT(largest_error, 1e-3 * largest);
  EXPECT_LT(surface_largest, 1e-3 * largest);
}

// The reduced S4 tank of both S4 tests: water H deep in an L x W box (m), c = 10 sqrt(g H),
// cubic spline at h = 1.3 dx (see S4HydrostaticTankWithBoundaryParticles), artificial viscosity 0.1.
scene::Scene s4_tank_scene(double dx, double L, double W, double H, double g) {
  scene::Scene s = water_scene(dx, 10.0 * std::sqrt(g * H));
  s.sph.kernel = scene::SphSettings::Kernel::cubic_spline;
  s.sph.artificial_viscosity = 0.1;
  s.fluids.push_back(box_body("water", Vec3(0, 0, 0), Vec3(L, W, H)));
  return s;
}

struct S4Figures {
  double pressure_error = 0;                  // L2, over rho g H, at the end
  double max_speed = 0;                       // m/s, from t = 0
  double max_speed_after_settle = 0;          // m/s, from the end of the settling phase (all of the run without one)
  double max_speed_late = 0;                  // m/s, second half
  double initial_energy = 0, max_energy = 0;  // J
  double bottom = 0, side = 0;                // N, wall forces, means of the last quarter
  double total_vertical = 0, weight = 0;      // N, all wall particles; the particles' weight
};

// S4 hydrostatic tank, reduced: H = 0.2 m, dx = H/10, L = 0.2 m, W = 0.1 m, wall particles of the
// test's own up to 4 dx above the free surface (wetted by the fluid only up to it), run to
// t_end, the water settling (FluidBody::settle_time) until settle.
S4Figures run_s4_tank(double t_end, double settle) {
  const double H = 0.2, dx = 0.02, g = 9.81, L = 0.2, W = 0.1;
  scene::Scene s = s4_tank_scene(dx, L, W, H, g);
  s.fluids.back().settle_time = settle;
  SphModel model(s);
  model.set_boundary(container_walls(Vec3(0, 0, 0), Vec3(L, W, H + 4 * dx), dx, 3));
  const auto& walls = model.boundary();
  // Corner particles belong to both walls: the bottom takes every particle below z = 0,
  // the side x = 0 every particle behind it.
  S4Figures out;
  double samples = 0;
  out.initial_energy = out.max_energy = model.energies().total();
  run_until(model, t_end, [&](double t) {
    out.max_energy = std::max(out.max_energy, model.energies().total());
    for (const Vec3& v : model.velocities()) {
      out.max_speed = std::max(out.max_speed, v.norm());
      if (t >= settle) out.max_speed_after_settle = std::max(out.max_speed_after_settle, v.norm());
      if (t >= 0.5 * t_end) out.max_speed_late = std::max(out.max_speed_late, v.norm());
    }
    if (t < 0.75 * t_end) return;
    for (std::size_t b = 0; b < walls.size(); ++b) {
      if (walls.position[b].z() < 0) out.bottom -= model.boundary_forces()[b].z();
      if (walls.position[b].x() < 0) out.side -= model.boundary_forces()[b].x();
    }
    samples += 1;
  });
  out.bottom /= samples;
  out.side /= samples;
  model.compute_internal_forces(0);
  out.pressure_error = hydrostatic_pressure_error(model, H, g);
  for (const Vec3& f : model.boundary_forces()) out.total_vertical -= f.z();
  out.weight = std::accumulate(model.masses().begin(), model.masses().end(), 0.0) * g;
  return out;
}

// S4 with boundary particles, the water settling for 4 sqrt(H/g) from t = 0 and then free
// to t = 12 sqrt(H/g) (the benchmark asks for 100 sqrt(H/g): bench_sph_stability). Cubic
// spline at h = 1.3 dx, the set-up the figures in docs/physics.md were first taken with (the
// default, Wendland C2 at h = 1.5 dx: bench sph_rest_probe; its energy rises, see there).
// The benchmark's bounds from t = 0, and the total energy (kinetic + potential + compression)
// never above its initial value (the stability criterion).
TEST(SphValidation, S4HydrostaticTankWithBoundaryParticles) {
  const double H = 0.2, g = 9.81, L = 0.2, W = 0.1, T = std::sqrt(H / g), U = std::sqrt(g * H);
  const S4Figures f = run_s4_tank(12 * T, 4 * T);
  const double weight = 1000 * g * H * L * W;
  const double side_expected = 1000 * g * H * H * W / 2;
  std::cout << "S4 pressure L2 error: measured " << 100 * f.pressure_error << " % of rho g H, expected <= 2 %\n";
  std::cout << "S4 largest speed / sqrt(gH), settling to t = 4 sqrt(H/g): measured " << f.max_speed / U
            << " from t = 0, " << f.max_speed_after_settle / U << " after the settling, " << f.max_speed_late / U
            << " in the second half; expected <= 1e-3\n";
  std::cout << "S4 total energy: initial " << f.initial_energy << " J, largest after it " << f.max_energy
            << " J (expected never above the initial value)\n";
  std::cout << "S4 bottom force (mean of the last quarter): measured " << f.bottom << " N, expected " << weight
            << " N (+-1%)\n";
  std::cout << "S4 side force (mean of the last quarter): measured " << f.side << " N, expected " << side_expected
            << " N (+-2%)\n";
  std::cout << "S4 total wall force: measured " << f.total_vertical << " N vs weight " << f.weight << " N\n";
  EXPECT_LT(f.pressure_error, 0.02);
  EXPECT_NEAR(f.bottom / weight, 1.0, 0.01);
  EXPECT_NEAR(f.side / side_expected, 1.0, 0.02);
  EXPECT_LT(f.max_speed, 1e-3 * U);
  EXPECT_LE(f.max_energy, f.initial_energy);
}

// The settling phase (FluidBody::settle_time): a settling body's velocities are damped and
// exactly zero after the step that reaches the phase's end; a body without one, out of
// reach of the first, runs as in a scene where nothing settles (to the float rounding of the
// positions, which are relative to the box around all particles); time() is the sum of the
// steps.
TEST(SphModelContract, SettlingDampsOnlyItsBodyAndEndsAtRest) {
  const double dx = 0.02, c = 20.0, settle = 0.05;
  const auto scene_with = [&](double settle_time) {
    scene::Scene s = water_scene(dx, c);
    s.fluids.push_back(box_body("settling", Vec3(0, 0, 0), Vec3(0.1, 0.1, 0.1)));
    s.fluids.back().settle_time = settle_time;
    s.fluids.push_back(box_body("falling", Vec3(0.5, 0, 0), Vec3(0.6, 0.1, 0.1)));
    return s;
  };
  SphModel settling(scene_with(settle)), free(scene_with(0));
  double t = 0, dt_previous = 0, largest_settling = 0, largest_free = 0;
  bool checked_end = false;
  while (t < 2 * settle) {
    for (SphModel* model : {&settling, &free}) model->compute_internal_forces(dt_previous);
    const double dt = settling.stable_dt();  // both models take the same steps
    for (SphModel* model : {&settling, &free}) model->integrate(dt_previous, dt);
    t += dt;
    dt_previous = dt;
    ASSERT_EQ(settling.time(), t);
    for (std::size_t i = 0; i < settling.size(); ++i) {
      if (settling.body_index()[i] == 1) {
        const Vec3 v = settling.velocities()[i], v_free = free.velocities()[i];
        ASSERT_LE((v - v_free).norm(), 1e-5 * 9.81 * t) << "falling particle " << i << " at t = " << t;
      } else if (t < settle) {
        largest_settling = std::max(largest_settling, settling.velocities()[i].norm());
        largest_free = std::max(largest_free, free.velocities()[i].norm());
      } else if (t - dt < settle) {
        ASSERT_EQ(settling.velocities()[i], Vec3::Zero()) << "settling particle " << i << " after the last step";
        checked_end = true;
      }
    }
  }
  // A damped free fall reaches at most g tau, tau at its largest kSettleDampingGrowth h / c.
  const double terminal = 9.81 * scene::kSettleDampingGrowth * settling.kernel().h / c;
  std::cout << "settling body in free fall, largest speed during the phase: " << largest_settling
            << " m/s, expected below the damped terminal speed " << terminal << " m/s; undamped " << largest_free
            << " m/s (a free fall to " << 9.81 * settle << " m/s)\n";
  EXPECT_TRUE(checked_end);
  EXPECT_LT(largest_settling, terminal);
  EXPECT_GT(largest_free, 0.9 * 9.81 * settle);
}

// The same tank started from the hydrostatic fill without settling: the top rows' imbalance
// (the fill is the continuum's equilibrium, not the particles') starts a transient of
// 1.4e-3 sqrt(gH), above the benchmark's 1e-3 (docs/physics.md, "S4's start-up"); held to
// 2e-3, and to 1e-3 in the second half, to t = 10 sqrt(H/g).
TEST(SphValidation, S4HydrostaticTankStartUpWithoutSettling) {
  const double H = 0.2, g = 9.81, T = std::sqrt(H / g), U = std::sqrt(g * H);
  const S4Figures f = run_s4_tank(10 * T, 0);
  std::cout << "S4 without settling, largest speed / sqrt(gH): measured " << f.max_speed / U << " from t = 0, "
            << f.max_speed_late / U << " in the second half (benchmark 1e-3 from t = 0; held here to 2e-3, and "
            << "1e-3 in the second half); pressure L2 error " << 100 * f.pressure_error << " %; energy: initial "
            << f.initial_energy << " J, largest " << f.max_energy << " J\n";
  EXPECT_LT(f.max_speed, 2e-3 * U);
  EXPECT_LT(f.max_speed_late, 1e-3 * U);
  EXPECT_LT(f.pressure_error, 0.02);
  EXPECT_LE(f.max_energy, f.initial_energy);
}

// Newton's third law between fluid and walls, and the same bits on 1 and 2 threads.
TEST(SphModelContract, WallForcesBalanceAndRunsAreDeterministic) {
  const double dx = 0.02;
  const auto run = [&](int threads, SphModel& model) {
    omp_set_num_threads(threads);
    model.set_boundary(container_walls(Vec3(0, 0, 0), Vec3(0.4, 0.2, 0.4), dx, 3));
    run_until(model, 0.02, [](double) {});
    model.compute_internal_forces(0);
  };
  scene::Scene s = water_scene(dx, 20.0);
  s.fluids.push_back(box_body("column", Vec3(0, 0, 0), Vec3(0.2, 0.2, 0.3)));  // collapses: not at rest
  SphModel one(s), two(s);
  run(1, one);
  run(2, two);
  omp_set_num_threads(2);
  ASSERT_EQ(one.size(), two.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    ASSERT_EQ(one.positions()[i], two.positions()[i]) << "particle " << i;
    ASSERT_EQ(one.velocities()[i], two.velocities()[i]) << "particle " << i;
    ASSERT_EQ(one.densities()[i], two.densities()[i]) << "particle " << i;
  }
  for (std::size_t b = 0; b < one.boundary().size(); ++b) ASSERT_EQ(one.boundary_forces()[b], two.boundary_forces()[b]);
  // Fluid-fluid terms cancel in pairs: the fluid's momentum change minus gravity is the wall force.
  const auto [fluid, wall, mass] = testing::wall_force_balance(one, s.run.gravity);
  // The fluid-fluid pair terms are single precision and the masses differ (rho dx^3, with the
  // depth), so they cancel to the float rounding of a mass (6e-8), not to double rounding.
  std::cout << "wall force on fluid: " << fluid.transpose() << " N, on walls: " << wall.transpose()
            << " N (expected opposite, within 1e-7 relative; measured " << (fluid + wall).norm() / fluid.norm()
            << ")\n";
  EXPECT_LT((fluid + wall).norm(), 1e-7 * fluid.norm());
}

// Penalty walls as the coupler computes them for an sph_fem pair (SurfaceContact, paper
// eqs. 3-6): contact radius dx/2 (what the sph_solver sends), no friction, an explicit
// stiffness k_n (N/m) and damping ratio zeta. One part per plane, so that out.part_force gives each wall's load.
struct PenaltyWalls {
  PenaltyWalls(SphModel& fluid, const std::string& source, const geometry::SurfaceMesh& surface, double stiffness,
               double damping_ratio = 0.0)
      : model(fluid),
        contact({source},
                [stiffness, damping_ratio](const std::string&, const std::string&) {
                  scene::SurfaceContact pair;
                  pair.friction = 0;
                  pair.normal_stiffness = stiffness;
                  pair.normal_damping_ratio = damping_ratio;
                  return pair;
                }),
        ids(fluid.size()),
        indices(fluid.size()),
        radius(fluid.size(), 0.5 * fluid.settings().particle_spacing),
        position(3 * fluid.size()),
        velocity(3 * fluid.size()) {
    contact.set_surface(surface);
    for (std::size_t i = 0; i < fluid.size(); ++i) ids[i] = indices[i] = static_cast<std::uint32_t>(i);
  }
  // Adds the contact forces at x_n to the model (after compute_internal_forces); returns the
  // contact's stable dt.
  double apply(double dt_previous) {
    for (std::size_t i = 0; i < model.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        position[3 * i + k] = model.positions()[i][k];
        velocity[3 * i + k] = model.velocities()[i][k];
      }
    }
    const contact::ParticleView view{ids, position, velocity, {}, radius, model.masses(), {}, {}};
    contact.compute(view, dt_previous, out);
    model.add_external_forces(indices, out.particle_force);
    return contact.stable_dt();
  }
  SphModel& model;
  contact::SurfaceContact contact;
  std::vector<std::uint64_t> ids;
  std::vector<std::uint32_t> indices;
  std::vector<double> radius, position, velocity;
  contact::ContactOutput out;
};

// The floor and four sides of the container [min, max] as planes, normals inward, parts
// "floor", "x_min", "x_max", "y_min", "y_max" in that order.
geometry::SurfaceMesh container_planes(const Vec3& min, const Vec3& max) {
  geometry::SurfaceMesh planes;
  const Vec3 size = max - min, centre = 0.5 * (min + max);
  const auto plane = [&](const std::string& name, const Vec3& origin, const Vec3& normal, const Vec3& direction,
                         double length, double width) {
    scene::Shape shape;
    shape.type = scene::Shape::Type::plane;
    shape.origin = origin;
    shape.normal = normal;
    shape.direction = direction;
    shape.length = length;
    shape.width = width;
    planes.append(geometry::triangulate(shape, name));
  };
  plane("floor", Vec3(centre.x(), centre.y(), min.z()), Vec3(0, 0, 1), Vec3(1, 0, 0), size.x(), size.y());
  plane("x_min", Vec3(min.x(), centre.y(), centre.z()), Vec3(1, 0, 0), Vec3(0, 1, 0), size.y(), size.z());
  plane("x_max", Vec3(max.x(), centre.y(), centre.z()), Vec3(-1, 0, 0), Vec3(0, 1, 0), size.y(), size.z());
  plane("y_min", Vec3(centre.x(), min.y(), centre.z()), Vec3(0, 1, 0), Vec3(1, 0, 0), size.x(), size.z());
  plane("y_max", Vec3(centre.x(), max.y(), centre.z()), Vec3(0, -1, 0), Vec3(1, 0, 0), size.x(), size.z());
  return planes;
}

// S1 dam break (Martin & Moyce 1952, n^2 = 2), reduced: a = 0.1 m, dx = a/10, a
// channel 4 dx wide with free-slip side walls (inviscid fluid: quasi 2-D), walls
// either boundary particles or the coupler's penalty contact (SurfaceContact, the
// kernel the coupler runs for sph_fem pairs) against the five planes of the channel.
constexpr double kMaxShift = 0.6;
struct DamBreakResult {
  double error = 0, error_unshifted = 0, shift = 0, e0 = 0, e_max = 0;
  std::size_t lost = 0;
};

DamBreakResult dam_break(bool penalty_walls, const char* csv_variable) {
  const double a = 0.1, H = 2 * a, dx = a / 10, g = 9.81, W = 4 * dx, length = 6 * a;
  scene::Scene s = water_scene(dx, 10.0 * std::sqrt(2 * g * H));
  s.sph.artificial_viscosity = 0.02;
  if (penalty_walls) s.sph.wall_model = scene::SphSettings::WallModel::penalty;
  s.fluids.push_back(box_body("column", Vec3(0, 0, 0), Vec3(a, W, H)));
  SphModel model(s);
  // Penalty: planes of the channel, normals into the fluid; contact radius dx/2 (what the
  // sph_solver sends), no friction, k = 4000 N/m: the bottom particle's share of the
  // column's weight, rho g H dx^2 = 0.2 N, presses it 5e-5 m = dx/200 in.
  const double top = 1.5 * H;
  PenaltyWalls walls(model, "column", container_planes(Vec3(0, 0, 0), Vec3(length, W, top)), 4000.0);
  if (!penalty_walls) model.set_boundary(container_walls(Vec3(0, 0, 0), Vec3(length, W, top), dx, 3));

  const double time_scale = std::sqrt(a / (2 * g));  // t = T * time_scale
  const double T_ref[] = {0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83, 2.98, 3.11, 3.33};
  const double Z_ref[] = {1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44, 3.67, 3.89, 4.11};
  std::vector<std::pair<double, double>> front;  // (T, Z)
  DamBreakResult result;
  result.e0 = result.e_max = model.energies().total();
  double t = 0, dt_previous = 0;
  // To T = 3.33 + kMaxShift: the largest shift searched below.
  while (t < (3.33 + kMaxShift + 0.02) * time_scale) {
    model.compute_internal_forces(dt_previous);
    double dt = model.stable_dt();
    if (penalty_walls) dt = std::min(dt, walls.apply(dt_previous));
    model.integrate(dt_previous, dt);
    t += dt;
    dt_previous = dt;
    double x_max = 0;
    for (std::size_t i = 0; i < model.size(); ++i) x_max = std::max(x_max, model.positions()[i].x());
    front.emplace_back(t / time_scale, (x_max + 0.5 * dx) / a);
    // The contact springs' energy belongs to the total, as in the coupler's accounting.
    result.e_max = std::max(result.e_max, model.energies().total() + (penalty_walls ? walls.out.elastic_energy : 0.0));
  }
  // RMS relative error over 0.84 <= T <= 3.33, best time shift searched over |s| <= kMaxShift
  // (the experiment's gate lag); the check below holds |s| <= 0.3, so it can fail.
  const auto error_with_shift = [&](double shift) {
    double sum = 0;
    int count = 0;
    for (std::size_t k = 1; k < std::size(T_ref); ++k) {
      const double T = T_ref[k] + shift;
      auto it = std::lower_bound(front.begin(), front.end(), std::make_pair(T, -1e9));
      if (it == front.end() || it == front.begin()) return 1e9;
      const auto& [t1, z1] = *(it - 1);
      const auto& [t2, z2] = *it;
      const double Z = z1 + (z2 - z1) * (T - t1) / (t2 - t1);
      sum += std::pow((Z - Z_ref[k]) / Z_ref[k], 2);
      ++count;
    }
    return std::sqrt(sum / count);
  };
  result.error_unshifted = result.error = error_with_shift(0);
  for (int k = -60; k <= 60; ++k) {
    const double shift = 0.01 * k;
    if (const double e = error_with_shift(shift); e < result.error) {
      result.error = e;
      result.shift = shift;
    }
  }
  // SABO_S1_FRONT_CSV=FILE (boundary particles) and SABO_S1_PENALTY_FRONT_CSV=FILE keep the
  // front history for scripts/plot_s1_front.py.
  if (const char* csv = std::getenv(csv_variable)) {
    std::ofstream file(csv);
    file << "T,Z\n";
    for (const auto& [T, Z] : front) file << T << "," << Z << "\n";
  }
  result.lost = model.lost_count();
  return result;
}

void check_dam_break(const char* walls, const DamBreakResult& r) {
  std::cout << "S1 front RMS error, " << walls << ": measured " << 100 * r.error_unshifted << " % without shift, "
            << 100 * r.error << " % with shift " << r.shift << " in T (searched over +-" << kMaxShift
            << "); expected <= 8 % and |shift| <= 0.3\n";
  std::cout << "S1 energy, " << walls << " (kinetic + potential + compression): initial " << r.e0 << " J, largest "
            << r.e_max << " J (expected not above initial by more than 0.1 %: density diffusion changes density "
            << "without work)\n";
  EXPECT_LT(r.error, 0.08);
  EXPECT_LE(std::abs(r.shift), 0.3);
  EXPECT_LE(r.e_max, r.e0 * 1.001);
  EXPECT_EQ(r.lost, 0u);
}

TEST(SphValidation, S1DamBreakFrontWithBoundaryParticles) {
  check_dam_break("boundary particles", dam_break(false, "SABO_S1_FRONT_CSV"));
}

TEST(SphValidation, S1DamBreakFrontWithPenaltyWalls) {
  check_dam_break("penalty walls", dam_break(true, "SABO_S1_PENALTY_FRONT_CSV"));
}

// S4 with penalty walls (the paper's way), the same tank and run as above, cubic spline at
// h = 1.3 dx: the figures the benchmark asks to report. The wall keeps the fluid out but the
// kernel sums of the particles next to it are cut off: the fluid next to the walls is pushed
// towards them, the lattice churns (0.4 sqrt(gH)), the pressure is off by 13 % of rho g H and
// the side walls carry 9 % too little. Held here to those figures (regressions) and to the
// tank's equilibrium: the floor carries the weight within the benchmark's 1 %.
TEST(SphValidation, S4HydrostaticTankWithPenaltyWalls) {
  const double H = 0.2, dx = 0.02, g = 9.81, L = 0.2, W = 0.1;
  scene::Scene scene = s4_tank_scene(dx, L, W, H, g);
  scene.sph.wall_model = scene::SphSettings::WallModel::penalty;
  SphModel model(scene);
  // k = 4000 N/m: the bottom particle's share of the weight, rho g H dx^2 = 0.78 N, presses it
  // 2e-4 m = dx/100 in; zeta = 0.5 as in configs/tests/sph_tank_penalty.toml.
  PenaltyWalls walls(model, "water", container_planes(Vec3(0, 0, 0), Vec3(L, W, H + 4 * dx)), 4000.0, 0.5);
  const double t_end = 10.0 * std::sqrt(H / g);
  double t = 0, dt_previous = 0, max_speed = 0, max_speed_late = 0, bottom = 0, side = 0, samples = 0;
  while (t < t_end) {
    model.compute_internal_forces(dt_previous);
    const double dt = std::min(model.stable_dt(), walls.apply(dt_previous));
    model.integrate(dt_previous, dt);
    t += dt;
    dt_previous = dt;
    for (const Vec3& v : model.velocities()) max_speed = std::max(max_speed, v.norm());
    if (t < 0.5 * t_end) continue;
    for (const Vec3& v : model.velocities()) max_speed_late = std::max(max_speed_late, v.norm());
    if (t < 0.75 * t_end) continue;
    bottom -= walls.out.part_force[0].z();  // parts: floor, x_min, x_max, y_min, y_max
    side -= walls.out.part_force[1].x();
    samples += 1;
  }
  bottom /= samples;
  side /= samples;
  const double error = hydrostatic_pressure_error(model, H, g);
  const double weight = 1000 * g * H * L * W, side_expected = 1000 * g * H * H * W / 2;
  double vertical = 0;
  for (const Vec3& f : walls.out.part_force) vertical -= f.z();
  std::cout << "S4 penalty walls, pressure L2 error: measured " << 100 * error
            << " % of rho g H (benchmark 2 %, held here to 15 %)\n";
  std::cout << "S4 penalty walls, largest speed / sqrt(gH): measured " << max_speed / std::sqrt(g * H)
            << " over the run, " << max_speed_late / std::sqrt(g * H)
            << " in the second half (benchmark 1e-3, held here to 0.5)\n";
  std::cout << "S4 penalty walls, bottom force (mean of the last quarter): measured " << bottom << " N, expected "
            << weight << " N (benchmark 1 %)\n";
  std::cout << "S4 penalty walls, side force (mean of the last quarter): measured " << side << " N, expected "
            << side_expected << " N (benchmark 2 %, held here to 12 %)\n";
  std::cout << "S4 penalty walls, vertical force on all walls at the last step: " << vertical << " N vs weight "
            << weight << " N\n";
  EXPECT_LT(error, 0.15);
  EXPECT_LT(max_speed_late, 0.5 * std::sqrt(g * H));
  EXPECT_NEAR(bottom / weight, 1.0, 0.01);
  EXPECT_NEAR(side / side_expected, 1.0, 0.12);
  EXPECT_EQ(model.lost_count(), 0u);
}

}  // namespace
}  // namespace sabo::sph

namespace sabo::sph {
namespace {

// Shear traction of the stress extrapolated onto the side-wall particles (horizontal
// normal n, 0 < z < top), |t - (t.n) n| with t = S_w n, and the same of S_w - <S_f>, the
// growth from the fluid's kernel average <S_f> = sum_f S_f W / sum_f W to the wall (Pa):
// returns the largest traction, the mean traction and the mean growth.
struct WallShear {
  double largest = 0, mean = 0, mean_growth = 0;
};
WallShear side_wall_shear(const SphModel& model, double top) {
  const auto& walls = model.boundary();
  const auto wall_stress = model.boundary_stresses();
  const auto fluid_stress = model.deviatoric_stress();
  const auto tangential = [](const Mat3& S, const Vec3& n) {
    const Vec3 t = S * n;
    return (t - t.dot(n) * n).norm();
  };
  const auto tensor = [](const double* s) {
    Mat3 S;
    S << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
    return S;
  };
  WallShear out;
  int count = 0;
  for (std::size_t b = 0; b < walls.size(); ++b) {
    const Vec3& n = walls.normal[b];
    const double z = walls.position[b].z();
    if (std::abs(n.z()) > 1e-9 || z <= 0 || z >= top) continue;
    Mat3 mean_fluid = Mat3::Zero();
    double sum_w = 0;
    for (std::size_t i = 0; i < model.size(); ++i) {
      const double r = (model.positions()[i] - walls.position[b]).norm();
      if (r >= model.kernel().support()) continue;
      const double w = model.kernel().value(r);
      mean_fluid += w * tensor(&fluid_stress[6 * i]);
      sum_w += w;
    }
    if (sum_w <= 0) continue;
    const Mat3 S_w = tensor(&wall_stress[6 * b]);
    const double shear = tangential(S_w, n);
    out.largest = std::max(out.largest, shear);
    out.mean += shear;
    out.mean_growth += tangential(S_w - mean_fluid / sum_w, n);
    ++count;
  }
  if (count > 0) {
    out.mean /= count;
    out.mean_growth /= count;
  }
  return out;
}

// An elastic-plastic column at rest in a tank with boundary-particle walls. The wall stress
// is the fluid's extrapolated with its growth along the normal, d(S.n)_t/dn = rho (a - g)_t +
// (grad p)_t (docs/physics.md); without the pressure gradient the vertical walls got a false
// shear rho g d_n: measured before the fix, at the start (S = 0 everywhere) largest 438 Pa,
// mean 179 Pa (rho g dx = 196 Pa). After the start the column has its own stress (it settles
// elastically against no-slip walls), and the growth from the fluid's average to the wall
// is printed, not held: it leaves out the divergence of S along the wall (docs/physics.md),
// which the settled column has. Not held either: the top rows of an elastic free surface
// jitter (largest speed printed).
TEST(SphValidation, ElasticPlasticColumnAtRestPutsNoFalseShearOnVerticalWalls) {
  const double H = 0.2, dx = 0.02, g = 9.81, L = 0.2, W = 0.1, rho = 1000;
  scene::Scene s = s4_tank_scene(dx, L, W, H, g);
  scene::Material& m = s.materials[0];
  m.rheology = scene::Material::Rheology::elastic_plastic;
  m.yield_stress = 580;  // Pa, the S8 slurry's (sigma_y = sqrt(3) tau_y)
  m.fluid_shear_modulus = 1e5;
  SphModel model(s);
  model.set_boundary(container_walls(Vec3(0, 0, 0), Vec3(L, W, H + 4 * dx), dx, 3));
  model.compute_internal_forces(0);
  // Below the top rows.
  const double submerged = H - 2 * model.kernel().h;
  const WallShear start = side_wall_shear(model, submerged);
  double max_speed = 0;
  run_until(model, 2.0 * std::sqrt(H / g), [&](double) {
    for (const Vec3& v : model.velocities()) max_speed = std::max(max_speed, v.norm());
  });
  model.compute_internal_forces(0);
  const WallShear end = side_wall_shear(model, submerged);
  const double scale = rho * g * dx;
  std::cout << "side-wall shear traction, elastic-plastic column at rest, at the start: measured largest "
            << start.largest << " Pa, mean " << start.mean
            << " Pa; expected 0 (held to 0.05 rho g dx = " << 0.05 * scale << " Pa)\n";
  std::cout << "after 2 sqrt(H/g): traction largest " << end.largest << " Pa, mean " << end.mean
            << " Pa; growth from the fluid's average to the wall: measured mean " << end.mean_growth
            << " Pa (the divergence of S along the wall is left out; not held)\n";
  std::cout << "largest speed over the run: " << max_speed / std::sqrt(g * H)
            << " sqrt(gH) (the jitter of the top rows; not held)\n";
  EXPECT_LT(start.largest, 0.05 * scale);
}

}  // namespace
}  // namespace sabo::sph
