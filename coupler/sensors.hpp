#pragma once
// The scene's [[sensors]] (docs/scene.md): the force each source puts on a patch of a structure, and
// sensors.csv. A sensor without a box takes its part's loads() (the same bits as forces.csv); one with a
// box sums the pair's point_loads() whose point lies in the box, in the pair's order.
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "coupler/accounting.hpp"
#include "coupler/contact/contact_pair.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::coupler {

class Sensors {
 public:
  // file: sensors.csv, opened before and then owned; surface: the FEM surface as registered (areas and
  // normals are taken from it); sources: the columns of forces.csv. Throws SceneError naming a sensor
  // whose box meets none of its part's surface.
  Sensors(std::FILE* file, const scene::Scene& scene, const geometry::SurfaceMesh& surface,
          std::vector<std::string> sources, bool header);

  // Whether pairs must keep their point loads (ContactPair::want_point_loads): a sensor has a box.
  [[nodiscard]] bool needs_point_loads() const { return any_box_; }
  // Every step: the loads of `pair` (forces.csv column `source`) over the step dt (s); `loads` is
  // pair.loads(), as forces.csv took it.
  void add(const ContactPair& pair, std::span<const Vec3> loads, std::size_t source, double dt);
  void write(double time) { history_.write(time); }
  void close() { history_.close(); }
  void save(io::hdf5::Group& group) const { history_.save(group); }
  void restore(const io::hdf5::Group& group) { history_.restore(group); }

 private:
  struct Slot {
    std::size_t part = 0;            // scene structure order (loads())
    std::uint32_t surface_part = 0;  // the part's index in the surface (PointLoad::part)
    std::optional<Aabb> box;         // m; none: the whole part
  };
  [[nodiscard]] static std::vector<Slot> slots_of(const scene::Scene& scene, const geometry::SurfaceMesh& surface);
  std::vector<Slot> slots_;
  bool any_box_ = false;
  std::vector<PointLoad> point_loads_;  // scratch
  ForceHistory history_;
};

}  // namespace sabo::coupler
