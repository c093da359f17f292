#include "tests/support/sph_scenes.hpp"

namespace sabo::sph::testing {

scene::Scene water_scene(double dx, double sound_speed, double smoothing_ratio) {
  scene::Scene s;
  s.run.gravity = Vec3(0, 0, -9.81);
  scene::Material water;
  water.name = "water";
  water.density = 1000;
  water.youngs_modulus = 1e9;
  water.poisson_ratio = 0.3;
  s.materials.push_back(water);
  s.sph.particle_spacing = dx;
  s.sph.smoothing_ratio = smoothing_ratio;
  s.sph.sound_speed = sound_speed;
  return s;
}

scene::FluidBody box_body(const std::string& name, const Vec3& min, const Vec3& max) {
  scene::FluidBody body;
  body.name = name;
  body.material = "water";
  body.shape = scene::FluidBody::Shape::box;
  body.box = Aabb{min, max};
  return body;
}

physics::BoundaryParticles container_walls(const Vec3& min, const Vec3& max, double dx, int layers, bool lid) {
  physics::BoundaryParticles walls;
  const Vec3 outer_min = min - Vec3::Constant(layers * dx);
  const Vec3 outer_max(max.x() + layers * dx, max.y() + layers * dx, max.z() + (lid ? layers * dx : 0.0));
  const Vec3 extent = outer_max - outer_min;
  const auto count = [&](double e) { return static_cast<int>(std::floor(e / dx + 1e-9)); };
  for (int k = 0; k < count(extent.z()); ++k) {
    for (int j = 0; j < count(extent.y()); ++j) {
      for (int i = 0; i < count(extent.x()); ++i) {
        const Vec3 p = outer_min + dx * Vec3(i + 0.5, j + 0.5, k + 0.5);
        if ((p.array() > min.array()).all() && (p.array() < max.array()).all()) continue;
        const Vec3 inner = p.cwiseMax(min).cwiseMin(max);
        Vec3 normal = inner - p;
        normal = normal.norm() > 0 ? normal.normalized() : Vec3(0, 0, 1);
        walls.position.push_back(p);
        walls.velocity.push_back(Vec3::Zero());
        walls.normal.push_back(normal);
        walls.acceleration.push_back(Vec3::Zero());
        walls.volume.push_back(dx * dx * dx);
      }
    }
  }
  return walls;
}

double hydrostatic_pressure_error(const SphModel& model, double H, double g) {
  double error2 = 0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    error2 += std::pow(model.pressures()[i] - 1000 * g * (H - model.positions()[i].z()), 2);
  }
  return std::sqrt(error2 / static_cast<double>(model.size())) / (1000 * g * H);
}

WallForceBalance wall_force_balance(const SphModel& model, const Vec3& gravity) {
  WallForceBalance out;
  for (std::size_t i = 0; i < model.size(); ++i) {
    out.on_fluid += model.masses()[i] * (model.accelerations()[i] - gravity);
    out.mass += model.masses()[i];
  }
  for (const Vec3& f : model.boundary_forces()) out.on_walls += f;
  return out;
}

}  // namespace sabo::sph::testing
