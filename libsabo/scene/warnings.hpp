#pragma once
// What the scene check says about a scene that runs but probably does not do
// what its author meant (sabo_scene check prints these on stderr and exits 0;
// the supervisor shows them before the run). Errors are SceneError (loader.hpp).
#include <string>
#include <vector>

#include "libsabo/scene/scene.hpp"

namespace sabo::scene {

// "FILE:LINE: key 'K': warning: PROBLEM. Fix: FIX." per finding, in file order:
// - a structure that nothing can touch: no particle set, fluid or other structure has contact with it
//   enabled (a rigid one, or one in a scene with other bodies: a lone deformable structure under its own
//   loads is a valid FEM scene);
// - a sensor box of a scene with fluids that is narrower along the face than sph.particle_spacing (or
//   covers less than its square): its reading jumps as the fluid particles pass.
[[nodiscard]] std::vector<std::string> scene_warnings(const Scene& scene);

}  // namespace sabo::scene
