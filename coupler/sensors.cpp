#include "coupler/sensors.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/surface_patch.hpp"

namespace sabo::coupler {
namespace {

std::string vector_text(const Vec3& v) {
  return fmt::format("[{:.6g}, {:.6g}, {:.6g}]", v.x(), v.y(), v.z());
}

std::vector<std::string> sensor_names(const scene::Scene& scene) {
  std::vector<std::string> names;
  for (const scene::Sensor& sensor : scene.sensors) names.push_back(sensor.name);
  return names;
}

// The index of a sensor's part in the registered surface; SceneError when the surface has none.
std::uint32_t surface_part_of(const scene::Scene& scene, const scene::Sensor& sensor,
                              const geometry::SurfaceMesh& surface) {
  const auto part = std::find(surface.part_name.begin(), surface.part_name.end(), sensor.part);
  if (part == surface.part_name.end()) {
    throw SceneError(
        fmt::format("{}:{}: sensor '{}': the fem_solver's surface has no part '{}'. Fix: name a "
                    "structure with a contact surface",
                    scene.file.string(), sensor.origin.line, sensor.name, sensor.part));
  }
  return static_cast<std::uint32_t>(part - surface.part_name.begin());
}

// Each sensor's part, area and normal on the registered surface.
std::vector<ForceHistory::SensorRow> sensor_rows(const scene::Scene& scene, const geometry::SurfaceMesh& surface) {
  std::vector<ForceHistory::SensorRow> rows;
  for (const scene::Sensor& sensor : scene.sensors) {
    const geometry::SurfacePatch patch =
        geometry::surface_patch(surface, surface_part_of(scene, sensor, surface), sensor.box);
    if (!(patch.area > 0)) {
      throw SceneError(fmt::format(
          "{}:{}: sensor '{}': the box [{}, {}] meets none of the surface of '{}', which spans {} to {}. Fix: move "
          "the box onto the part's face (a box a few mm thick across the face)",
          scene.file.string(), sensor.origin.line, sensor.name, vector_text(sensor.box->min),
          vector_text(sensor.box->max), sensor.part, vector_text(patch.part_bounds.min),
          vector_text(patch.part_bounds.max)));
    }
    rows.push_back({sensor.part, patch.area, patch.mean_normal()});
  }
  return rows;
}

}  // namespace

std::vector<Sensors::Slot> Sensors::slots_of(const scene::Scene& scene, const geometry::SurfaceMesh& surface) {
  std::vector<Slot> slots;
  for (const scene::Sensor& sensor : scene.sensors) {
    const auto part = std::find_if(scene.structures.begin(), scene.structures.end(),
                                   [&](const scene::Structure& s) { return s.name == sensor.part; });
    assert(part != scene.structures.end() && "the loader checks that a sensor's part is a structure");
    slots.push_back({static_cast<std::size_t>(part - scene.structures.begin()), surface_part_of(scene, sensor, surface),
                     sensor.box});
  }
  return slots;
}

Sensors::Sensors(std::FILE* file, const scene::Scene& scene, const geometry::SurfaceMesh& surface,
                 std::vector<std::string> sources, bool header)
    : slots_(slots_of(scene, surface)),
      any_box_(std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.box.has_value(); })),
      history_(file, sensor_names(scene), sensor_rows(scene, surface), std::move(sources), header) {}

void Sensors::add(const ContactPair& pair, std::span<const Vec3> loads, std::size_t source, double dt) {
  if (any_box_) {
    point_loads_.clear();
    pair.point_loads(point_loads_);
  }
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const Slot& slot = slots_[k];
    Vec3 force = Vec3::Zero();
    if (!slot.box) {
      if (slot.part < loads.size()) force = loads[slot.part];
    } else {
      for (const PointLoad& load : point_loads_) {
        if (load.part == slot.surface_part && slot.box->contains(load.point)) force += load.force;
      }
    }
    history_.add(k, source, force, dt);
  }
}

}  // namespace sabo::coupler
