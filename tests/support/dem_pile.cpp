#include "tests/support/dem_pile.hpp"

namespace sabo::dem {

scene::Scene pile_scene(std::size_t count, double height_over_side, std::uint64_t seed) {
  scene::Scene scene;
  scene.file = "dem pile (built in code)";
  scene.run.gravity = Vec3(0, 0, -9.81);
  scene::Material granite;
  granite.name = "granite";
  granite.density = 2650;
  granite.youngs_modulus = 50e9;
  granite.poisson_ratio = 0.25;
  scene.materials.push_back(granite);
  scene.dem_contact.model = scene::DemLaw::hertz_mindlin;
  scene.dem_contact.restitution = 0.3;
  scene.dem_contact.friction = 0.5;
  scene.dem_contact.rolling_friction = 0.1;
  scene::ParticleSet set;
  set.name = "pile";
  set.material = "granite";
  set.kind = scene::ParticleSet::Kind::fill;
  set.count = count;
  set.diameter_min = 1.0;
  set.diameter_max = 2.0;
  set.seed = seed;
  const double volume = static_cast<double>(count) * set.mean_sphere_volume() / 0.25;
  const double side = std::cbrt(volume / height_over_side);
  set.region = Aabb{Vec3::Zero(), Vec3(side, side, side * height_over_side)};
  scene.particle_sets.push_back(set);
  return scene;
}

PileReport settle_pile(const scene::Scene& scene, double duration, double beta) {
  const scene::ParticleSet& set = scene.particle_sets.front();
  DemModel model(scene);
  model.add_region_walls(set);
  PileReport report;
  report.dt = beta * model.stable_dt();
  report.steps = static_cast<std::int64_t>(std::ceil(duration / report.dt));
  report.initial_energy = model.energies().total();
  report.largest_energy_rise = -std::numeric_limits<double>::infinity();
  double dt_previous = 0;
  for (std::int64_t n = 0; n < report.steps; ++n) {
    model.compute_internal_forces(dt_previous);
    model.integrate(dt_previous, report.dt);
    dt_previous = report.dt;
    report.largest_energy_rise = std::max(report.largest_energy_rise, model.energies().total() - report.initial_energy);
    if (n % 100 == 0 || n + 1 == report.steps) {
      for (std::size_t i = 0; i < model.size(); ++i) {
        report.escaped += set.contains_sphere(model.positions()[i], 0.5 * model.radii()[i]) ? 0 : 1;
      }
    }
  }
  for (const auto& v : model.velocities()) report.final_largest_speed = std::max(report.final_largest_speed, v.norm());
  double sum = 0;
  for (const auto& contact : model.contact_histories()) {
    const double ra = model.radii()[contact.a], rb = model.radii()[contact.b];
    const double overlap = ra + rb - (model.positions()[contact.a] - model.positions()[contact.b]).norm();
    const double ratio = overlap / std::min(ra, rb);
    report.final_largest_overlap_ratio = std::max(report.final_largest_overlap_ratio, ratio);
    sum += ratio;
    ++report.contacts;
  }
  report.final_mean_overlap_ratio = report.contacts > 0 ? sum / static_cast<double>(report.contacts) : 0;
  return report;
}

}  // namespace sabo::dem
