#pragma once
// The pair terms of the SPH passes (sph_solver/passes/*.cpp), private to sph_solver/: which
// terms a step computes (Terms, with_terms), the kernel in single precision, the pair
// formulas shared by the fluid and wall loops, the small tensors they carry in registers,
// and the artificial stress of a particle (gather(), passes/grid.cpp).
//
// An unnamed namespace: each pass file gets its own internal copy, and no symbol leaves
// the library.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "libsabo/core/types.hpp"
#include "libsabo/scene/scene.hpp"
#include "sph_solver/sph_kernel.hpp"

namespace sabo::sph {
namespace {

using Rheology = scene::Material::Rheology;
using KernelKind = scene::SphSettings::Kernel;
using DensityDiffusion = scene::SphSettings::DensityDiffusion;

// The terms a step computes, fixed at compile time: the pair loops carry no
// branch for a term that no material asks for.
template <KernelKind Kind, bool Viscous, bool Stress, DensityDiffusion Diffusion, bool Artificial = false,
          bool Transpose = false>
struct Terms {
  static constexpr KernelKind kernel = Kind;
  static constexpr bool viscous = Viscous;        // velocity gradients, Morris's pair term for div(eta L)
  static constexpr bool stress = Stress;          // deviatoric stress (elastic-plastic)
  static constexpr bool artificial = Artificial;  // Monaghan's artificial stress (fluid pairs only)
  // With viscous: the divergence of eta L~^T, so that the viscous stress is 2 eta D
  // (sph.viscous_operator = "strain_rate").
  static constexpr bool transpose = Viscous && Transpose;
  static constexpr bool diffusion = Diffusion != DensityDiffusion::none;
  static constexpr bool hydrostatic = Diffusion == DensityDiffusion::fourtakas;
};

// AllowArtificial: the caller has an artificial-stress path (only the fluid pair loop);
// AllowTranspose: the caller has the eta L^T path (the fluid and wall force loops). The
// others are not instantiated for them.
template <bool AllowArtificial = false, bool AllowTranspose = false, class F>
void with_terms(KernelKind kind, bool viscous, bool stress, bool artificial, bool transpose, DensityDiffusion diffusion,
                F&& f) {
  const auto with_diffusion = [&]<KernelKind K, bool V, bool S, bool A = false, bool Tr = false>() {
    switch (diffusion) {
      case DensityDiffusion::none: f(Terms<K, V, S, DensityDiffusion::none, A, Tr>{}); return;
      case DensityDiffusion::molteni: f(Terms<K, V, S, DensityDiffusion::molteni, A, Tr>{}); return;
      case DensityDiffusion::fourtakas: f(Terms<K, V, S, DensityDiffusion::fourtakas, A, Tr>{}); return;
    }
  };
  // The viscous variants, with or without the eta L^T term.
  const auto with_transpose = [&]<KernelKind K, bool S, bool A = false>() {
    if constexpr (AllowTranspose) {
      if (transpose) {
        with_diffusion.template operator()<K, true, S, A, true>();
        return;
      }
    }
    with_diffusion.template operator()<K, true, S, A>();
  };
  const auto with_rheology = [&]<KernelKind K>() {
    if constexpr (AllowArtificial) {
      if (stress && artificial) {
        with_transpose.template operator()<K, true, true>();
        return;
      }
    }
    if (stress) {
      with_transpose.template operator()<K, true>();
    } else if (viscous) {
      with_transpose.template operator()<K, false>();
    } else {
      with_diffusion.template operator()<K, false, false>();
    }
  };
  if (kind == KernelKind::wendland_c2) {
    with_rheology.template operator()<KernelKind::wendland_c2>();
  } else {
    with_rheology.template operator()<KernelKind::cubic_spline>();
  }
}

// The kernel of sph_kernel.hpp in single precision, branch-free for the vectorised loops.
struct KernelF {
  float inverse_h, normalisation, gradient_scale;
  explicit KernelF(const Kernel& kernel)
      : inverse_h(static_cast<float>(kernel.inverse_h)),
        normalisation(static_cast<float>(kernel.normalisation)),
        gradient_scale(static_cast<float>(kernel.gradient_scale)) {}
};

// (dW/dr) / r at squared distance r2 < (2h)^2, 1/m^5; finite for every r2 >= 0.
template <KernelKind Kind>
inline float gradient_factor(float r2, const KernelF& k) {
  const float q = std::sqrt(r2) * k.inverse_h;
  if constexpr (Kind == KernelKind::wendland_c2) {
    const float a = 1.0f - 0.5f * q;
    return -5.0f * k.gradient_scale * a * a * a;
  } else {
    const float inner = k.gradient_scale * (-3.0f + 2.25f * q);
    const float b = 2.0f - q;
    const float outer = -0.75f * k.gradient_scale * b * b / std::max(q, 1e-6f);
    return q < 1.0f ? inner : outer;
  }
}

// W at squared distance r2 < (2h)^2, 1/m^3.
template <KernelKind Kind>
inline float kernel_value(float r2, const KernelF& k) {
  const float q = std::sqrt(r2) * k.inverse_h;
  if constexpr (Kind == KernelKind::wendland_c2) {
    const float a = 1.0f - 0.5f * q;
    const float a2 = a * a;
    return k.normalisation * a2 * a2 * (2.0f * q + 1.0f);
  } else {
    const float inner = k.normalisation * (1.0f - 1.5f * q * q + 0.75f * q * q * q);
    const float b = 2.0f - q;
    const float outer = k.normalisation * 0.25f * b * b * b;
    return q < 1.0f ? inner : outer;
  }
}

// Pressure and Monaghan viscosity of a pair, per unit F(r) r_ij: the acceleration of i
// is pair_scalar * F * r_ij. Symmetric in i and j for equal masses (the same float).
inline float pair_scalar(float m_j, float pr_i, float pr_j, float vr, float inverse_r2, float rho_i, float rho_j,
                         float alpha_hc) {
  const float pressure = -m_j * (pr_i + pr_j);
  const float viscosity = m_j * alpha_hc * vr * inverse_r2 / (0.5f * (rho_i + rho_j));
  return vr < 0.0f ? pressure + viscosity : pressure;
}

// A symmetric 3x3 tensor (stress, Pa, or stress over density squared): six scalars,
// which the vectoriser keeps in registers (arrays it would not).
struct Sym6 {
  float xx = 0, yy = 0, zz = 0, xy = 0, yz = 0, zx = 0;
};

// Component q of slot j at s[q * stride + j] (component-major: contiguous vector loads).
inline Sym6 load_sym6(const float* s, std::size_t stride, std::size_t j) {
  return {s[j], s[stride + j], s[2 * stride + j], s[3 * stride + j], s[4 * stride + j], s[5 * stride + j]};
}

// Adds S . (f r) to t.
inline void add_stress_dot(const Sym6& s, float f, float rx, float ry, float rz, float& tx, float& ty, float& tz) {
  const float gx = f * rx, gy = f * ry, gz = f * rz;
  tx += s.xx * gx + s.xy * gy + s.zx * gz;
  ty += s.xy * gx + s.yy * gy + s.yz * gz;
  tz += s.zx * gx + s.yz * gy + s.zz * gz;
}

// A general 3x3 tensor (eta L^T, Pa), nine scalars kept in registers like Sym6; ab is row a, column b.
struct Mat9 {
  float xx = 0, xy = 0, xz = 0, yx = 0, yy = 0, yz = 0, zx = 0, zy = 0, zz = 0;
};

// Component ab of slot j at s[(3 a + b) * stride + j].
inline Mat9 load_mat9(const float* s, std::size_t stride, std::size_t j) {
  return {s[j],
          s[stride + j],
          s[2 * stride + j],
          s[3 * stride + j],
          s[4 * stride + j],
          s[5 * stride + j],
          s[6 * stride + j],
          s[7 * stride + j],
          s[8 * stride + j]};
}

// Adds c (A + B) . r to t.
inline void add_sum_dot(const Mat9& a, const Mat9& b, float c, float rx, float ry, float rz, float& tx, float& ty,
                        float& tz) {
  const float gx = c * rx, gy = c * ry, gz = c * rz;
  tx += (a.xx + b.xx) * gx + (a.xy + b.xy) * gy + (a.xz + b.xz) * gz;
  ty += (a.yx + b.yx) * gx + (a.yy + b.yy) * gy + (a.yz + b.yz) * gz;
  tz += (a.zx + b.zx) * gx + (a.zy + b.zy) * gy + (a.zz + b.zz) * gz;
}

// The approach of fluid particle i and a wall particle for the artificial viscosity: `full` = (v_i - v_w).r,
// d = v_i - v_w; against a free-slip wall particle (s its unit normal; zero for a no-slip one) the normal part
// only, (d.s)(s.r): the wall takes no tangential friction from the artificial viscosity, as none from the
// viscous terms (a uniform flow along it keeps its speed).
inline float wall_approach(float full, float dx, float dy, float dz, float rx, float ry, float rz, float sx, float sy,
                           float sz) {
  // |s|^2 is 1 or 0: for a no-slip particle full + (0 - 0), full to the bit.
  const float normal = (dx * sx + dy * sy + dz * sz) * (rx * sx + ry * sy + rz * sz);
  return full + (normal - full * (sx * sx + sy * sy + sz * sz));
}

// Acceleration t of fluid particle i (density rho_i, p_i / rho_i^2 = pr_i, viscosity
// eta_i, stress s_i) from wall particle b (mass m_b, density rho_b, pr_b), r = x_i - x_b,
// vr = (v_i - v_wall).r, u = v_i - v_b (no-slip wall velocity), s_b the wall's stress
// (the fluid's, extrapolated in boundary_state). One function for both sides of the
// pair: the force on the wall particle is minus m_i times the same float.
// t_i: the fluid particle's eta L~^T (sph.viscous_operator = "strain_rate"); the wall
// particle carries the same (the no-slip image continues the fluid's velocity gradient, as
// its velocity 2 v_w - v~ continues the velocity), so the pair adds
// m_b / (rho_i rho_b) 2 t_i . grad W, with Morris's r^2 / (r^2 + eta^2).
template <class T>
inline void wall_pair(float m_b, float rho_b, float pr_b, float rho_i, float pr_i, float eta_i, const Sym6& s_i,
                      const Sym6& s_b, const Mat9& t_i, float f, float rx, float ry, float rz, float r2, float vr,
                      float inverse_r2, float ux, float uy, float uz, float alpha_hc, float& tx, float& ty, float& tz) {
  const float sf = pair_scalar(m_b, pr_i, pr_b, vr, inverse_r2, rho_i, rho_b, alpha_hc) * f;
  tx = sf * rx;
  ty = sf * ry;
  tz = sf * rz;
  if constexpr (T::viscous) {
    const float viscous = m_b * 2.0f * eta_i / (rho_i * rho_b) * f * r2 * inverse_r2;
    tx += viscous * ux;
    ty += viscous * uy;
    tz += viscous * uz;
  }
  if constexpr (T::transpose) {
    const float c = m_b / (rho_i * rho_b) * f * r2 * inverse_r2;
    add_sum_dot(t_i, t_i, c, rx, ry, rz, tx, ty, tz);
  }
  if constexpr (T::stress) {
    const float a_i = m_b / (rho_i * rho_i), a_b = m_b / (rho_b * rho_b);
    const Sym6 sum{s_i.xx * a_i + s_b.xx * a_b, s_i.yy * a_i + s_b.yy * a_b, s_i.zz * a_i + s_b.zz * a_b,
                   s_i.xy * a_i + s_b.xy * a_b, s_i.yz * a_i + s_b.yz * a_b, s_i.zx * a_i + s_b.zx * a_b};
    add_stress_dot(sum, f, rx, ry, rz, tx, ty, tz);
  }
}

// A symmetric tensor stored as 6 components (xx yy zz xy yz zx), as a matrix and back.
inline Mat3 unpack_sym6(const double* s) {
  Mat3 m;
  m << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
  return m;
}
inline void pack_sym6(const Mat3& m, double* out) {
  out[0] = m(0, 0);
  out[1] = m(1, 1);
  out[2] = m(2, 2);
  out[3] = m(0, 1);
  out[4] = m(1, 2);
  out[5] = m(2, 0);
}

// Monaghan's artificial stress of one particle over its density squared (Gray, Monaghan &
// Swift 2001): sigma = -p I + S (Pa, s: xx yy zz xy yz zx) in its principal axes, each
// tensile principal stress sigma_a > 0 gives R_a = -epsilon sigma_a / rho^2, back to the
// lattice axes; compressive ones give 0. Pa m^6/kg^2.
inline void artificial_stress(const double* s, double p, double rho, double epsilon, double (&out)[6]) {
  const Mat3 sigma = unpack_sym6(s) - p * Mat3::Identity();
  for (double& v : out) v = 0;
  Eigen::SelfAdjointEigenSolver<Mat3> eigen;
  eigen.computeDirect(sigma);
  const Vec3 principal = eigen.eigenvalues();
  if (principal.maxCoeff() <= 0) return;
  const double scale = -epsilon / (rho * rho);
  const Vec3 r = principal.unaryExpr([&](double v) { return v > 0 ? scale * v : 0.0; });
  const Mat3& axes = eigen.eigenvectors();
  pack_sym6(axes * r.asDiagonal() * axes.transpose(), out);
}

// Density difference that delta-SPH diffuses between fluid particles i and j (Fourtakas et
// al. 2019, in its dynamic-pressure form): the pressure difference less the hydrostatic
// one, (p_j - p_i - rho_mean g.(x_j - x_i)) / c^2, r = x_i - x_j. It vanishes in a fluid
// at rest for any EOS; the density difference less rho0 g.(x_j - x_i) / c^2 does not: Tait
// stiffens by (rho/rho0)^(gamma-1), 6 % at rho = 1.01 rho0.
inline float dynamic_density_difference(float p_i, float p_j, float rho_i, float rho_j, float g_dot_r,
                                        float inverse_c2) {
  return (p_j - p_i + 0.5f * (rho_i + rho_j) * g_dot_r) * inverse_c2;
}

}  // namespace
}  // namespace sabo::sph
