#include "libsabo/scene/warnings.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

namespace sabo::scene {
namespace {

std::string located(const Origin& origin, const std::string& problem, const std::string& fix) {
  return fmt::format("{}:{}: key '{}': warning: {}. Fix: {}.", origin.file.string(), origin.line, origin.key, problem,
                     fix);
}

bool fluid_touches(const Scene& scene, const FluidBody& fluid, const Structure& structure) {
  // Boundary-particle walls sample every structure surface; the penalty walls follow the pair's settings.
  return scene.sph.wall_model == SphSettings::WallModel::boundary_particles ||
         scene.surface_contact(fluid.name, structure.name).enabled;
}

}  // namespace

std::vector<std::string> scene_warnings(const Scene& scene) {
  std::vector<std::string> warnings;
  const std::size_t bodies = scene.fluids.size() + scene.particle_sets.size() + scene.structures.size();
  for (const Structure& structure : scene.structures) {
    if (!structure.rigid && bodies == 1) continue;
    const bool by_set = std::any_of(scene.particle_sets.begin(), scene.particle_sets.end(), [&](const ParticleSet& s) {
      return scene.surface_contact(s.name, structure.name).enabled;
    });
    const bool by_fluid = std::any_of(scene.fluids.begin(), scene.fluids.end(),
                                      [&](const FluidBody& f) { return fluid_touches(scene, f, structure); });
    const bool by_structure = std::any_of(scene.structures.begin(), scene.structures.end(), [&](const Structure& o) {
      return scene.fem_fem_contact(structure.name, o.name).enabled;
    });
    if (by_set || by_fluid || by_structure) continue;
    std::vector<std::string> off;
    if (!scene.particle_sets.empty()) off.emplace_back("particle sets");
    if (!scene.fluids.empty()) off.emplace_back("fluids");
    if (scene.structures.size() > 1) off.emplace_back("other structures");
    const std::string why =
        off.empty() ? "the scene has no other body"
                    : fmt::format("none of the scene's {} has contact with it enabled", fmt::join(off, " and "));
    const std::string load = structure.rigid ? "a rigid structure that nothing touches does nothing"
                                             : "it feels its own weight and nothing else";
    warnings.push_back(located(structure.origin,
                               fmt::format("nothing can touch structure \"{}\": {}; {}", structure.name, why, load),
                               "give it a contact: an [[interactions]] pair that names it without `enabled = false` "
                               "(or remove the one that switches it off), [contact.fem_fem] `enabled = true` for "
                               "the other structures; or remove the structure"));
  }
  return warnings;
}

}  // namespace sabo::scene
