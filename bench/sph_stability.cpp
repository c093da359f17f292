// Stability runs of SphModel (issue 3): a hydrostatic tank for 100 000 steps,
// and a dam break that strikes the end wall of a short tank at full speed.
// Prints, for each: steps, largest speed, particles that left the domain, the
// largest total energy (kinetic + potential + compression) over the
// initial one, and the density range at the end.
//   bench_sph_stability [--steps N] [--impact-time T] [--kernel cubic_spline|wendland_c2] [--ratio h/dx]
//                       [--diffusion none|molteni|fourtakas] [--trace N] [--settle T]
//                       [--wall-work bounded|stored|unstored]
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>

#include "libsabo/scene/names.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

namespace {

using namespace sabo;

scene::SphSettings::Kernel kernel_choice = scene::SphSettings::Kernel::wendland_c2;
double smoothing_ratio = 1.5;
long trace_every = 0;       // steps between trace lines; 0: none
double settle_periods = 0;  // the tank's settling phase, sqrt(H/g)
scene::SphSettings::WallWork wall_work_choice = scene::SphSettings::WallWork::bounded;
scene::SphSettings::DensityDiffusion diffusion_choice = scene::SphSettings::DensityDiffusion::fourtakas;

scene::Scene water(double dx, double c, const Aabb& domain) {
  scene::Scene s = sph::testing::water_scene(dx, c, smoothing_ratio);
  s.sph.domain = domain;
  s.sph.kernel = kernel_choice;
  s.sph.density_diffusion = diffusion_choice;
  s.sph.wall_work = wall_work_choice;
  return s;
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
    if (trace_every > 0 && steps % trace_every == 0) {
      const sph::Energies e = model.energies();
      fmt::print("  {} t {:.5f} s: E - E0 {:+.4e} J (kinetic {:.5e}, potential {:.6e}, compression {:.5e})\n", name, t,
                 e.total() - e0, e.kinetic, e.potential, e.elastic);
    }
    // Second half: of the steps for a step-limited run, of the time for a time-limited one.
    const bool late = time_limit > 1e29 ? 2 * steps > steps_limit : 2 * t > time_limit;
    for (const Vec3& v : model.velocities()) {
      v_max = std::max(v_max, v.norm());
      if (late) v_max_late = std::max(v_max_late, v.norm());
    }
  }
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (model.active()[i] == 0) {
      const Vec3& x = model.positions()[i];
      const Vec3& v = model.velocities()[i];
      fmt::print(
          "  left the domain: particle {} at ({:.4f}, {:.4f}, {:.4f}) m, velocity ({:.3f}, {:.3f}, {:.3f}) m/s\n", i,
          x.x(), x.y(), x.z(), v.x(), v.y(), v.z());
    }
  }
  const auto [rho_min, rho_max] = std::minmax_element(model.densities().begin(), model.densities().end());
  fmt::print(
      "{}: steps {} t {:.4f} s, particles {}, largest speed {:.4g} m/s ({:.4g} in the second half), left the domain "
      "{}, largest energy - initial {:.4g} J (initial {:.6g} J), walls' work held back {:.4g} J, density "
      "{:.2f}..{:.2f} kg/m^3\n",
      name, steps, t, model.size(), v_max, v_max_late, model.lost_count(), e_max - e0, e0, model.energies().wall_held,
      *rho_min, *rho_max);
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
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::Kernel>()));
  app.add_option("--ratio", smoothing_ratio, "h / dx");
  app.add_option("--trace", trace_every, "print the energies every N steps (0: never)");
  app.add_option("--settle", settle_periods, "the tank's settling phase from t = 0, sqrt(H/g)");
  std::string diffusion = "fourtakas";
  app.add_option("--diffusion", diffusion, "density diffusion")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::DensityDiffusion>()));
  std::string wall_work = "bounded";
  app.add_option("--wall-work", wall_work, "sph.wall_work: what becomes of the walls' work")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::WallWork>()));
  CLI11_PARSE(app, argc, argv);
  kernel_choice = scene::value_named<scene::SphSettings::Kernel>(kernel);
  diffusion_choice = scene::value_named<scene::SphSettings::DensityDiffusion>(diffusion);
  wall_work_choice = scene::value_named<scene::SphSettings::WallWork>(wall_work);
  fmt::print("kernel {}, h = {} dx, wall_work {}\n", kernel, smoothing_ratio, wall_work);
  {
    const double H = 0.2, dx = 0.02, L = 0.2, W = 0.1;
    scene::Scene s = water(dx, 10 * std::sqrt(9.81 * H), Aabb{Vec3(-0.1, -0.1, -0.1), Vec3(0.3, 0.2, 0.4)});
    s.sph.artificial_viscosity = 0.1;
    s.fluids.push_back(sph::testing::box_body("water", Vec3::Zero(), Vec3(L, W, H)));
    s.fluids.back().settle_time = settle_periods * std::sqrt(H / 9.81);
    sph::SphModel model(s);
    model.set_boundary(sph::testing::container_walls(Vec3::Zero(), Vec3(L, W, H + 4 * dx), dx, 3));
    run("hydrostatic tank", model, steps, 1e30);
  }
  {
    // Column a x 4dx x 2a in a tank 2a long: the surge hits the end wall at about sqrt(2 g H).
    const double a = 0.1, dx = a / 10, W = 4 * dx;
    scene::Scene s =
        water(dx, 10 * std::sqrt(2 * 9.81 * 2 * a), Aabb{Vec3(-0.05, -0.05, -0.05), Vec3(0.25, W + 0.05, 0.65)});
    s.sph.artificial_viscosity = 0.02;
    s.fluids.push_back(sph::testing::box_body("column", Vec3::Zero(), Vec3(a, W, 2 * a)));
    sph::SphModel model(s);
    model.set_boundary(sph::testing::container_walls(Vec3::Zero(), Vec3(2 * a, W, 0.6), dx, 3));
    run("wall impact", model, 100000000, impact_time);
  }
  return 0;
}
