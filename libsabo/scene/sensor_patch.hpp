#pragma once
// The surface a box sensor ([[sensors]] with min/max) covers, known from the scene alone: for the scene
// check (an empty box is an error, a narrow one a warning). The coupler measures on the surface the
// fem_solver registers (coupler/sensors.hpp).
#include <optional>
#include <vector>

#include "libsabo/geometry/surface_patch.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::scene {

// The part's surface clipped to the sensor's box; nullopt for a sensor without a box, an unknown part, a
// deformable .msh part (its surface is checked by the coupler once registered) or a shape that cannot be
// triangulated (reported with the structure).
[[nodiscard]] std::optional<geometry::SurfacePatch> sensor_patch(const std::vector<Structure>& structures,
                                                                 const Sensor& sensor);

}  // namespace sabo::scene
