#include "coupler/contact/pair_factory.hpp"

#include "coupler/contact/sph_dem_boundary_pair.hpp"
#include "coupler/contact/sph_dem_penalty_pair.hpp"
#include "coupler/contact/surface_penalty_pair.hpp"
#include "coupler/contact/wall_particles_pair.hpp"

namespace sabo::coupler {

std::vector<std::unique_ptr<ContactPair>> make_contact_pairs(const scene::Scene& scene) {
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
  if (scene.needs(Role::sph) && scene.needs(Role::dem)) {
    // One pair per law that some (fluid body, particle set) uses.
    bool penalty = false, boundary = false;
    for (const auto& fluid : scene.fluids) {
      for (const auto& set : scene.particle_sets) {
        const scene::SphDemContact contact = scene.sph_dem_contact(fluid.name, set.name);
        if (!contact.enabled) continue;
        (contact.model == scene::SphDemContact::Model::penalty ? penalty : boundary) = true;
      }
    }
    if (boundary) pairs.push_back(std::make_unique<SphDemBoundaryPair>(scene));
    if (penalty) pairs.push_back(std::make_unique<SphDemPenaltyPair>(scene));
  }
  return pairs;
}

}  // namespace sabo::coupler
