#include "libsabo/solver/stability.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>

#include "libsabo/scene/scene.hpp"

namespace sabo::solver {

StabilityLimits stability_limits(const scene::Scene& scene, Role role) {
  StabilityLimits limits;
  limits.min_density_ratio = scene.sph.density_ratio_limits[0];
  limits.max_density_ratio = scene.sph.density_ratio_limits[1];
  if (scene.run.max_speed) {
    limits.max_speed = *scene.run.max_speed;
    return limits;
  }
  if (role == Role::sph) {
    limits.max_speed = scene.sph.sound_speed;
    return limits;
  }
  double fastest = 0;
  for (const auto& set : scene.particle_sets) {
    fastest = std::max(fastest, set.velocity.norm());
    for (const auto& sphere : set.spheres) fastest = std::max(fastest, sphere.velocity.norm());
  }
  for (const auto& fluid : scene.fluids) fastest = std::max(fastest, fluid.velocity.norm());
  for (const auto& structure : scene.structures) fastest = std::max(fastest, structure.velocity.norm());
  limits.max_speed = std::max(kDefaultMaxSpeed, 10.0 * fastest);
  return limits;
}

namespace {

// "; and 7 more" when `count` entities are bad and `shown` of them are named.
std::string and_more(std::size_t count, std::size_t shown) {
  return count > shown ? fmt::format("; and {} more", count - shown) : std::string();
}

}  // namespace

std::optional<Instability> check_motion(std::span<const Vec3> position, std::span<const Vec3> velocity,
                                        std::span<const std::uint8_t> active, double max_speed, std::string_view noun,
                                        std::span<const std::uint64_t> ids) {
  const double limit2 = max_speed * max_speed;
  Instability found;
  std::size_t count = 0;
  bool all_finite = true;
  for (std::size_t i = 0; i < position.size(); ++i) {
    if (!active.empty() && active[i] == 0) continue;
    const Vec3& x = position[i];
    const Vec3& v = velocity[i];
    const bool finite = std::isfinite(x.x() + x.y() + x.z()) && std::isfinite(v.x() + v.y() + v.z());
    if (finite && !(v.squaredNorm() > limit2)) continue;  // the square is inf when it overflows: too fast
    ++count;
    all_finite = all_finite && finite;
    if (found.indices.size() >= Instability::kMaxReported) continue;
    found.indices.push_back(i);
    found.detail +=
        fmt::format("{}{} {}: at ({:.6g}, {:.6g}, {:.6g}) m, velocity ({:.6g}, {:.6g}, {:.6g}) m/s{}",
                    found.indices.size() > 1 ? "; " : "", noun, ids.empty() ? i : ids[i], x.x(), x.y(), x.z(), v.x(),
                    v.y(), v.z(), finite ? fmt::format(", speed {:.6g} m/s", v.stableNorm()) : ", not finite");
  }
  if (count == 0) return std::nullopt;
  found.what = all_finite ? "too fast" : "not finite";
  found.detail = fmt::format("{} {}{} {} max_speed = {:g} m/s: {}{}", count, noun, count > 1 ? "s" : "",
                             all_finite ? "faster than" : "not finite, or faster than", max_speed, found.detail,
                             and_more(count, found.indices.size()));
  return found;
}

std::optional<Instability> check_density(std::span<const double> density, std::span<const std::uint32_t> material,
                                         std::span<const double> rest_density, std::span<const std::uint8_t> active,
                                         const StabilityLimits& limits) {
  Instability found;
  std::size_t count = 0;
  for (std::size_t i = 0; i < density.size(); ++i) {
    if (!active.empty() && active[i] == 0) continue;
    const double ratio = density[i] / rest_density[material[i]];
    if (ratio >= limits.min_density_ratio && ratio <= limits.max_density_ratio) continue;  // false for NaN
    ++count;
    if (found.indices.size() >= Instability::kMaxReported) continue;
    found.indices.push_back(i);
    found.detail += fmt::format("{}particle {}: density {:.6g} kg/m^3, {:.4g} times its rest density",
                                found.indices.size() > 1 ? "; " : "", i, density[i], ratio);
  }
  if (count == 0) return std::nullopt;
  found.what = "density";
  found.detail = fmt::format(
      "{} particle{} with a density outside sph.density_ratio_limits = [{:g}, {:g}] of the rest density: {}{}", count,
      count > 1 ? "s" : "", limits.min_density_ratio, limits.max_density_ratio, found.detail,
      and_more(count, found.indices.size()));
  return found;
}

void write_instability(const std::filesystem::path& file, std::span<const Vec3> position,
                       std::span<const Vec3> velocity, const Instability& instability, double radius,
                       std::span<const std::pair<std::string, std::span<const double>>> point_data) {
  std::vector<std::size_t> chosen(instability.indices.begin(), instability.indices.end());
  const double r2 = radius * radius;
  for (std::size_t i = 0; i < position.size(); ++i) {
    if (std::find(instability.indices.begin(), instability.indices.end(), i) != instability.indices.end()) continue;
    for (const std::size_t c : instability.indices) {
      // A culprit whose position is not finite has no neighbours.
      if ((position[i] - position[c]).squaredNorm() <= r2) {
        chosen.push_back(i);
        break;
      }
    }
  }
  std::vector<Vec3> points, velocities;
  std::vector<std::uint8_t> culprit;
  std::vector<std::uint64_t> index;
  for (const std::size_t i : chosen) {
    points.push_back(position[i]);
    velocities.push_back(velocity[i]);
    culprit.push_back(index.size() < instability.indices.size() ? 1 : 0);
    index.push_back(i);
  }
  std::vector<std::vector<double>> picked;
  for (const auto& [name, values] : point_data) {
    auto& column = picked.emplace_back();
    for (const std::size_t i : chosen) column.push_back(i < values.size() ? values[i] : 0.0);
  }
  std::vector<io::vtk::Array> arrays{io::vtk::Array::vectors("velocity", velocities),
                                     io::vtk::Array::of<std::uint8_t>("culprit", culprit),
                                     io::vtk::Array::of<std::uint64_t>("index", index)};
  for (std::size_t k = 0; k < point_data.size(); ++k) {
    arrays.push_back(io::vtk::Array::scalars(point_data[k].first, picked[k]));
  }
  io::vtk::write_points(file, points, arrays);
}

std::filesystem::path instability_file(const std::filesystem::path& run_dir, Role role) {
  const auto first = run_dir / "instability.vtp";
  // Claimed atomically: two processes that fail at the same step write a file each.
  const int fd = ::open(first.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd >= 0) {
    ::close(fd);
    return first;
  }
  return run_dir / fmt::format("instability_{}.vtp", role_name(role));
}

}  // namespace sabo::solver
