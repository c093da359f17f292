#pragma once
// Materials, scene pieces and checks shared by the FEM tests.
#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "fem_solver/body_common.hpp"
#include "fem_solver/materials/plastic_kinematic.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::fem::test {

// Elastic structural steel.
inline MaterialParameters steel() {
  MaterialParameters m;
  m.density = 7850;
  m.youngs_modulus = 210e9;
  m.poisson_ratio = 0.3;
  return m;
}

// An elastic scene material: density kg/m^3, Young's modulus Pa.
inline scene::Material scene_material(const std::string& name, double density, double youngs_modulus,
                                      double poisson_ratio) {
  scene::Material m;
  m.name = name;
  m.density = density;
  m.youngs_modulus = youngs_modulus;
  m.poisson_ratio = poisson_ratio;
  return m;
}

// steel() as a scene material named "steel".
inline scene::Material scene_steel() {
  return scene_material("steel", 7850, 210e9, 0.3);
}

// A deformable structure of the scene material `material`; shape, thickness
// and fixed faces are the caller's.
inline scene::Structure deformable_structure(const std::string& name, const std::string& material) {
  scene::Structure s;
  s.name = name;
  s.material = material;
  s.rigid = false;
  return s;
}

// A plane panel centred at `origin`: `length` along `direction` by `width`
// (m), elements of about `element_size` (m).
inline scene::Shape plane_shape(const Vec3& origin, const Vec3& normal, const Vec3& direction, double length,
                                double width, double element_size) {
  scene::Shape shape;
  shape.type = scene::Shape::Type::plane;
  shape.origin = origin;
  shape.normal = normal;
  shape.direction = direction;
  shape.length = length;
  shape.width = width;
  shape.element_size = element_size;
  return shape;
}

// A box of hexahedra of about `element_size` (m).
inline scene::Shape box_shape(const Aabb& box, double element_size) {
  scene::Shape shape;
  shape.type = scene::Shape::Type::box;
  shape.box = box;
  shape.element_size = element_size;
  return shape;
}

// The hourglass criterion (hourglass energy below 10% of the internal energy)
// over a whole run: observe() every step; worst() is the largest ratio over
// the steps whose internal energy is at least `floor_fraction` of the run's
// largest (near zero internal energy, e.g. as a vibration passes its rest
// position, the ratio of two vanishing numbers says nothing).
class HourglassMonitor {
 public:
  explicit HourglassMonitor(double floor_fraction = 0.1) : floor_fraction_(floor_fraction) {}
  void observe(const SolidEnergies& e) { samples_.emplace_back(e.internal, e.hourglass); }
  [[nodiscard]] double worst() const {
    double peak = 0;
    for (const auto& [internal, hourglass] : samples_) peak = std::max(peak, internal);
    double worst = 0;
    for (const auto& [internal, hourglass] : samples_) {
      if (internal > floor_fraction_ * peak && internal > 0) worst = std::max(worst, hourglass / internal);
    }
    return worst;
  }

 private:
  double floor_fraction_;
  std::vector<std::pair<double, double>> samples_;  // (internal, hourglass), J
};

}  // namespace sabo::fem::test
