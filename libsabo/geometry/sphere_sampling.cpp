#include "libsabo/geometry/sphere_sampling.hpp"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "libsabo/core/error.hpp"

namespace sabo::geometry {

SphereSampling sample_sphere(double radius, double spacing, std::size_t layers) {
  if (!(radius > 0) || !(spacing > 0) || layers == 0 || !std::isfinite(radius) || !std::isfinite(spacing)) {
    throw Error(fmt::format("sample_sphere: radius {} m and spacing {} m must be > 0, layers {} >= 1", radius, spacing,
                            layers));
  }
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  SphereSampling out;
  for (std::size_t k = 0; k < layers; ++k) {
    const double shell = radius - (static_cast<double>(k) + 0.5) * spacing;
    if (shell <= 0) break;
    const double inner = std::max(0.0, shell - 0.5 * spacing), outer = shell + 0.5 * spacing;
    const auto count = static_cast<std::size_t>(
        std::max(1.0, std::round(4.0 * std::numbers::pi * shell * shell / (spacing * spacing))));
    const double volume =
        4.0 / 3.0 * std::numbers::pi * (outer * outer * outer - inner * inner * inner) / static_cast<double>(count);
    const double turn = 0.5 * golden_angle * static_cast<double>(k);
    for (std::size_t i = 0; i < count; ++i) {
      const double z = count == 1 ? 1.0 : 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(count);
      const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const double phi = turn + golden_angle * static_cast<double>(i);
      const Vec3 n(r * std::cos(phi), r * std::sin(phi), z);
      out.normal.push_back(n);
      out.offset.push_back(shell * n);
      out.volume.push_back(volume);
    }
  }
  return out;
}

}  // namespace sabo::geometry
