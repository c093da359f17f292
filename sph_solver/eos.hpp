#pragma once
// Equations of state of the weakly compressible fluids (docs/scene.md,
// [materials.NAME] eos): pressure from density and its inverse.
#include <cmath>

#include "libsabo/scene/scene.hpp"

namespace sabo::sph {

struct EquationOfState {
  scene::Material::Eos kind = scene::Material::Eos::tait;
  double rest_density = 1000;  // kg/m^3
  double sound_speed = 10;     // m/s, artificial
  double tait_b = 0;           // Pa
  double gamma = 7;
  double c0 = 0, c1 = 0, c2 = 0, c3 = 0;  // Pa (polynomial, c1..c3 scaled to the artificial stiffness)

  EquationOfState() = default;
  EquationOfState(const scene::Material& material, double artificial_sound_speed)
      : kind(material.eos), rest_density(material.density), sound_speed(artificial_sound_speed) {
    gamma = material.tait_exponent;
    tait_b = rest_density * sound_speed * sound_speed / gamma;
    if (kind == scene::Material::Eos::polynomial) {
      const double scale = rest_density * sound_speed * sound_speed / material.eos_c1;
      c0 = material.eos_c0;
      c1 = material.eos_c1 * scale;
      c2 = material.eos_c2 * scale;
      c3 = material.eos_c3 * scale;
    }
  }

  [[nodiscard]] double pressure(double density) const {
    if (kind == scene::Material::Eos::tait) return tait_b * (std::pow(density / rest_density, gamma) - 1.0);
    const double mu = density / rest_density - 1.0;
    return c0 + mu * (c1 + mu * (c2 + mu * c3));
  }

  // Compression energy per unit mass, J/kg: e(rho) = integral of p / rho^2 from rest_density
  // to rho, the internal energy whose rate p/rho^2 drho/dt the symmetric pressure force
  // balances, so that kinetic + potential + sum m e is conserved (up to the dissipation).
  [[nodiscard]] double specific_energy(double density) const {
    const double mu = density / rest_density - 1.0;
    const double log_x = std::log1p(mu);
    if (kind == scene::Material::Eos::tait) {
      return tait_b / rest_density * (std::expm1((gamma - 1.0) * log_x) / (gamma - 1.0) - mu / (1.0 + mu));
    }
    // (1/rho0) integral over m from 0 to mu of p(m) / (1 + m)^2, term by term with u = 1 + m.
    const double u = 1.0 + mu;
    const double i0 = mu / u;                                                 // of 1 / u^2
    const double i1 = log_x - mu / u;                                         // of (u - 1) / u^2
    const double i2 = mu - 2.0 * log_x + mu / u;                              // of (u - 1)^2 / u^2
    const double i3 = 0.5 * (u * u - 1.0) - 3.0 * mu + 3.0 * log_x - mu / u;  // of (u - 1)^3 / u^2
    return (c0 * i0 + c1 * i1 + c2 * i2 + c3 * i3) / rest_density;
  }

  // The density at which pressure(density) == p (Newton on the polynomial, from the linear guess).
  [[nodiscard]] double density(double p) const {
    if (kind == scene::Material::Eos::tait) {
      return rest_density * std::pow(std::max(p / tait_b + 1.0, 1e-6), 1.0 / gamma);
    }
    double mu = (p - c0) / c1;
    for (int k = 0; k < 20; ++k) {
      const double f = c0 + mu * (c1 + mu * (c2 + mu * c3)) - p;
      const double df = c1 + mu * (2.0 * c2 + 3.0 * mu * c3);
      if (df <= 0) break;
      const double step = f / df;
      mu -= step;
      if (std::abs(step) < 1e-15) break;
    }
    return rest_density * (1.0 + mu);
  }
};

}  // namespace sabo::sph
