#include "tests/support/sph_dem_archimedes.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numbers>

#include "tests/support/sph_scenes.hpp"

namespace sabo::testing {

namespace {

constexpr double kWaterDensity = 1000;  // kg/m^3

scene::Material rock(double density) {
  scene::Material m;
  m.name = "rock";
  m.density = density;
  m.youngs_modulus = 1e9;
  m.poisson_ratio = 0.3;
  return m;
}

// The free surface far from the sphere and the walls: the mean top of the lattice columns plus dx/2, m.
double free_surface(const sph::SphModel& model, double dx, const Vec3& centre, double radius, double width) {
  std::map<std::pair<long, long>, double> top;
  for (std::size_t i = 0; i < model.size(); ++i) {
    const Vec3& x = model.positions()[i];
    const long cx = std::lround(std::floor(x.x() / dx)), cy = std::lround(std::floor(x.y() / dx));
    const double px = (static_cast<double>(cx) + 0.5) * dx, py = (static_cast<double>(cy) + 0.5) * dx;
    if (std::hypot(px - centre.x(), py - centre.y()) < radius + 3 * dx) continue;
    if (std::min({px, width - px, py, width - py}) < 1.5 * dx) continue;
    auto [it, inserted] = top.try_emplace({cx, cy}, x.z());
    if (!inserted) it->second = std::max(it->second, x.z());
  }
  double sum = 0;
  for (const auto& [column, z] : top) sum += z;
  return sum / static_cast<double>(top.size()) + 0.5 * dx;
}

double cap_fraction(double centre_height, double surface, double radius) {
  const double h = std::clamp(surface - (centre_height - radius), 0.0, 2 * radius);
  return h * h * (3 * radius - h) / (4 * radius * radius * radius);
}

}  // namespace

scene::Scene water_tank_scene(double dx, double width, double depth, double sound_speed, double viscosity,
                              const std::vector<scene::Sphere>& spheres, double density,
                              scene::SphDemContact::Model model) {
  scene::Scene s = sph::testing::water_scene(dx, sound_speed, 1.5);
  if (viscosity > 0) {
    s.materials[0].rheology = scene::Material::Rheology::newtonian;
    s.materials[0].viscosity = viscosity;
  }
  s.sph.artificial_viscosity = 0.05;
  s.materials.insert(s.materials.begin(), rock(density));  // sorted by name: rock, water
  s.fluids.push_back(sph::testing::box_body("water", Vec3::Zero(), Vec3(width, width, depth)));
  scene::ParticleSet set;
  set.name = "boulders";
  set.material = "rock";
  set.spheres = spheres;
  s.particle_sets.push_back(set);
  s.sph_dem_default.model = model;
  for (auto role : {sabo::Role::sph, sabo::Role::dem}) s.solvers.emplace_back().role = role;
  return s;
}

physics::BoundaryParticles water_tank_walls(double dx, double width, double height) {
  return sph::testing::container_walls(Vec3::Zero(), Vec3(width, width, height), dx, 3);
}

void add_dem_tank_walls(dem::DemModel& model, double width) {
  for (auto [point, normal] :
       {std::pair{Vec3(0, 0, 0), Vec3(0, 0, 1)}, std::pair{Vec3(0, 0, 0), Vec3(1, 0, 0)},
        std::pair{Vec3(0, 0, 0), Vec3(0, 1, 0)}, std::pair{Vec3(width, width, 0), Vec3(-1, 0, 0)},
        std::pair{Vec3(width, width, 0), Vec3(0, -1, 0)}}) {
    dem::Wall wall;
    wall.point = point;
    wall.normal = normal;
    model.add_wall(wall);
  }
}

ArchimedesResult run_archimedes(const ArchimedesCase& c) {
  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  ArchimedesResult r;
  r.floats = c.density < kWaterDensity;
  r.radius = c.radius;
  const double diameter = 2 * c.radius;
  r.dx = diameter / c.diameter_spacings;
  // The tank a whole number of spacings wide and deep, so that the lattice fills it.
  const auto whole = [&](double length) { return std::round(length / r.dx) * r.dx; };
  r.width = whole((c.width_diameters > 0 ? c.width_diameters : (r.floats ? 2.0 : 1.6)) * diameter);
  r.depth = whole(c.depth_diameters * diameter);
  const double start = r.floats ? r.depth : c.radius;
  const std::vector<scene::Sphere> ball{
      {Vec3(0.5 * r.width, 0.5 * r.width, start), c.radius, Vec3::Zero(), Vec3::Zero()}};
  scene::Scene scene = water_tank_scene(r.dx, r.width, r.depth, c.sound_speed, c.viscosity, ball, c.density, c.model);
  if (c.cfl > 0) scene.sph.cfl = c.cfl;
  const double g = -scene.run.gravity.z();
  SphDemHarness run(scene, water_tank_walls(r.dx, r.width, c.wall_height_depths * r.depth));
  add_dem_tank_walls(run.dem(), r.width);
  r.fluid_particles = run.sph().size();
  const double end_time = c.end_time > 0 ? c.end_time : (r.floats ? 0.5 : 0.2);
  // The fluid's push on the sphere and the sphere's height averaged over the last quarter of the run: what
  // the heave has left of the pressure waves averages out.
  double push_impulse = 0, height_integral = 0, window = 0;
  while (run.time() < end_time) {
    const double before = run.time();
    run.step();
    if (before >= 0.75 * end_time) {
      const double dt = run.time() - before;
      push_impulse += run.fluid_force_on_sphere(0).z() * dt;
      height_integral += run.dem().positions()[0].z() * dt;
      window += dt;
    }
  }
  r.steps = run.steps();
  r.time = run.time();
  const Vec3 centre = run.dem().positions()[0];
  r.centre_height = height_integral / window;
  r.speed = run.dem().velocities()[0].norm();
  const double volume = 4.0 / 3.0 * std::numbers::pi * std::pow(c.radius, 3);
  if (r.floats) {
    r.surface = free_surface(run.sph(), r.dx, centre, c.radius, r.width);
    r.submerged_fraction = cap_fraction(r.centre_height, r.surface, c.radius);
    r.expected_fraction = c.density / kWaterDensity;
  } else {
    const double weight = c.density * volume * g;
    r.floor_reaction = weight - push_impulse / window;
    r.expected_reaction = weight - kWaterDensity * volume * g;
  }
  r.wall_seconds = std::chrono::duration<double>(Clock::now() - started).count();
  return r;
}

Convergence convergence(double coarse_dx, double coarse_error, double fine_dx, double fine_error) {
  Convergence c;
  c.order = std::log(coarse_error / fine_error) / std::log(coarse_dx / fine_dx);
  c.limit = fine_error - (coarse_error - fine_error) * fine_dx / (coarse_dx - fine_dx);
  return c;
}

}  // namespace sabo::testing
