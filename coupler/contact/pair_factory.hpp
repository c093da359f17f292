#pragma once
// The one place that knows which contact pairs a scene asks for.
#include <memory>
#include <vector>

#include "coupler/contact/contact_pair.hpp"

namespace sabo::coupler {

// The pairs of the scene's solvers, in a fixed order (DEM-FEM, SPH-FEM, SPH-DEM): the order in which
// their forces are summed into each reply.
[[nodiscard]] std::vector<std::unique_ptr<ContactPair>> make_contact_pairs(const scene::Scene& scene);

}  // namespace sabo::coupler
