#pragma once
// Random non-overlapping placement of the spheres of a `fill` particle set.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::geometry {

// Uniform double in [0, 1) from the top 53 bits of a 64-bit draw: the same bits
// on every standard library (std::uniform_real_distribution is not portable).
double unit_uniform(std::uint64_t bits);

// What fill_region throws: a SceneError with the set's origin, and the reason alone (for the scene check,
// which names the key itself).
class FillError : public SceneError {
 public:
  FillError(const std::string& message, std::string set_name, std::string problem)
      : SceneError(message), set_name_(std::move(set_name)), problem_(std::move(problem)) {}
  [[nodiscard]] const std::string& set_name() const { return set_name_; }
  [[nodiscard]] const std::string& problem() const { return problem_; }

 private:
  std::string set_name_, problem_;
};

// Places set.count spheres (diameters of the set's distribution: uniform, clipped
// normal, or sieve grading, a class drawn with sieve_class_probabilities then
// uniform in it; drawn from std::mt19937_64 seeded with set.seed) entirely inside
// the set's region (the box, or the polygon extruded along y: centres drawn in its
// bounding box, kept if inside),
// overlapping neither each other nor `obstacles`. The largest spheres are
// placed first, each at the first of up to `attempts_per_sphere` random
// centres that fits; the spheres are returned in placement order with the
// set's initial velocity. Throws FillError (with set.origin, how many fitted
// and the fix) when a sphere finds no place.
std::vector<scene::Sphere> fill_region(const scene::ParticleSet& set, std::span<const scene::Sphere> obstacles,
                                       int attempts_per_sphere = 2000);

// The spheres of every particle set (scene order) at t = 0 as the dem_solver places them, where
// that is known without running the DEM: a listed set, and a fill set placed by fill_region with
// the listed spheres and the earlier fills as obstacles, unless it or an earlier fill set settles
// under gravity (settle_time > 0: where they come to rest is the DEM's answer): then nullopt.
// Throws SceneError as fill_region does.
[[nodiscard]] std::vector<std::optional<std::vector<scene::Sphere>>> initial_spheres(const scene::Scene& scene);

}  // namespace sabo::geometry
