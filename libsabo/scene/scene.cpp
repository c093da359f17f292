#include "libsabo/scene/scene.hpp"

#include <algorithm>
#include <cassert>

namespace sabo::scene {

const char* role_name(Role role) {
  switch (role) {
    case Role::sph: return "sph_solver";
    case Role::dem: return "dem_solver";
    case Role::fem: return "fem_solver";
  }
  return "unknown";
}

bool Scene::needs(Role role) const {
  return solver(role) != nullptr;
}

const SolverSettings* Scene::solver(Role role) const {
  auto it = std::find_if(solvers.begin(), solvers.end(), [role](const SolverSettings& s) { return s.role == role; });
  return it == solvers.end() ? nullptr : &*it;
}

std::size_t Scene::material_index(const std::string& name) const {
  auto it = std::find_if(materials.begin(), materials.end(), [&](const Material& m) { return m.name == name; });
  assert(it != materials.end() && "material names are checked by the loader");
  return static_cast<std::size_t>(it - materials.begin());
}

SurfaceContact Scene::surface_contact(const std::string& set, const std::string& structure) const {
  for (const auto& interaction : interactions) {
    if ((interaction.a == set && interaction.b == structure) || (interaction.a == structure && interaction.b == set)) {
      return interaction.contact;
    }
  }
  const bool is_fluid = std::any_of(fluids.begin(), fluids.end(), [&](const FluidBody& f) { return f.name == set; });
  return is_fluid ? sph_fem_default : dem_fem_default;
}

}  // namespace sabo::scene
