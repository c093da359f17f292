// Stability runs of SphModel (issue 3): a hydrostatic tank for 100 000 steps,
// and a dam break that strikes the end wall of a short tank at full speed.
// Prints, for each: steps, largest speed, particles that left the domain, the
// largest total energy (kinetic + potential + compression) over the
// initial one, and the density range at the end.
//   bench_sph_stability [--steps N] [--impact-time T] [--kernel cubic_spline|wendland_c2] [--ratio h/dx]
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>

#include "sph_solver/sph_model.hpp"

namespace {

using namespace sabo;

scene::SphSettings::Kernel kernel_choice = scene::SphSettings::Kernel::wendland_c2;
double smoothing_ratio = 1.5;

scene::Scene water(double dx, double c, const Aabb& domain) {
  scene::Scene s;
  scene::Material m;
  m.name = "water";
  m.density = 1000;
  m.youngs_modulus = 1e9;
  m.poisson_ratio = 0.3;
  s.materials.push_back(m);
  s.sph.particle_spacing = dx;
  s.sph.sound_speed = c;
  s.sph.domain = domain;
  s.sph.kernel = kernel_choice;
  s.sph.smoothing_ratio = smoothing_ratio;
  return s;
}

physics::BoundaryParticles tank(const Vec3& min, const Vec3& max, double dx, int layers) {
  physics::BoundaryParticles walls;
  const Vec3 lo = min - Vec3::Constant(layers * dx), hi(max.x() + layers * dx, max.y() + layers * dx, max.z());
  const auto count = [&](double e) { return static_cast<int>(std::floor(e / dx + 1e-9)); };
  for (int k = 0; k < count(hi.z() - lo.z()); ++k)
    for (int j = 0; j < count(hi.y() - lo.y()); ++j)
      for (int i = 0; i < count(hi.x() - lo.x()); ++i) {
        const Vec3 p = lo + dx * Vec3(i + 0.5, j + 0.5, k + 0.5);
        if ((p.array() > min.array()).all() && (p.array() < max.array()).all()) continue;
        // Normal into the fluid: towards the nearest point of the container (floor, wall, edge).
        const Vec3 inner = p.cwiseMax(min).cwiseMin(max);
        walls.position.push_back(p);
        walls.velocity.push_back(Vec3::Zero());
        walls.normal.push_back((inner - p).normalized());
        walls.acceleration.push_back(Vec3::Zero());
        walls.volume.push_back(dx * dx * dx);
      }
  return walls;
}

void run(const char* name, sph::SphModel& model, long steps_limit, double time_limit) {
  const double e0 = model.energies().total();
  double e_max = e0, v_max = 0, v_max_late = 0, t = 0, dt_previous = 0;
  long steps = 0;
  while (steps < steps_limit && t < time_limit) {
    model.compute_internal_forces(dt_previous);
    const double dt = model.stable_dt();
    model.integrate(dt_previous, dt);
    dt_previous = dt;
    t += dt;
    ++steps;
    e_max = std::max(e_max, model.energies().total());
    // Second half: of the steps for a step-limited run, of the time for a time-limited one.
    const bool late = time_limit > 1e29 ? 2 * steps > steps_limit : 2 * t > time_limit;
    for (const Vec3& v : model.velocities()) {
      v_max = std::max(v_max, v.norm());
      if (late) v_max_late = std::max(v_max_late, v.norm());
    }
  }
  const auto [rho_min, rho_max] = std::minmax_element(model.densities().begin(), model.densities().end());
  fmt::print(
      "{}: steps {} t {:.4f} s, particles {}, largest speed {:.4g} m/s ({:.4g} in the second half), left the domain "
      "{}, largest energy - initial {:.4g} J (initial {:.6g} J), density {:.2f}..{:.2f} kg/m^3\n",
      name, steps, t, model.size(), v_max, v_max_late, model.lost_count(), e_max - e0, e0, *rho_min, *rho_max);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("SPH stability runs");
  long steps = 100000;
  double impact_time = 1.0;
  app.add_option("--steps", steps, "steps of the hydrostatic run");
  app.add_option("--impact-time", impact_time, "simulated time of the wall impact run, s");
  std::string kernel = "wendland_c2";
  app.add_option("--kernel", kernel, "wendland_c2 or cubic_spline")
      ->check(CLI::IsMember({"wendland_c2", "cubic_spline"}));
  app.add_option("--ratio", smoothing_ratio, "h / dx");
  CLI11_PARSE(app, argc, argv);
  if (kernel == "cubic_spline") kernel_choice = scene::SphSettings::Kernel::cubic_spline;
  fmt::print("kernel {}, h = {} dx\n", kernel, smoothing_ratio);
  {
    const double H = 0.2, dx = 0.02, L = 0.2, W = 0.1;
    scene::Scene s = water(dx, 10 * std::sqrt(9.81 * H), Aabb{Vec3(-0.1, -0.1, -0.1), Vec3(0.3, 0.2, 0.4)});
    s.sph.artificial_viscosity = 0.1;
    scene::FluidBody body;
    body.name = "water";
    body.material = "water";
    body.box = Aabb{Vec3::Zero(), Vec3(L, W, H)};
    s.fluids.push_back(body);
    sph::SphModel model(s);
    model.set_boundary(tank(Vec3::Zero(), Vec3(L, W, H + 4 * dx), dx, 3));
    run("hydrostatic tank", model, steps, 1e30);
  }
  {
    // Column a x 4dx x 2a in a tank 2a long: the surge hits the end wall at about sqrt(2 g H).
    const double a = 0.1, dx = a / 10, W = 4 * dx;
    scene::Scene s =
        water(dx, 10 * std::sqrt(2 * 9.81 * 2 * a), Aabb{Vec3(-0.05, -0.05, -0.05), Vec3(0.25, W + 0.05, 0.65)});
    s.sph.artificial_viscosity = 0.02;
    scene::FluidBody body;
    body.name = "column";
    body.material = "water";
    body.box = Aabb{Vec3::Zero(), Vec3(a, W, 2 * a)};
    s.fluids.push_back(body);
    sph::SphModel model(s);
    model.set_boundary(tank(Vec3::Zero(), Vec3(2 * a, W, 0.6), dx, 3));
    run("wall impact", model, 100000000, impact_time);
  }
  return 0;
}
