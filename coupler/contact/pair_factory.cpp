#include "coupler/contact/pair_factory.hpp"

#include "coupler/contact/surface_penalty_pair.hpp"
#include "coupler/contact/wall_particles_pair.hpp"

namespace sabo::coupler {

std::vector<std::unique_ptr<ContactPair>> make_contact_pairs(const scene::Scene& scene) {
  using scene::Role;
  std::vector<std::unique_ptr<ContactPair>> pairs;
  if (scene.needs(Role::dem) && scene.needs(Role::fem)) {
    pairs.push_back(std::make_unique<SurfacePenaltyPair>(scene, Role::dem));
  }
  if (scene.needs(Role::sph) && scene.needs(Role::fem)) {
    if (scene.sph.wall_model == scene::SphSettings::WallModel::penalty) {
      pairs.push_back(std::make_unique<SurfacePenaltyPair>(scene, Role::sph));
    } else {
      pairs.push_back(std::make_unique<WallParticlesPair>(scene));
    }
  }
  return pairs;
}

}  // namespace sabo::coupler
