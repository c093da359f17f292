// FEM throughput: element-steps per second of the deformable kernels alone
// (no protocol, no output). Prints one JSON line.
//
// hex: a cube of the paper's dam material (docs/model.md: rho 2300, E 8 GPa, nu
//   0.23, yield 8 MPa, plastic kinematic with tangent modulus 0.8 GPa) meshed
//   n x n x n with one-point hexahedra (--formulation fully_integrated or
//   enhanced_strain: 2 x 2 x 2 points), its base fixed, moving at 5 m/s against it: elements yield
//   from the first steps.
// shell: a square brick wall (240 mm BLT shells, 5 points through the
//   thickness, the same material; --formulation fully_integrated: 2 x 2
//   in-plane points, MITC4 shear) of n x n elements, edges clamped, struck
//   out of plane at 5 m/s.
// dt = 0.9 * stable dt. Element-steps per second = elements * steps / wall time.
//
//   bench_fem_throughput --kind hex --elements 32768 --steps 50 [--formulation fully_integrated|enhanced_strain]
//   bench_fem_throughput --kind shell --elements 16384 --steps 50 [--formulation fully_integrated]
#include <fmt/format.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>

#include "fem_solver/shell_body.hpp"
#include "fem_solver/solid_body.hpp"

using namespace sabo;
using namespace sabo::fem;
using Clock = std::chrono::steady_clock;

namespace {

MaterialParameters dam_material() {
  MaterialParameters m;
  m.density = 2300;
  m.youngs_modulus = 8e9;
  m.poisson_ratio = 0.23;
  m.yield_stress = 8e6;
  m.tangent_modulus = 0.8e9;
  m.hardening = 0.5;
  return m;
}

template <class Body>
double run(Body& body, int warmup, int steps) {
  const double dt = 0.9 * body.stable_dt();
  double dt_previous = 0;
  for (int n = 0; n < warmup; ++n) {
    body.compute_internal_forces(dt_previous);
    body.integrate(dt_previous, dt);
    dt_previous = dt;
  }
  const auto start = Clock::now();
  for (int n = 0; n < steps; ++n) {
    body.compute_internal_forces(dt_previous);
    body.integrate(dt_previous, dt);
    dt_previous = dt;
  }
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  std::string kind = "hex";
  long elements = 32768;
  int steps = 50, warmup = 5;
  std::string formulation = "one_point";
  CLI::App app{"FEM throughput: element-steps per second of hexahedra or shells."};
  app.add_option("--kind", kind, "hex or shell")->check(CLI::IsMember({"hex", "shell"}))->capture_default_str();
  app.add_option("--elements", elements, "elements, about (a cube n^3 or a square n^2)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--steps", steps, "timed steps")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--warmup", warmup, "steps before timing")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--formulation", formulation,
                 "one_point, fully_integrated (hexahedra and shells) or enhanced_strain (hexahedra)")
      ->check(CLI::IsMember({"one_point", "fully_integrated", "enhanced_strain"}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (kind == "shell" && formulation == "enhanced_strain") {
    fmt::print(stderr,
               "--formulation enhanced_strain is for hexahedra: use --kind hex, or one_point or "
               "fully_integrated for shells\n");
    return 2;
  }

  double wall = 0;
  std::size_t count = 0;
  double plastic_fraction = 0;
  const auto setup_start = Clock::now();
  double setup = 0;
  if (kind == "hex") {
    const auto n = static_cast<std::size_t>(std::max(1.0, std::round(std::cbrt(static_cast<double>(elements)))));
    SolidBody body(structured_box(Aabb{Vec3::Zero(), Vec3(2, 2, 2)}, {n, n, n}), dam_material(),
                   formulation == "fully_integrated"  ? HexFormulation::fully_integrated
                   : formulation == "enhanced_strain" ? HexFormulation::enhanced_strain
                                                      : HexFormulation::one_point);
    body.fix_in_box(Aabb{Vec3(-1, -1, -1e-9), Vec3(3, 3, 1e-9)}, dof_all);
    body.set_velocity(Vec3(0, 0, -5));
    setup = std::chrono::duration<double>(Clock::now() - setup_start).count();
    wall = run(body, warmup, steps);
    count = body.element_count();
    for (std::size_t e = 0; e < count; ++e) plastic_fraction += body.element_state(e).point.plastic_strain > 0;
  } else {
    const auto n = static_cast<std::size_t>(std::max(1.0, std::round(std::sqrt(static_cast<double>(elements)))));
    ShellMesh mesh;
    add_panel(mesh, Vec3::Zero(), Vec3(6, 0, 0), Vec3(0, 0, 6), n, n, 0.24, 0);
    ShellBody body(
        mesh, {dam_material()},
        formulation == "fully_integrated" ? ShellFormulation::fully_integrated : ShellFormulation::one_point);
    for (const Aabb& edge : {Aabb{Vec3(-1, -1, -1), Vec3(1e-9, 1, 7)}, Aabb{Vec3(6 - 1e-9, -1, -1), Vec3(7, 1, 7)},
                             Aabb{Vec3(-1, -1, -1), Vec3(7, 1, 1e-9)}, Aabb{Vec3(-1, -1, 6 - 1e-9), Vec3(7, 1, 7)}}) {
      body.fix_in_box(edge, dof_all | rotations_all);
    }
    body.set_velocity(Vec3(0, 5, 0));
    setup = std::chrono::duration<double>(Clock::now() - setup_start).count();
    wall = run(body, warmup, steps);
    count = body.element_count();
    for (std::size_t e = 0; e < count; ++e) plastic_fraction += body.element_state(e).point[0].plastic_strain > 0;
  }
  plastic_fraction /= static_cast<double>(count);
  fmt::print(
      "{{\"bench\": \"fem_throughput\", \"kind\": \"{}\", \"formulation\": \"{}\", \"elements\": {}, \"steps\": {}, "
      "\"threads\": {}, "
      "\"element_steps_per_second\": {:.0f}, \"microseconds_per_step\": {:.1f}, \"plastic_fraction\": {:.3f}, "
      "\"wall_seconds\": {:.3f}, \"setup_seconds\": {:.3f}}}\n",
      kind, formulation, count, steps, omp_get_max_threads(), static_cast<double>(count) * steps / wall,
      1e6 * wall / steps, plastic_fraction, wall, setup);
  return 0;
}
