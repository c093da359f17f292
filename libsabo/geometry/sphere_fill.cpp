#include "libsabo/geometry/sphere_fill.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <random>

#include "libsabo/core/error.hpp"
#include "libsabo/physics/cell_list.hpp"

namespace sabo::geometry {
namespace {

// Spheres already placed, binned on a grid that grows one sphere at a time.
class PlacedSpheres {
 public:
  PlacedSpheres(std::span<const scene::Sphere> obstacles, const Aabb& region, double largest_radius,
                std::size_t expected_count)
      : largest_radius_(largest_radius) {
    for (const auto& sphere : obstacles) largest_radius_ = std::max(largest_radius_, sphere.radius);
    cell_size_ = 2.0 * largest_radius_;
    origin_ = region.min;
    // Bound the grid's memory for a huge region of tiny spheres: coarser cells stay correct.
    const double max_cells = std::max(4096.0, 8.0 * static_cast<double>(expected_count + obstacles.size()));
    const Vec3 extent = region.max - region.min;
    while ((extent / cell_size_).array().ceil().max(1.0).prod() > max_cells) cell_size_ *= 1.5;
    for (int axis = 0; axis < 3; ++axis) {
      dims_[axis] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(extent[axis] / cell_size_)));
    }
    cells_.resize(static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]));
    for (const auto& sphere : obstacles) {
      // Obstacles that cannot reach the region need not be stored.
      if ((sphere.center - region.min).minCoeff() < -sphere.radius - 2 * largest_radius_) continue;
      if ((region.max - sphere.center).minCoeff() < -sphere.radius - 2 * largest_radius_) continue;
      add(sphere.center, sphere.radius);
    }
  }

  [[nodiscard]] bool fits(const Vec3& center, double radius) const {
    std::int64_t cell[3];
    locate(center, cell);
    for (std::int64_t iz = std::max<std::int64_t>(cell[2] - 1, 0); iz <= std::min(cell[2] + 1, dims_[2] - 1); ++iz) {
      for (std::int64_t iy = std::max<std::int64_t>(cell[1] - 1, 0); iy <= std::min(cell[1] + 1, dims_[1] - 1); ++iy) {
        for (std::int64_t ix = std::max<std::int64_t>(cell[0] - 1, 0); ix <= std::min(cell[0] + 1, dims_[0] - 1);
             ++ix) {
          for (std::size_t k : cells_[index(ix, iy, iz)]) {
            const double reach = radius + radii_[k];
            if ((centers_[k] - center).squaredNorm() < reach * reach) return false;
          }
        }
      }
    }
    return true;
  }

  void add(const Vec3& center, double radius) {
    std::int64_t cell[3];
    locate(center, cell);
    cells_[index(cell[0], cell[1], cell[2])].push_back(centers_.size());
    centers_.push_back(center);
    radii_.push_back(radius);
  }

 private:
  // Cells clamp outside points to the border cell; with cells 2 r_max wide, a
  // neighbour out of the region by up to 2 r_max is still found.
  void locate(const Vec3& p, std::int64_t cell[3]) const {
    for (int axis = 0; axis < 3; ++axis) {
      const double coordinate = std::floor((p[axis] - origin_[axis]) / cell_size_);
      cell[axis] = static_cast<std::int64_t>(std::clamp(coordinate, 0.0, static_cast<double>(dims_[axis] - 1)));
    }
  }
  [[nodiscard]] std::size_t index(std::int64_t ix, std::int64_t iy, std::int64_t iz) const {
    return static_cast<std::size_t>(ix + dims_[0] * (iy + dims_[1] * iz));
  }

  double largest_radius_;
  double cell_size_ = 1;
  Vec3 origin_;
  std::int64_t dims_[3] = {1, 1, 1};
  std::vector<std::vector<std::size_t>> cells_;
  std::vector<Vec3> centers_;
  std::vector<double> radii_;
};

}  // namespace

double unit_uniform(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

namespace {

// One diameter of the set's distribution (uniform, clipped normal, or sieve grading: a class drawn
// with sieve_probability, the set's sieve_class_probabilities(), then uniform in it), m.
double draw_diameter(const scene::ParticleSet& set, std::span<const double> sieve_probability,
                     std::mt19937_64& random) {
  const double low = set.diameter_min, high = set.diameter_max;
  switch (set.distribution) {
    case scene::SizeDistribution::uniform: return low + (high - low) * unit_uniform(random());
    case scene::SizeDistribution::normal: {
      if (!(set.std_diameter > 0)) return std::clamp(set.mean_diameter, low, high);
      // Box-Muller on our own uniform draws (std::normal_distribution is not portable), redrawn
      // until inside the clip range; the loader keeps the mean inside it, so this ends.
      for (;;) {
        const double u = 1.0 - unit_uniform(random());  // (0, 1]
        const double v = unit_uniform(random());
        const double z = std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * std::numbers::pi * v);
        const double d = set.mean_diameter + set.std_diameter * z;
        if (d >= low && d <= high) return d;
      }
    }
    case scene::SizeDistribution::sieve: {
      const double pick = unit_uniform(random());
      const double within = unit_uniform(random());
      double cumulative = 0;
      std::size_t chosen = set.sieve.size() - 1;
      for (std::size_t k = 1; k < set.sieve.size(); ++k) {
        cumulative += sieve_probability[k];
        if (pick < cumulative && sieve_probability[k] > 0) {
          chosen = k;
          break;
        }
      }
      while (chosen > 1 && !(sieve_probability[chosen] > 0)) --chosen;  // round-off at the top end
      const double a = set.sieve[chosen - 1][0], b = set.sieve[chosen][0];
      return a + (b - a) * within;
    }
  }
  return low;
}

}  // namespace

std::vector<scene::Sphere> fill_region(const scene::ParticleSet& set, std::span<const scene::Sphere> obstacles,
                                       int attempts_per_sphere) {
  assert(set.kind == scene::ParticleSet::Kind::fill);
  assert(set.diameter_min > 0 && set.diameter_min <= set.diameter_max);
  std::mt19937_64 random(set.seed);

  std::vector<double> radii(set.count);
  const std::vector<double> sieve_probability =
      set.distribution == scene::SizeDistribution::sieve ? set.sieve_class_probabilities() : std::vector<double>{};
  for (double& radius : radii) radius = 0.5 * draw_diameter(set, sieve_probability, random);
  // Largest first: small spheres then fill the gaps left between large ones.
  std::stable_sort(radii.begin(), radii.end(), std::greater<>());

  std::vector<scene::Sphere> placed;
  placed.reserve(set.count);
  if (set.count == 0) return placed;
  PlacedSpheres grid(obstacles, set.region, radii.front(), set.count);
  const Vec3 extent = set.region.max - set.region.min;
  for (double radius : radii) {
    bool found = false;
    // Centres keep the whole sphere inside the region.
    const Vec3 free_extent = extent.array() - 2 * radius;
    if ((free_extent.array() >= 0).all()) {
      for (int attempt = 0; attempt < attempts_per_sphere && !found; ++attempt) {
        Vec3 center;
        for (int axis = 0; axis < 3; ++axis) {
          center[axis] = set.region.min[axis] + radius + free_extent[axis] * unit_uniform(random());
        }
        if (!set.polygon_xz.empty() && !set.contains_sphere(center, radius)) continue;
        if (grid.fits(center, radius)) {
          grid.add(center, radius);
          placed.push_back(scene::Sphere{center, radius, set.velocity, Vec3::Zero()});
          found = true;
        }
      }
    }
    if (!found) {
      double requested_volume = 0;
      for (double r : radii) requested_volume += 4.0 / 3.0 * std::numbers::pi * r * r * r;
      const double region_volume = set.region_volume();
      const std::string problem =
          (free_extent.array() < 0).any()
              ? fmt::format("a sphere of diameter {:g} m does not fit in the region ({:g} x {:g} x {:g} m)", 2 * radius,
                            extent.x(), extent.y(), extent.z())
              : fmt::format(
                    "only {} of {} spheres could be placed without overlap (sphere {} of diameter {:g} m "
                    "found no free place in {} random tries; the spheres would fill {:.0f}% of the region, "
                    "random placement rarely exceeds 30-35%)",
                    placed.size(), set.count, placed.size() + 1, 2 * radius, attempts_per_sphere,
                    100.0 * requested_volume / region_volume);
      throw FillError(fmt::format("{}:{}: particle set '{}' ({}): {}. Fix: enlarge the region, or lower 'count' or "
                                  "the diameters.",
                                  set.origin.file.string(), set.origin.line, set.name,
                                  set.origin.key.empty() ? std::string("fill") : set.origin.key, problem),
                      set.name, problem);
    }
  }
  return placed;
}

std::vector<std::optional<std::vector<scene::Sphere>>> initial_spheres(const scene::Scene& scene) {
  std::vector<std::optional<std::vector<scene::Sphere>>> sets;
  std::vector<scene::Sphere> obstacles;
  for (const auto& set : scene.particle_sets) {
    if (set.kind == scene::ParticleSet::Kind::list)
      obstacles.insert(obstacles.end(), set.spheres.begin(), set.spheres.end());
  }
  bool settled_before = false;
  for (const auto& set : scene.particle_sets) {
    if (set.kind == scene::ParticleSet::Kind::list) {
      sets.emplace_back(set.spheres);
      continue;
    }
    if (settled_before || set.settle_time > 0) {
      settled_before = true;
      sets.emplace_back(std::nullopt);
      continue;
    }
    auto filled = fill_region(set, obstacles);
    obstacles.insert(obstacles.end(), filled.begin(), filled.end());
    sets.emplace_back(std::move(filled));
  }
  return sets;
}

}  // namespace sabo::geometry
