#pragma once
// Scenes built in code for the DEM tests.
#include "libsabo/scene/scene.hpp"

namespace sabo::dem::testing {

inline scene::Scene rock_scene(double density = 2500.0) {
  scene::Scene scene;
  scene.file = "/tmp/dem-test/scene.toml";
  scene::Material rock;
  rock.name = "rock";
  rock.density = density;
  rock.youngs_modulus = 30e9;
  rock.poisson_ratio = 0.3;
  scene.materials.push_back(rock);
  scene.run.gravity = Vec3(0, 0, -9.81);
  return scene;
}

inline scene::ParticleSet list_set(std::string name, std::vector<scene::Sphere> spheres, int line = 20) {
  scene::ParticleSet set;
  set.name = std::move(name);
  set.material = "rock";
  set.origin = {"/tmp/dem-test/scene.toml", line, "particles"};
  set.kind = scene::ParticleSet::Kind::list;
  set.spheres = std::move(spheres);
  return set;
}

inline scene::ParticleSet fill_set(std::string name, const Aabb& region, std::size_t count, double diameter_min,
                                   double diameter_max, std::uint64_t seed, int line = 30) {
  scene::ParticleSet set;
  set.name = std::move(name);
  set.material = "rock";
  set.origin = {"/tmp/dem-test/scene.toml", line, "particles"};
  set.kind = scene::ParticleSet::Kind::fill;
  set.region = region;
  set.count = count;
  set.diameter_min = diameter_min;
  set.diameter_max = diameter_max;
  set.seed = seed;
  return set;
}

}  // namespace sabo::dem::testing
