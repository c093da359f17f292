#include "tests/support/sph_slump.hpp"

namespace sabo::sph::testing {

double slump_analysis(double yield_number) {
  return yield_number * (1.0 - std::log(yield_number));
}

SlumpRun run_slump(const SlumpCase& c, const std::function<void(double, double, double)>& on_report) {
  const double rho = 1000, g = 9.81, dx = c.dx;
  scene::Scene s = water_scene(dx, 10.0 * std::sqrt(g * c.height), 1.5);
  s.sph.artificial_viscosity = 0.1;
  s.sph.cfl = c.cfl;
  s.sph.viscous_operator = c.op;
  scene::Material& m = s.materials[0];
  m.rheology = scene::Material::Rheology::bingham;
  m.yield_stress = c.yield_number * rho * g * c.height / std::sqrt(3.0);
  m.viscosity = c.plastic_viscosity;
  m.yield_shear_rate = c.yield_shear_rate;
  const double half = 0.5 * c.side;
  s.fluids.push_back(box_body("column", Vec3(-half, -half, 0), Vec3(half, half, c.height)));
  SphModel model(s);
  const double floor_half = std::ceil(1.25 * c.side / dx) * dx;
  model.set_boundary(container_walls(Vec3(-floor_half, -floor_half, 0), Vec3(floor_half, floor_half, 0), dx, 3));
  const auto top = [&] {
    double z = 0;
    for (const Vec3& p : model.positions()) {
      if (std::abs(p.x()) < dx && std::abs(p.y()) < dx) z = std::max(z, p.z());
    }
    return z + 0.5 * dx;
  };
  SlumpRun out;
  double quiet_since = -1, next_report = 0;
  out.steps = run_until(model, c.t_end, [&](double t) {
    out.time = t;
    double fastest = 0;
    for (const Vec3& v : model.velocities()) fastest = std::max(fastest, v.norm());
    if (on_report && t >= next_report) {
      on_report(t, top() / c.height, fastest);
      next_report += 0.05;
    }
    if (fastest >= c.rest_speed) {
      quiet_since = -1;
      return true;
    }
    if (quiet_since < 0) quiet_since = t;
    out.stopped = t - quiet_since >= c.rest_time;
    return !out.stopped;
  });
  out.final_height = top();
  for (const Vec3& p : model.positions()) out.spread = std::max({out.spread, std::abs(p.x()), std::abs(p.y())});
  out.spread += 0.5 * dx;
  return out;
}

}  // namespace sabo::sph::testing
