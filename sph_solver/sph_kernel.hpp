#pragma once
// SPH smoothing kernels in 3-D, support 2h. Each gives W(r) and
// F(r) = (dW/dr) / r, so that grad_i W_ij = F(r_ij) (x_i - x_j) without a division.
#include <cmath>
#include <numbers>

#include "libsabo/scene/scene.hpp"

namespace sabo::sph {

struct Kernel {
  scene::SphSettings::Kernel type = scene::SphSettings::Kernel::wendland_c2;
  double h = 0;               // m, smoothing length
  double inverse_h = 0;       // 1/m
  double normalisation = 0;   // 1/m^3 (alpha_d)
  double gradient_scale = 0;  // alpha_d / h^2, 1/m^5

  Kernel() = default;
  Kernel(scene::SphSettings::Kernel kind, double smoothing_length) : type(kind), h(smoothing_length) {
    inverse_h = 1.0 / h;
    const double h3 = h * h * h;
    normalisation = kind == scene::SphSettings::Kernel::wendland_c2 ? 21.0 / (16.0 * std::numbers::pi * h3)
                                                                    : 1.0 / (std::numbers::pi * h3);
    gradient_scale = normalisation / (h * h);
  }

  [[nodiscard]] double support() const { return 2.0 * h; }

  [[nodiscard]] double value(double r) const {
    const double q = r * inverse_h;
    if (q >= 2.0) return 0.0;
    if (type == scene::SphSettings::Kernel::wendland_c2) {
      const double a = 1.0 - 0.5 * q;
      const double a2 = a * a;
      return normalisation * a2 * a2 * (2.0 * q + 1.0);
    }
    if (q < 1.0) return normalisation * (1.0 - 1.5 * q * q + 0.75 * q * q * q);
    const double b = 2.0 - q;
    return normalisation * 0.25 * b * b * b;
  }

  // (dW/dr) / r, 1/m^5 (negative inside the support).
  [[nodiscard]] double gradient_factor(double r) const {
    const double q = r * inverse_h;
    if (q >= 2.0) return 0.0;
    if (type == scene::SphSettings::Kernel::wendland_c2) {
      const double a = 1.0 - 0.5 * q;
      return -5.0 * gradient_scale * a * a * a;
    }
    if (q < 1.0) return gradient_scale * (-3.0 + 2.25 * q);
    const double b = 2.0 - q;
    return -0.75 * gradient_scale * b * b / q;
  }
};

}  // namespace sabo::sph
