#include "libsabo/scene/sensor_patch.hpp"

#include <algorithm>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/primitives.hpp"

namespace sabo::scene {

std::optional<geometry::SurfacePatch> sensor_patch(const std::vector<Structure>& structures, const Sensor& sensor) {
  if (!sensor.box) return std::nullopt;
  const auto structure =
      std::find_if(structures.begin(), structures.end(), [&](const Structure& s) { return s.name == sensor.part; });
  if (structure == structures.end() || (structure->shape.type == Shape::Type::mesh && !structure->rigid)) {
    return std::nullopt;
  }
  try {
    return geometry::surface_patch(geometry::triangulate(structure->shape, structure->name, structure->origin), 0,
                                   sensor.box);
  } catch (const Error&) {
    return std::nullopt;
  }
}

}  // namespace sabo::scene
