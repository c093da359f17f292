// Where and when a fluid at rest moves (issue 3, S4): the reduced S4 tank (H = 0.2 m,
// dx = H/res, 0.2 x 0.1 m, c = 10 sqrt(gH), wall particles 3 layers deep up to wall-top dx
// above the free surface). Every `report` sqrt(H/g) it prints the largest speed of that
// window over sqrt(gH), the lattice index (i, j, k; k = 9 is the top row at res 10) of the
// particle that had it and when, the total energy (kinetic + potential + compression) less
// the initial one, the kinetic energy and the mean neighbour count; at the end the pressure
// L2 error against rho g (H - z) and the largest energy rise.
//   bench_sph_rest_probe [--kernel cubic_spline|wendland_c2] [--ratio h/dx] [--alpha A]
//                        [--diffusion none|molteni|fourtakas] [--delta D] [--periods N]
//                        [--report P] [--res R] [--wall-top K] [--settle T]
//                        [--wall-work bounded|stored|unstored]
// --settle T gives the water the scene's settling phase (FluidBody::settle_time) of
// T sqrt(H/g) from t = 0; the windows and the largest speed include it.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "libsabo/scene/names.hpp"
#include "sph_solver/sph_model.hpp"
#include "tests/support/sph_scenes.hpp"

using namespace sabo;

int main(int argc, char** argv) {
  CLI::App app("S4 tank at rest: where and when the fastest particle is");
  std::string kernel = "cubic_spline", diffusion = "fourtakas";
  double ratio = 1.3, alpha = 0.1, delta = 0.1, periods = 10, report = 0.25, res = 10, wall_top = 4, settle = 0;
  app.add_option("--kernel", kernel)->check(CLI::IsMember(scene::choice_names<scene::SphSettings::Kernel>()));
  app.add_option("--ratio", ratio, "h / dx");
  app.add_option("--alpha", alpha, "artificial viscosity");
  app.add_option("--diffusion", diffusion)
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::DensityDiffusion>()));
  app.add_option("--delta", delta, "density diffusion delta");
  app.add_option("--periods", periods, "run length, sqrt(H/g)");
  app.add_option("--report", report, "report window, sqrt(H/g)");
  app.add_option("--res", res, "H / dx");
  app.add_option("--wall-top", wall_top, "wall height above the free surface, dx");
  app.add_option("--settle", settle, "the water's settling phase from t = 0, sqrt(H/g)");
  std::string wall_work = "bounded";
  app.add_option("--wall-work", wall_work, "sph.wall_work (the default: bounded)")
      ->check(CLI::IsMember(scene::choice_names<scene::SphSettings::WallWork>()));
  CLI11_PARSE(app, argc, argv);
  const double H = 0.2, dx = H / res, g = 9.81, L = 0.2, W = 0.1;
  scene::Scene s = sph::testing::water_scene(dx, 10 * std::sqrt(g * H), ratio);
  s.sph.kernel = scene::value_named<scene::SphSettings::Kernel>(kernel);
  s.sph.wall_work = scene::value_named<scene::SphSettings::WallWork>(wall_work);
  s.sph.artificial_viscosity = alpha;
  s.sph.density_diffusion_delta = delta;
  s.sph.density_diffusion = scene::value_named<scene::SphSettings::DensityDiffusion>(diffusion);
  s.fluids.push_back(sph::testing::box_body("water", Vec3::Zero(), Vec3(L, W, H)));
  const double T = std::sqrt(H / g), U = std::sqrt(g * H);
  s.fluids.back().settle_time = settle * T;
  sph::SphModel model(s);
  model.set_boundary(sph::testing::container_walls(Vec3::Zero(), Vec3(L, W, H + wall_top * dx), dx, 3));
  const std::vector<Vec3> x0(model.positions().begin(), model.positions().end());
  const double e0 = model.energies().total();
  double next = report * T, v_window = 0, v_all = 0, e_max = e0, t_fastest = 0;
  std::size_t fastest = 0;
  fmt::print("particles {}, initial energy {:.9g} J\n", model.size(), e0);
  const int steps = sph::testing::run_until(model, periods * T, [&](double t) {
    e_max = std::max(e_max, model.energies().total());
    for (std::size_t i = 0; i < model.size(); ++i) {
      const double v = model.velocities()[i].norm();
      if (v > v_window) {
        v_window = v;
        fastest = i;
        t_fastest = t;
      }
    }
    if (t >= next) {
      const Vec3 p = x0[fastest] / dx - Vec3::Constant(0.5);
      fmt::print(
          "t {:6.2f}: largest speed {:.3e} sqrt(gH) at ({:.0f},{:.0f},{:.0f}), t {:.2f}; E - E0 {:.3e} J, kinetic "
          "{:.3e} J, neighbours {:.1f}\n",
          t / T, v_window / U, p.x(), p.y(), p.z(), t_fastest / T, model.energies().total() - e0,
          model.energies().kinetic, model.mean_neighbours());
      v_all = std::max(v_all, v_window);
      v_window = 0;
      next += report * T;
    }
  });
  v_all = std::max(v_all, v_window);  // the last window, if the run ended inside it
  model.compute_internal_forces(0);
  fmt::print("pressure L2 error {:.3f} % of rho g H\n", 100 * sph::testing::hydrostatic_pressure_error(model, H, g));
  fmt::print("steps {}, largest speed {:.3e} sqrt(gH), largest E - E0 {:.3e} J ({:.3e} of E0), left the domain {}\n",
             steps, v_all / U, e_max - e0, (e_max - e0) / e0, model.lost_count());
  return 0;
}
