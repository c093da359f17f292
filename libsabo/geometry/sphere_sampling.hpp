#pragma once
// Boundary particles of a sphere for SPH walls (Adami, Hu & Adams 2012), as
// the structure walls have them (surface_sampling.hpp): `layers` spherical
// shells at depths (k + 1/2) dx below the surface, k = 0 .. layers - 1 (those
// of positive radius). Shell k of radius r_k holds N_k = max(1, round(4 pi
// r_k^2 / dx^2)) points on a golden-angle (Fibonacci) spiral, so that each
// point covers about dx^2 of its shell; the spirals of successive shells are
// turned against each other so that their points do not line up radially.
// A point's volume is its shell's, 4/3 pi ((r_k + dx/2)^3 - (r_k - dx/2)^3)
// (its inner radius clipped at 0), over N_k: the layers sum to the volume of
// the sphere down to the last shell. Its normal is radial, out of the sphere
// (into the fluid). Deterministic: the same radius, spacing and layers give
// the same bits.
#include <cstddef>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::geometry {

struct SphereSampling {
  std::vector<Vec3> offset;    // m, from the centre
  std::vector<Vec3> normal;    // unit, radial
  std::vector<double> volume;  // m^3
  [[nodiscard]] std::size_t size() const { return offset.size(); }
};

// radius, spacing > 0 (m), layers >= 1. Throws sabo::Error otherwise.
[[nodiscard]] SphereSampling sample_sphere(double radius, double spacing, std::size_t layers);

}  // namespace sabo::geometry
