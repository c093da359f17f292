#include "sph_solver/sph_model.hpp"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <string>

#include "libsabo/core/error.hpp"
#include "libsabo/core/isa.hpp"

namespace sabo::sph {
namespace {

using Rheology = scene::Material::Rheology;
using KernelKind = scene::SphSettings::Kernel;
using DensityDiffusion = scene::SphSettings::DensityDiffusion;
using WallWork = scene::SphSettings::WallWork;

// Above this many particles (or wall particles; images not counted: the loops skip them) the loops run in parallel.
constexpr std::size_t kParallelThreshold = 512;
// More cells than this means a domain far larger than the particles need.
constexpr std::int64_t kMaxCells = std::int64_t{1} << 27;
// Slots per block of the inner loops (one AVX-512 register of floats); the
// cell-ordered arrays carry this many padding entries.
constexpr std::uint32_t kLanes = 16;
// Particles per block of the energy sums (fixed: the same bits on any number of threads).
constexpr std::size_t kEnergyBlock = 4096;
// Sums per block: kinetic, potential, elastic, wall work held back.
constexpr std::size_t kEnergyTerms = 4;
// Kernel moments per wall slot for the stress extrapolation: W, W p, W e (3), W e e^T (6),
// W p e (3), W S_f (6), e = x_f - x_w.
constexpr std::size_t kWallMoments = 20;
// Padding slots sit this far (m) from everything: outside every support.
constexpr float kFarAway = 1e6f;
// The kernel-gradient correction of the strain-rate viscosity (compute_velocity_gradients):
// the eigenvalues of the moment matrix M (1 in the bulk, about 1/2 across a free surface) are
// held at this or more, so that a particle with almost no neighbours along some direction
// (a splash) is amplified at most 1 / kMinGradientMoment times. A cube's corner particle has 0.19
// (Wendland C2, h = 1.5 dx) and is corrected in full.
constexpr double kMinGradientMoment = 0.1;

// The fraction of a fluid particle's wall credit (wall_compression()) that wall_work =
// "bounded" applies. stored (J): the compression energy the whole credit would store this
// step; held (J): the wall work the particle has held back so far. Work the fluid loses to
// the walls (stored >= 0) is held back, not stored, as without any credit; work the walls
// give back (stored < 0) is paid from what is held, and only the part beyond it is credited.
// So held never goes below zero, and the walls' pressure never gives the fluid energy that
// the fluid did not first lose to it.
double bounded_credit(double stored, float& held) {
  if (stored >= 0.0 || held >= -stored) {
    held = static_cast<float>(std::max(0.0, held + stored));  // >= 0 through the rounding too
    return 0.0;
  }
  const double beyond = 1.0 + held / stored;  // of -stored, what held cannot pay
  held = 0.0f;
  return beyond;
}

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

// Particles per unit of work handed to with_best_isa() by the parallel loops.
constexpr std::int64_t kChunk = 64;

// Resizes a cell-ordered array to count + kLanes entries, the padding set to `pad`.
template <class V>
void resize_padded(std::vector<V>& array, std::size_t count, V pad) {
  array.resize(count + kLanes);
  std::fill(array.begin() + static_cast<std::ptrdiff_t>(count), array.end(), pad);
}

// Adds to s the deviatoric stress that the shear traction grows by over the distance
// d_n (m) along the wall normal n: t n + n t, t = d_n times the part of `growth` along the
// wall, growth = rho (a_w - g) + grad p (the tangential momentum balance next to a wall,
// d(S.n)_t/dn = rho (a - g)_t + (grad p)_t, docs/physics.md; the normal part is the
// pressure's, eq. 27).
inline void add_wall_shear(const Vec3& growth, const Vec3& n, double d_n, Sym6& s) {
  const Vec3 t = d_n * (growth - growth.dot(n) * n);
  s.xx += static_cast<float>(2.0 * t.x() * n.x());
  s.yy += static_cast<float>(2.0 * t.y() * n.y());
  s.zz += static_cast<float>(2.0 * t.z() * n.z());
  s.xy += static_cast<float>(t.x() * n.y() + n.x() * t.y());
  s.yz += static_cast<float>(t.y() * n.z() + n.y() * t.z());
  s.zx += static_cast<float>(t.z() * n.x() + n.z() * t.x());
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

double FluidMaterial::viscosity_at(double shear_rate) const {
  // Papanastasiou's yield term tau_y (1 - exp(-gamma_dot / gamma_0)) / gamma_dot, limit tau_y / gamma_0.
  const auto yield_term = [&] {
    const double x_rate = shear_rate / yield_shear_rate;
    const double factor = x_rate > 1e-8 ? -std::expm1(-x_rate) / shear_rate : 1.0 / yield_shear_rate;
    return yield_stress * factor;
  };
  switch (rheology) {
    case Rheology::inviscid: return 0;
    case Rheology::newtonian: return viscosity;
    case Rheology::bingham: return viscosity + yield_term();
    case Rheology::herschel_bulkley:
      // K gamma_dot^(n-1), held at its value at gamma_0 below it (bounded for n < 1).
      return consistency_index * std::pow(std::max(shear_rate, yield_shear_rate), flow_index - 1.0) + yield_term();
    case Rheology::elastic_plastic: return viscosity;
  }
  return 0;
}

double FluidMaterial::max_viscosity() const {
  switch (rheology) {
    case Rheology::inviscid: return 0;
    case Rheology::newtonian: return viscosity;
    case Rheology::bingham: return viscosity + yield_stress / yield_shear_rate;
    case Rheology::herschel_bulkley:
      return consistency_index * std::pow(yield_shear_rate, flow_index - 1.0) + yield_stress / yield_shear_rate;
    case Rheology::elastic_plastic: return viscosity;
  }
  return 0;
}

// The inner loops index slots in 64 bits and test lanes in 32 bits: contiguous vector loads.
template <class Block>
void SphModel::for_neighbour_blocks(const Vec3& position, const std::vector<std::uint32_t>& start,
                                    const float* sorted_x, Block&& block) const {
  NeighbourRow rows[9];
  const int row_count = neighbour_rows(position.x(), position.y(), position.z(), start, rows);
  for (int r = 0; r < row_count; ++r) {
    const std::uint32_t end = rows[r].end;
    // Blocks wholly outside the x window hold no neighbour: skipped.
    std::uint32_t j0 = rows[r].begin;
    while (j0 < end && sorted_x[std::min(j0 + kLanes, end) - 1] < rows[r].x_min) j0 += kLanes;
    std::uint32_t stop = j0;
    while (stop < end && sorted_x[stop] <= rows[r].x_max) stop += kLanes;
    for (; j0 < stop; j0 += kLanes) block(j0, static_cast<std::int32_t>(std::min(end - j0, kLanes)));
  }
}

namespace {

// Neighbours of a point of a cubic lattice within `reach` lattice spacings (itself excluded).
int lattice_neighbours(double reach) {
  const auto cells = static_cast<int>(std::ceil(reach));
  int count = 0;
  for (int a = -cells; a <= cells; ++a) {
    for (int b = -cells; b <= cells; ++b) {
      for (int c = -cells; c <= cells; ++c) count += (a * a + b * b + c * c) < reach * reach ? 1 : 0;
    }
  }
  return count - 1;
}

}  // namespace

SphModel::SphModel(const scene::Scene& scene)
    : settings_(scene.sph),
      kernel_(scene.sph.kernel, scene.sph.smoothing_length()),
      gravity_(scene.run.gravity),
      sound_speed_(scene.sph.sound_speed) {
  eta_squared_ = 0.01 * kernel_.h * kernel_.h;
  // Penalty walls put no particles into a kernel: the fluid beside them, cut off like a free
  // surface, needs the diffusion (S4 with penalty walls: pressure error 8.9 % with it, 52 %
  // without), so there every pair diffuses.
  if (scene.sph.wall_model == scene::SphSettings::WallModel::boundary_particles) {
    full_support_neighbours_ = static_cast<std::int32_t>(
        std::ceil(kFullSupportFraction * lattice_neighbours(kernel_.support() / scene.sph.particle_spacing)));
  }
  // Materials used by fluids, in scene material order (index = material id).
  std::vector<std::uint32_t> body_material;
  materials_.resize(scene.materials.size());
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    const scene::Material& source = scene.materials[m];
    FluidMaterial& material = materials_[m];
    material.eos = EquationOfState(source, sound_speed_);
    material.rheology = source.rheology;
    material.viscosity = source.viscosity;
    material.yield_stress = source.yield_stress.value_or(0.0);
    material.yield_shear_rate = source.yield_shear_rate;
    material.consistency_index = source.consistency_index;
    material.flow_index = source.flow_index;
    material.shear_modulus = source.fluid_shear_modulus > 0 ? source.fluid_shear_modulus : source.shear_modulus();
    if (material.rheology == Rheology::elastic_plastic) {
      material.artificial_stress = source.artificial_stress.value_or(kDefaultArtificialStress);
      // Elastic waves: c_eff^2 = c^2 + 4 G / (3 rho0).
      const double c_eff =
          std::sqrt(sound_speed_ * sound_speed_ + 4.0 * material.shear_modulus / (3.0 * material.eos.rest_density));
      elastic_wave_dt_ = std::min(elastic_wave_dt_, kernel_.h / c_eff);
    }
  }
  for (const auto& body : scene.fluids) {
    const auto m = static_cast<std::uint32_t>(scene.material_index(body.material));
    body_material.push_back(m);
    any_gradient_ = any_gradient_ || materials_[m].needs_velocity_gradient();
    has_stress_ = has_stress_ || materials_[m].rheology == Rheology::elastic_plastic;
    any_artificial_stress_ = any_artificial_stress_ || materials_[m].artificial_stress > 0;
    strain_rate_viscosity_ = strain_rate_viscosity_ || materials_[m].max_viscosity() > 0;
  }
  strain_rate_viscosity_ =
      strain_rate_viscosity_ && settings_.viscous_operator == scene::SphSettings::ViscousOperator::strain_rate;
  FluidFill fill = fill_fluids(scene, materials_, body_material);
  position_ = std::move(fill.position);
  velocity_ = std::move(fill.velocity);
  density_ = std::move(fill.density);
  pressure_ = std::move(fill.pressure);
  mass_ = std::move(fill.mass);
  material_ = std::move(fill.material);
  body_ = std::move(fill.body);
  const std::size_t n = position_.size();
  acceleration_.assign(n, Vec3::Zero());
  if (has_stress_) {
    stress_ = std::move(fill.stress);
    stress_rate_.assign(6 * n, 0.0);
  }
  active_.assign(n, 1);
  for (const scene::FluidBody& body : scene.fluids) settle_time_.push_back(body.settle_time);
  const std::optional<std::array<double, 2>>* spans[2] = {&settings_.periodic_x, &settings_.periodic_y};
  for (int axis = 0; axis < 2; ++axis) {
    const auto& span = *spans[axis];
    if (!span) continue;
    const double period = (*span)[1] - (*span)[0];
    if (!(period >= 2.0 * kernel_.support())) {
      throw SceneError(fmt::format(
          "sph.periodic_{} = [{}, {}]: the period {} m is shorter than two kernel supports (4h = {} m). Fix: widen "
          "the span or lower sph.particle_spacing",
          axis == 0 ? 'x' : 'y', (*span)[0], (*span)[1], period, 2.0 * kernel_.support()));
    }
    periodic_.push_back({axis, (*span)[0], (*span)[1]});
  }
  if (!periodic_.empty()) {
    wrap_offset_.assign(n, Vec3::Zero());
    wrap_positions();
  }
  if (credits_wall_work() && settings_.wall_work == WallWork::bounded) wall_work_held_.assign(n, 0.0f);
  stable_dt_ = initial_stable_dt();
  energies_.kinetic = 0;
  for (std::size_t i = 0; i < n; ++i) {
    energies_.kinetic += 0.5 * mass_[i] * velocity_[i].squaredNorm();
    energies_.potential -=
        mass_[i] * gravity_.dot(wrap_offset_.empty() ? position_[i] : Vec3(position_[i] - wrap_offset_[i]));
    energies_.elastic += mass_[i] * materials_[material_[i]].eos.specific_energy(density_[i]);
  }
}

void SphModel::update_settle_factors(double dt) {
  // tau from h / c, the grid-scale acoustic modes critically damped, so that the fill's
  // imbalance at the free surface moves no particle faster than about a0 h / c, to
  // kSettleDampingGrowth h / c at the end, which lets the slower modes relax.
  const double acoustic = kernel_.h / sound_speed_;
  settle_factor_.resize(settle_time_.size());
  for (std::size_t b = 0; b < settle_time_.size(); ++b) {
    const double end = settle_time_[b];
    double& factor = settle_factor_[b];
    if (time_ >= end) {
      factor = 1.0;
    } else if (time_ + dt >= end) {
      factor = 0.0;  // the phase ends at rest
    } else {
      factor = std::exp(-dt / (acoustic * (1.0 + (scene::kSettleDampingGrowth - 1.0) * time_ / end)));
    }
  }
}

double SphModel::initial_stable_dt() const {
  const double h = kernel_.h;
  double dt = h / sound_speed_;
  const double g = gravity_.norm();
  if (g > 0) dt = std::min(dt, std::sqrt(h / g));
  double max_speed = 0;
  for (const Vec3& v : velocity_) max_speed = std::max(max_speed, v.norm());
  dt = std::min(dt, h / (sound_speed_ + max_speed));
  for (std::size_t m = 0; m < materials_.size(); ++m) {
    const double eta = materials_[m].max_viscosity();
    if (eta > 0 && std::find(material_.begin(), material_.end(), m) != material_.end()) {
      dt = std::min(dt, materials_[m].eos.rest_density * h * h / (8.0 * eta));
    }
  }
  return settings_.cfl * dt;
}

void SphModel::set_boundary(physics::BoundaryParticles boundary) {
  const std::size_t n = boundary.size();
  if (boundary.velocity.size() != n || boundary.normal.size() != n || boundary.acceleration.size() != n ||
      boundary.volume.size() != n || (!boundary.free_slip.empty() && boundary.free_slip.size() != n)) {
    throw ModelInputError(fmt::format(
        "boundary particles: {} positions but {} velocities, {} normals, {} "
        "accelerations, {} volumes, {} free-slip flags; every array needs one entry per particle (the flags "
        "may be empty)",
        n, boundary.velocity.size(), boundary.normal.size(), boundary.acceleration.size(), boundary.volume.size(),
        boundary.free_slip.size()));
  }
  for (const PeriodicAxis& periodic : periodic_) {
    for (std::size_t b = 0; b < n; ++b) {
      const double x = boundary.position[b][periodic.axis];
      if (x < periodic.min || x >= periodic.max) {
        throw Error(fmt::format(
            "sph_solver: wall particle {} lies at {} = {} m, outside the periodic span sph.periodic_{} = [{}, {}); "
            "the images of the wall particles stand for the walls beyond the seam. Fix: end the structures at "
            "the span (a floor covering [min, max) once)",
            b, periodic.axis == 0 ? 'x' : 'y', x, periodic.axis == 0 ? 'x' : 'y', periodic.min, periodic.max));
      }
    }
  }
  boundary_ = std::move(boundary);
}

// Puts every active particle back into the periodic span: x -= period past max, += below min.
void SphModel::wrap_positions() {
  for (const PeriodicAxis& periodic : periodic_) {
    const int a = periodic.axis;
    const double period = periodic.max - periodic.min;
    for (std::size_t i = 0; i < position_.size(); ++i) {
      if (!active_[i]) continue;
      double& x = position_[i][a];
      if (x >= periodic.min && x < periodic.max) continue;
      const double shift = -period * std::floor((x - periodic.min) / period);
      x += shift;
      if (x >= periodic.max) x = periodic.min;  // rounding of x + period just below min
      wrap_offset_[i][a] += shift;
    }
  }
}

// The image slots of this step: every active fluid particle and every wall particle within
// one support (plus a margin for the float positions) of a seam, shifted by the period
// towards the other side (both shifts at a corner of x and y). Serial: fixed order.
void SphModel::make_images() {
  f_image_source_.clear();
  b_image_source_.clear();
  if (periodic_.empty()) return;
  const double reach = kernel_.support() * (1.0 + 1e-3);
  const auto add_images = [&](const Vec3& p, std::uint32_t id, std::vector<Vec3>& out,
                              std::vector<std::uint32_t>& source) {
    Vec3 shifts[2] = {Vec3::Zero(), Vec3::Zero()};
    int count[2] = {1, 1};
    for (std::size_t k = 0; k < periodic_.size(); ++k) {
      const PeriodicAxis& periodic = periodic_[k];
      const double period = periodic.max - periodic.min;
      const double x = p[periodic.axis];
      if (x < periodic.min + reach) {
        shifts[k][periodic.axis] = period;
        count[k] = 2;
      } else if (x >= periodic.max - reach) {
        shifts[k][periodic.axis] = -period;
        count[k] = 2;
      }
    }
    for (int a = 0; a < count[0]; ++a) {
      for (int b = 0; b < count[1]; ++b) {
        if (a == 0 && b == 0) continue;
        out.push_back(p + static_cast<double>(a) * shifts[0] + static_cast<double>(b) * shifts[1]);
        source.push_back(id);
      }
    }
  };
  f_sort_position_.assign(position_.begin(), position_.end());
  for (std::size_t i = 0; i < position_.size(); ++i) {
    if (active_[i]) add_images(position_[i], static_cast<std::uint32_t>(i), f_sort_position_, f_image_source_);
  }
  b_sort_position_.assign(boundary_.position.begin(), boundary_.position.end());
  for (std::size_t b = 0; b < boundary_.size(); ++b) {
    add_images(boundary_.position[b], static_cast<std::uint32_t>(b), b_sort_position_, b_image_source_);
  }
}

Aabb SphModel::bounds() const {
  Aabb box;
  for (std::size_t i = 0; i < position_.size(); ++i) {
    if (active_[i]) box.extend(position_[i]);
  }
  return box;
}

void SphModel::build_grid() {
  const double cell = kernel_.support();
  const bool periodic = !periodic_.empty();
  const std::vector<Vec3>& f_position = periodic ? f_sort_position_ : position_;
  const std::vector<Vec3>& b_position = periodic ? b_sort_position_ : boundary_.position;
  const std::size_t particles = position_.size();
  Aabb box = bounds();
  for (const Vec3& p : b_position) box.extend(p);
  for (std::size_t k = particles; k < f_position.size(); ++k) box.extend(f_position[k]);
  if (box.empty()) box = Aabb{Vec3::Zero(), Vec3::Zero()};
  grid_origin_ = box.min.array() - 0.5 * cell;
  const Vec3 extent = box.max - grid_origin_;
  nx_ = static_cast<std::int64_t>(extent.x() / cell) + 2;
  ny_ = static_cast<std::int64_t>(extent.y() / cell) + 2;
  nz_ = static_cast<std::int64_t>(extent.z() / cell) + 2;
  if (nx_ * ny_ * nz_ > kMaxCells) {
    throw Error(
        fmt::format("sph_solver: the particles span {:.1f} x {:.1f} x {:.1f} m, {} cells of {:.3g} m; "
                    "a particle has probably run away. Fix: give sph.domain_min/domain_max so that particles "
                    "leaving the domain are taken out, or close the walls.",
                    extent.x(), extent.y(), extent.z(), nx_ * ny_ * nz_, cell));
  }
  const std::size_t cells = static_cast<std::size_t>(nx_ * ny_ * nz_);
  const double inverse_cell = 1.0 / cell;
  inverse_cell_ = inverse_cell;
  const auto cell_of = [&](const Vec3& p) {
    const auto ix = static_cast<std::int64_t>((p.x() - grid_origin_.x()) * inverse_cell);
    const auto iy = static_cast<std::int64_t>((p.y() - grid_origin_.y()) * inverse_cell);
    const auto iz = static_cast<std::int64_t>((p.z() - grid_origin_.z()) * inverse_cell);
    return static_cast<std::size_t>((iz * ny_ + iy) * nx_ + ix);
  };
  // Counting sort by cell, ids ascending inside a cell; the cell is computed twice
  // rather than stored (memory per particle).
  const auto sort = [&](const std::vector<Vec3>& position, auto is_active, std::vector<std::uint32_t>& start,
                        std::vector<std::uint32_t>& order) {
    start.assign(cells + 1, 0);
    std::size_t used = 0;
    for (std::size_t i = 0; i < position.size(); ++i) {
      if (!is_active(i)) continue;
      ++start[cell_of(position[i]) + 1];
      ++used;
    }
    for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
    order.resize(used);
    cell_next_.assign(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < position.size(); ++i) {
      if (!is_active(i)) continue;
      order[cell_next_[cell_of(position[i])]++] = static_cast<std::uint32_t>(i);
    }
  };
  // Then by x inside each cell (ties by id): every row of cells is x-sorted.
  const auto sort_by_x = [&](const std::vector<Vec3>& position, const std::vector<std::uint32_t>& start,
                             std::vector<std::uint32_t>& order, std::size_t images) {
    const auto cell_count = static_cast<std::int64_t>(cells);
#pragma omp parallel for schedule(static) if (order.size() - images > kParallelThreshold)
    for (std::int64_t c = 0; c < cell_count; ++c) {
      const auto first = order.begin() + start[static_cast<std::size_t>(c)];
      const auto last = order.begin() + start[static_cast<std::size_t>(c) + 1];
      if (last - first < 2) continue;
      std::sort(first, last, [&](std::uint32_t a, std::uint32_t b) {
        const double xa = position[a].x(), xb = position[b].x();
        return xa < xb || (xa == xb && a < b);
      });
    }
  };
  sort(
      f_position, [&](std::size_t i) { return i >= particles || active_[i] != 0; }, f_cell_start_, f_order_);
  sort_by_x(f_position, f_cell_start_, f_order_, f_image_source_.size());
  sort(
      b_position, [](std::size_t) { return true; }, b_cell_start_, b_order_);
  sort_by_x(b_position, b_cell_start_, b_order_, b_image_source_.size());
  if (periodic) {
    f_slot_of_.resize(particles);
    for (std::size_t s = 0; s < f_order_.size(); ++s) {
      if (f_order_[s] < particles) f_slot_of_[f_order_[s]] = static_cast<std::uint32_t>(s);
    }
    b_slot_of_.resize(boundary_.size());
    for (std::size_t s = 0; s < b_order_.size(); ++s) {
      if (b_order_[s] < boundary_.size()) b_slot_of_[b_order_[s]] = static_cast<std::uint32_t>(s);
    }
  }
}

void SphModel::gather() {
  const std::size_t n = f_order_.size();
  const std::size_t particles = position_.size(), walls = boundary_.size();
  const Vec3 origin = grid_origin_;
  resize_padded(fx_, n, kFarAway);
  resize_padded(fy_, n, kFarAway);
  resize_padded(fz_, n, kFarAway);
  for (auto* v : {&fvx_, &fvy_, &fvz_, &fpr_}) resize_padded(*v, n, 0.0f);
  resize_padded(fm_, n, 0.0);
  resize_padded(ffull_, n, 0.0f);
  resize_padded(frho_, n, 1.0f);
  resize_padded(fmat_, n, std::uint32_t{0});
  if (any_gradient_) resize_padded(feta_, n, 0.0f);
  if (has_stress_) fstress_.assign(6 * (n + kLanes), 0.0f);                 // component-major, stride n + kLanes
  if (any_artificial_stress_) fartificial_.assign(6 * (n + kLanes), 0.0f);  // like fstress_
  out_drho_.resize(n);
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (n - f_image_source_.size() > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto s = static_cast<std::size_t>(k);
    const std::uint32_t slot_id = f_order_[s];
    // An image slot: its own position, its source's state.
    const bool image = slot_id >= particles;
    const std::uint32_t i = fluid_source(slot_id);
    const Vec3& position = image ? f_sort_position_[slot_id] : position_[i];
    fx_[s] = static_cast<float>(position.x() - origin.x());
    fy_[s] = static_cast<float>(position.y() - origin.y());
    fz_[s] = static_cast<float>(position.z() - origin.z());
    fvx_[s] = static_cast<float>(velocity_[i].x());
    fvy_[s] = static_cast<float>(velocity_[i].y());
    fvz_[s] = static_cast<float>(velocity_[i].z());
    frho_[s] = static_cast<float>(density_[i]);
    // p(rho_n): set by the fill and by integrate().
    fpr_[s] = static_cast<float>(pressure_[i] / (density_[i] * density_[i]));
    fm_[s] = mass_[i];
    ffull_[s] = support_neighbours_.empty() || support_neighbours_[i] >= full_support_neighbours_ ||
                        materials_[material_[i]].rheology == Rheology::elastic_plastic
                    ? 1.0f
                    : 0.0f;
    fmat_[s] = material_[i];
    if (any_gradient_) feta_[s] = 0;
    if (has_stress_) {
      for (std::size_t q = 0; q < 6; ++q) fstress_[q * (n + kLanes) + s] = static_cast<float>(stress_[6 * i + q]);
    }
    if (any_artificial_stress_) {
      const double epsilon = materials_[material_[i]].artificial_stress;
      if (epsilon > 0) {
        double r[6];
        artificial_stress(&stress_[6 * i], pressure_[i], density_[i], epsilon, r);
        for (std::size_t q = 0; q < 6; ++q) fartificial_[q * (n + kLanes) + s] = static_cast<float>(r[q]);
      }
    }
  }
  const std::size_t nb = b_order_.size();
  resize_padded(bx_, nb, kFarAway);
  resize_padded(by_, nb, kFarAway);
  resize_padded(bz_, nb, kFarAway);
  for (auto* v : {&bwx_, &bwy_, &bwz_, &bvol_, &bpr_}) resize_padded(*v, nb, 0.0f);
  if (credits_wall_work()) resize_padded(bcredit_, nb, 0.0f);
  resize_padded(brho_, nb, 1.0f);
  if (has_stress_) bstress_.assign(6 * (nb + kLanes), 0.0f);  // component-major, stride nb + kLanes
  if (any_gradient_) {
    for (auto* v : {&bvx_, &bvy_, &bvz_}) resize_padded(*v, nb, 0.0f);
  }
  for (std::size_t s = 0; s < nb; ++s) {
    const std::uint32_t slot_id = b_order_[s];
    const bool image = slot_id >= walls;
    const std::uint32_t b = wall_source(slot_id);
    const Vec3& position = image ? b_sort_position_[slot_id] : boundary_.position[b];
    bx_[s] = static_cast<float>(position.x() - origin.x());
    by_[s] = static_cast<float>(position.y() - origin.y());
    bz_[s] = static_cast<float>(position.z() - origin.z());
    bwx_[s] = static_cast<float>(boundary_.velocity[b].x());
    bwy_[s] = static_cast<float>(boundary_.velocity[b].y());
    bwz_[s] = static_cast<float>(boundary_.velocity[b].z());
    bvol_[s] = static_cast<float>(boundary_.volume[b]);
  }
  if (!periodic_.empty()) {
    fm_wall_.assign(fm_.begin(), fm_.end());
    for (std::size_t s = 0; s < n; ++s) {
      if (f_order_[s] >= particles) fm_wall_[s] = 0.0;
    }
  }
}

// A wall image carries its source's state from boundary_state() and extrapolate_wall_stress().
void SphModel::copy_wall_image_state() {
  const std::size_t walls = boundary_.size();
  const std::size_t b_stride = b_order_.size() + kLanes;
  for (std::size_t s = 0; s < b_order_.size(); ++s) {
    const std::uint32_t slot_id = b_order_[s];
    if (slot_id < walls) continue;
    const std::uint32_t source = b_slot_of_[wall_source(slot_id)];
    bpr_[s] = bpr_[source];
    brho_[s] = brho_[source];
    bvol_[s] = bvol_[source];
    if (any_gradient_) {
      bvx_[s] = bvx_[source];
      bvy_[s] = bvy_[source];
      bvz_[s] = bvz_[source];
    }
    if (has_stress_) {
      for (std::size_t q = 0; q < 6; ++q) bstress_[q * b_stride + s] = bstress_[q * b_stride + source];
    }
  }
}

void SphModel::compute_boundary_state() {
  boundary_pressure_.assign(boundary_.size(), 0.0);
  if (has_stress_) bmoment_.resize(kWallMoments * b_order_.size());
  with_terms(kernel_.type, any_gradient_, has_stress_, false, false, DensityDiffusion::none,
             [&](auto terms) { boundary_state(terms); });
  if (has_stress_) {
    boundary_stress_.resize(6 * boundary_.size());  // every entry is written: b_order_ holds every wall particle
    extrapolate_wall_stress();
  }
  if (!b_image_source_.empty()) copy_wall_image_state();
}

// Elastic-plastic fluids: the wall carries the fluid's deviatoric stress extrapolated like
// the pressure, with its growth along the normal (docs/physics.md, "Walls"):
//   S_w = <S_f> + t n + n t,  t = d_n (rho_w (a_w - g) + grad p) less its part along n
// (the tangential momentum balance, less the divergence of S along the wall, which is left
// out: estimated from the particles' stresses it fed their noise back through the wall, and
// a column at rest no longer ran), <.> = sum_f (.) W_wf / sum_f W_wf, d_n = (x_w - <x_f>).n, and grad p the
// weighted least-squares slope of the fluid pressures around the wall particle (along a
// vertical wall it balances gravity: without it the wall took a false shear rho g d_n).
// All from the kernel moments boundary_state() summed.
void SphModel::extrapolate_wall_stress() {
  const std::size_t nb = b_order_.size();
  const std::size_t b_stride = nb + kLanes;
  const auto count = static_cast<std::int64_t>(nb);
#pragma omp parallel for schedule(static) if (nb - b_image_source_.size() > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto s = static_cast<std::size_t>(k);
    const std::uint32_t id = b_order_[s];
    if (id >= boundary_.size()) continue;  // an image: copy_wall_image_state()
    const double* m = &bmoment_[kWallMoments * s];
    Sym6 s_w;
    if (m[0] > 0) {
      const double inverse_w = 1.0 / m[0];
      s_w = {static_cast<float>(m[14] * inverse_w), static_cast<float>(m[15] * inverse_w),
             static_cast<float>(m[16] * inverse_w), static_cast<float>(m[17] * inverse_w),
             static_cast<float>(m[18] * inverse_w), static_cast<float>(m[19] * inverse_w)};
      const Vec3 mean_e = Vec3(m[2], m[3], m[4]) * inverse_w;  // <x_f - x_w>
      Mat3 covariance;
      covariance << m[5], m[8], m[10], m[8], m[6], m[9], m[10], m[9], m[7];
      covariance = covariance * inverse_w - mean_e * mean_e.transpose();
      const Vec3 pressure_covariance = Vec3(m[11], m[12], m[13]) * inverse_w - (m[1] * inverse_w) * mean_e;
      // Pseudo-inverse: no slope along a direction the neighbours do not span.
      const Eigen::SelfAdjointEigenSolver<Mat3> eigen(covariance);
      const double tolerance = 1e-3 * eigen.eigenvalues().maxCoeff();
      Mat3 inverse = Mat3::Zero();
      for (int e = 0; e < 3; ++e) {
        const double lambda = eigen.eigenvalues()(e);
        if (lambda > tolerance && lambda > 0) {
          const Vec3 v = eigen.eigenvectors().col(e);
          inverse += v * v.transpose() / lambda;
        }
      }
      const Vec3 grad_p = inverse * pressure_covariance;
      const Vec3& n = boundary_.normal[id];
      const Vec3 growth = double{brho_[s]} * (boundary_.acceleration[id] - gravity_) + grad_p;
      add_wall_shear(growth, n, -mean_e.dot(n), s_w);
    }
    const float components[6] = {s_w.xx, s_w.yy, s_w.zz, s_w.xy, s_w.yz, s_w.zx};
    for (std::size_t q = 0; q < 6; ++q) {
      bstress_[q * b_stride + s] = components[q];
      boundary_stress_[6 * id + q] = components[q];
    }
  }
}

template <class T>
void SphModel::boundary_state(T) {
  const std::size_t nb = b_order_.size(), walls = boundary_.size();
  const KernelF kernel(kernel_);
  const auto support2 = static_cast<float>(kernel_.support() * kernel_.support());
  const float* fx = fx_.data();
  const float* fy = fy_.data();
  const float* fz = fz_.data();
  const float* fvx = fvx_.data();
  const float* fvy = fvy_.data();
  const float* fvz = fvz_.data();
  const float* frho = frho_.data();
  const float* fpr = fpr_.data();
  const float* fstress = fstress_.data();
  const std::size_t stress_stride = f_order_.size() + kLanes;
  // With one fluid material the material of every wall particle is known.
  const bool credit_walls = credits_wall_work();
  const bool one_material = std::all_of(fmat_.begin(), fmat_.begin() + static_cast<std::ptrdiff_t>(f_order_.size()),
                                        [&](std::uint32_t m) { return m == fmat_[0]; });
  const auto count = static_cast<std::int64_t>(nb);
  const std::int64_t chunks = (count + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) if (nb - b_image_source_.size() > kParallelThreshold)
  for (std::int64_t chunk = 0; chunk < chunks; ++chunk) {
    const std::int64_t first = chunk * kChunk, last = std::min(count, first + kChunk);
    with_best_isa([=, this] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto s = static_cast<std::size_t>(k);
        const std::uint32_t id = b_order_[s];
        if (id >= walls) continue;  // an image: copy_wall_image_state()
        const Vec3 g_minus_a = gravity_ - boundary_.acceleration[id];
        const auto gax = static_cast<float>(g_minus_a.x()), gay = static_cast<float>(g_minus_a.y()),
                   gaz = static_cast<float>(g_minus_a.z());
        // Its part along the wall: the head that decides how far the wall particle stands
        // below the fluid's free surface (the wetted fraction below).
        const Vec3& normal = boundary_.normal[id];
        const Vec3 g_along = g_minus_a - g_minus_a.dot(normal) * normal;
        const auto gtx = static_cast<float>(g_along.x()), gty = static_cast<float>(g_along.y()),
                   gtz = static_cast<float>(g_along.z());
        alignas(64) float sum_w[kLanes] = {}, sum_pw[kLanes] = {}, sum_rho_r_g[kLanes] = {}, sum_wet[kLanes] = {};
        alignas(64) float svx[kLanes] = {}, svy[kLanes] = {}, svz[kLanes] = {};
        // Stress terms: sums of W e, W e e^T, W p e and W S_f, e = x_f - x_w (extrapolate_wall_stress).
        alignas(64) float moment[kWallMoments - 2][kLanes] = {};
        const float x = bx_[s], y = by_[s], z = bz_[s];
        const Vec3& position = boundary_.position[id];
        for_neighbour_blocks(position, f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = x - fx[j], ry = y - fy[j], rz = z - fz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float w = inside ? kernel_value<T::kernel>(r2, kernel) : 0.0f;
            const float rho_j = frho[j];
            sum_w[l] += w;
            const float p_j = fpr[j] * rho_j * rho_j;
            const float pw = p_j * w;
            sum_pw[l] += pw;
            sum_rho_r_g[l] += rho_j * w * (gax * rx + gay * ry + gaz * rz);
            sum_wet[l] += (std::max(p_j, 0.0f) + rho_j * (gtx * rx + gty * ry + gtz * rz)) * w;
            if constexpr (T::stress) {
              const float ex = -rx, ey = -ry, ez = -rz;
              moment[0][l] += w * ex;
              moment[1][l] += w * ey;
              moment[2][l] += w * ez;
              moment[3][l] += w * ex * ex;
              moment[4][l] += w * ey * ey;
              moment[5][l] += w * ez * ez;
              moment[6][l] += w * ex * ey;
              moment[7][l] += w * ey * ez;
              moment[8][l] += w * ez * ex;
              moment[9][l] += pw * ex;
              moment[10][l] += pw * ey;
              moment[11][l] += pw * ez;
              const Sym6 s_j = load_sym6(fstress, stress_stride, j);
              moment[12][l] += w * s_j.xx;
              moment[13][l] += w * s_j.yy;
              moment[14][l] += w * s_j.zz;
              moment[15][l] += w * s_j.xy;
              moment[16][l] += w * s_j.yz;
              moment[17][l] += w * s_j.zx;
            }
            if constexpr (T::viscous) {
              svx[l] += fvx[j] * w;
              svy[l] += fvy[j] * w;
              svz[l] += fvz[j] * w;
            }
          }
        });
        double total_w = 0, total_pw = 0, total_rho_r_g = 0, total_wet = 0, total_vx = 0, total_vy = 0, total_vz = 0;
        for (std::uint32_t l = 0; l < kLanes; ++l) {
          total_w += sum_w[l];
          total_pw += sum_pw[l];
          total_rho_r_g += sum_rho_r_g[l];
          total_wet += sum_wet[l];
          total_vx += svx[l];
          total_vy += svy[l];
          total_vz += svz[l];
        }
        if constexpr (T::stress) {
          double* out = &bmoment_[kWallMoments * s];
          out[0] = total_w;
          out[1] = total_pw;
          for (std::size_t q = 0; q + 2 < kWallMoments; ++q) {
            double total = 0;
            for (std::uint32_t l = 0; l < kLanes; ++l) total += moment[q][l];
            out[q + 2] = total;
          }
        }
        std::uint32_t material = fmat_.empty() ? 0 : fmat_[0];
        if (!one_material && total_w > 0) {
          // The material of the nearest fluid particle (largest W, the first in search order).
          double best_w = -1;
          for_neighbours(position.x(), position.y(), position.z(), f_cell_start_, [&](std::uint32_t j) {
            const double rx = x - fx[j], ry = y - fy[j], rz = z - fz[j];
            const double r2 = rx * rx + ry * ry + rz * rz;
            if (r2 >= support2) return;
            const double w = kernel_.value(std::sqrt(r2));
            if (w > best_w) {
              best_w = w;
              material = fmat_[j];
            }
          });
        }
        const EquationOfState& eos = materials_.empty() ? EquationOfState() : materials_[material].eos;
        double p = 0, rho = eos.rest_density;
        if (total_w > 0) {
          // Adami et al. 2012 eq. 27; negative wall pressure would glue the fluid to the wall.
          p = std::max(0.0, (total_pw + total_rho_r_g) / total_w);
          rho = eos.density(p);
        }
        bpr_[s] = static_cast<float>(p / (rho * rho));
        brho_[s] = static_cast<float>(rho);
        // The wall's compression goes back to the fluid whose pressures p_w averages
        // (wall_compression()); not where p_w is clamped to 0 (no work to balance), nor against
        // elastic-plastic fluid, whose wall stress has no energy-consistent counterpart: with
        // it a column at rest ran away within 0.04 s (docs/physics.md, "Energy").
        if (credit_walls) {
          const bool credited =
              p > 0 && (materials_.empty() || materials_[material].rheology != Rheology::elastic_plastic);
          bcredit_[s] = credited ? static_cast<float>(1.0 / total_w) : 0.0f;
        }
        // A wall particle stands for the fluid mirrored behind the wall: where that is air
        // (above the free surface beside a wall) it must not act. Its volume is scaled by the
        // wetted fraction of its cell (height cbrt(V)) along the wall: the extrapolated
        // pressure with only the along-wall head, rho0 |g_t| d, puts the free surface d above
        // it; 1 at d >= cbrt(V)/2, 0 at d <= -cbrt(V)/2. Fluid tension does not dry a wall
        // (max(p, 0)); walls across gravity (floors, ceilings) have no along-wall head and stay
        // whole. Without it the wall particles above a tank's free surface push the fluid
        // beside them down and inwards with its own p / rho^2: S4's start-up 2.6e-2 sqrt(gH).
        const double head = eos.rest_density * g_along.norm() * std::cbrt(double{bvol_[s]}) * total_w;
        if (total_w > 0 && head > 0) {
          bvol_[s] *= static_cast<float>(std::clamp(0.5 + total_wet / head, 0.0, 1.0));
        }
        if constexpr (T::viscous) {
          // No-slip wall velocity for the viscous terms: 2 v_w - v_extrapolated (Adami eq. 22).
          const bool any = total_w > 0;
          bvx_[s] = any ? static_cast<float>(2.0 * bwx_[s] - total_vx / total_w) : bwx_[s];
          bvy_[s] = any ? static_cast<float>(2.0 * bwy_[s] - total_vy / total_w) : bwy_[s];
          bvz_[s] = any ? static_cast<float>(2.0 * bwz_[s] - total_vz / total_w) : bwz_[s];
          if (any && !boundary_.free_slip.empty() && boundary_.free_slip[id] != 0) {
            // Free slip: the fluid's velocity with its normal part relative to the wall mirrored.
            const Vec3 fluid(total_vx / total_w, total_vy / total_w, total_vz / total_w);
            const Vec3 wall(bwx_[s], bwy_[s], bwz_[s]);
            const Vec3 mirrored = fluid - 2.0 * (fluid - wall).dot(normal) * normal;
            bvx_[s] = static_cast<float>(mirrored.x());
            bvy_[s] = static_cast<float>(mirrored.y());
            bvz_[s] = static_cast<float>(mirrored.z());
          }
        }
        boundary_pressure_[id] = p;
      }
    });
  }
}

void SphModel::compute_velocity_gradients(bool elastic_plastic_only) {
  const std::size_t n = f_order_.size();
  min_viscous_dt_ = std::numeric_limits<double>::infinity();
  if (!any_gradient_) {
    fgrad_.clear();
    return;
  }
  fgrad_.assign(9 * n, 0.0);
  // The eta L~^T term of the strain-rate viscosity: from the first pass of a step (integrate()'s
  // elastic-plastic pass reads only the gradients).
  const bool transpose = strain_rate_viscosity_ && !elastic_plastic_only;
  const std::size_t stride = n + kLanes;
  if (transpose) ftranspose_.assign(9 * stride, 0.0f);
  const std::size_t particles = position_.size();
  const double support2 = kernel_.support() * kernel_.support();
  const double h = kernel_.h;
  double min_viscous_dt = min_viscous_dt_;
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) \
    reduction(min                         \
              : min_viscous_dt) if (n - f_image_source_.size() > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const FluidMaterial& material = materials_[fmat_[i]];
    if (!material.needs_velocity_gradient() || f_order_[i] >= particles) continue;  // images: copied below
    if (elastic_plastic_only && material.rheology != Rheology::elastic_plastic) continue;
    const double x = fx_[i], y = fy_[i], z = fz_[i];
    double L[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    // M = -sum_j V_j F r r^T (xx yy zz xy yz zx): L of the linear field v_j - v_i = G (x_j - x_i) is G M.
    double M[6] = {0, 0, 0, 0, 0, 0};
    const auto add = [&](double rx, double ry, double rz, double r2, double dvx, double dvy, double dvz,
                         double volume) {
      const double f = kernel_.gradient_factor(std::sqrt(r2)) * volume;
      const double g[3] = {f * rx, f * ry, f * rz};
      const double dv[3] = {dvx, dvy, dvz};
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) L[3 * a + b] += dv[a] * g[b];
      }
      if (transpose) {
        M[0] -= g[0] * rx;
        M[1] -= g[1] * ry;
        M[2] -= g[2] * rz;
        M[3] -= g[0] * ry;
        M[4] -= g[1] * rz;
        M[5] -= g[2] * rx;
      }
    };
    const Vec3& position = position_[f_order_[i]];
    for_neighbours(position.x(), position.y(), position.z(), f_cell_start_, [&](std::uint32_t j) {
      if (j == i) return;
      const double rx = x - fx_[j], ry = y - fy_[j], rz = z - fz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 < support2) {
        add(rx, ry, rz, r2, double{fvx_[j]} - fvx_[i], double{fvy_[j]} - fvy_[i], double{fvz_[j]} - fvz_[i],
            double{fm_[j]} / frho_[j]);
      }
    });
    for_neighbours(position.x(), position.y(), position.z(), b_cell_start_, [&](std::uint32_t j) {
      const double rx = x - bx_[j], ry = y - by_[j], rz = z - bz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 < support2) {
        add(rx, ry, rz, r2, double{bvx_[j]} - fvx_[i], double{bvy_[j]} - fvy_[i], double{bvz_[j]} - fvz_[i], bvol_[j]);
      }
    });
    std::copy_n(L, 9, &fgrad_[9 * i]);
    // The strain-rate viscosity works with the kernel-gradient-corrected L~ = L M^-1, exact for
    // a linear velocity field whatever the neighbours: at a free surface L itself falls short by
    // the missing neighbours (M about 1/2 across it), which would leave the surface layers a
    // lower shear rate, so a higher viscosity (a crust), than the flow below them
    // (docs/physics.md, "Viscosity"). M's eigenvalues are held at kMinGradientMoment or more.
    // The stress rates of elastic-plastic fluids keep L (fgrad_, above).
    const double* rate_gradient = L;
    double corrected[9];
    if (transpose) {
      Mat3 moment;
      moment << M[0], M[3], M[5], M[3], M[1], M[4], M[5], M[4], M[2];
      Eigen::SelfAdjointEigenSolver<Mat3> eigen;
      eigen.computeDirect(moment, Eigen::EigenvaluesOnly);
      Mat3 inverse;
      if (eigen.eigenvalues().minCoeff() >= kMinGradientMoment) {
        inverse = moment.inverse();
      } else {
        eigen.computeDirect(moment);
        const Vec3 held = eigen.eigenvalues().cwiseMax(kMinGradientMoment);
        inverse = eigen.eigenvectors() * held.cwiseInverse().asDiagonal() * eigen.eigenvectors().transpose();
      }
      Mat3 grad;
      grad << L[0], L[1], L[2], L[3], L[4], L[5], L[6], L[7], L[8];
      const Mat3 product = grad * inverse;
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) corrected[3 * a + b] = product(a, b);
      }
      rate_gradient = corrected;
    }
    const double* G = rate_gradient;
    // Strain rate D = (L + L^T)/2; shear rate sqrt(2 D':D').
    double d[6] = {G[0], G[4], G[8], 0.5 * (G[1] + G[3]), 0.5 * (G[5] + G[7]), 0.5 * (G[6] + G[2])};
    const double trace = (d[0] + d[1] + d[2]) / 3.0;
    d[0] -= trace;
    d[1] -= trace;
    d[2] -= trace;
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]);
    const double shear_rate = std::sqrt(2.0 * dd);
    // Papanastasiou for bingham and herschel_bulkley (FluidMaterial::viscosity_at).
    const double eta = material.viscosity_at(shear_rate);
    feta_[i] = static_cast<float>(eta);
    if (eta > 0) min_viscous_dt = std::min(min_viscous_dt, double{frho_[i]} * h * h / (8.0 * eta));
    if (transpose) {
      // eta (L~^T - 2/3 tr(L~) I): with Morris's eta L the stress is 2 eta D', deviatoric (no bulk
      // viscosity on the weakly compressible fluid's density changes). A rigid rotation gives
      // L~^T = -L~, and this term cancels Morris's pair by pair.
      const double dilatation = (2.0 / 3.0) * (G[0] + G[4] + G[8]);
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
          const double t = eta * (G[3 * b + a] - (a == b ? dilatation : 0.0));
          ftranspose_[static_cast<std::size_t>(3 * a + b) * stride + i] = static_cast<float>(t);
        }
      }
    }
  }
  min_viscous_dt_ = min_viscous_dt;
  if (!f_image_source_.empty()) {
    for (std::size_t s = 0; s < n; ++s) {
      if (f_order_[s] < particles) continue;
      const std::size_t source = f_slot_of_[fluid_source(f_order_[s])];
      feta_[s] = feta_[source];
      if (transpose) {
        for (std::size_t q = 0; q < 9; ++q) ftranspose_[q * stride + s] = ftranspose_[q * stride + source];
      }
    }
  }
}

void SphModel::compute_fluid_forces() {
  with_terms<true, true>(kernel_.type, any_gradient_, has_stress_, any_artificial_stress_, strain_rate_viscosity_,
                         settings_.density_diffusion, [&](auto terms) { fluid_forces(terms); });
}

template <class T>
void SphModel::fluid_forces(T) {
  const std::size_t n = f_order_.size(), particles = position_.size();
  if (T::diffusion && support_neighbours_.size() != particles) support_neighbours_.assign(particles, 0);
  const float* ffull = ffull_.data();
  const KernelF kernel(kernel_);
  const auto support2 = static_cast<float>(kernel_.support() * kernel_.support());
  const double c = sound_speed_;
  const auto h = static_cast<float>(kernel_.h), eta2 = static_cast<float>(eta_squared_);
  const auto alpha_hc = static_cast<float>(settings_.artificial_viscosity * kernel_.h * c);
  const double diffusion_scale = 2.0 * settings_.density_diffusion_delta * kernel_.h * c;
  const double gx = gravity_.x(), gy = gravity_.y(), gz = gravity_.z();
  const auto gxf = static_cast<float>(gx), gyf = static_cast<float>(gy), gzf = static_cast<float>(gz);
  const auto inverse_c2 = static_cast<float>(1.0 / (c * c));
  const float* fx = fx_.data();
  const float* fy = fy_.data();
  const float* fz = fz_.data();
  const float* fvx = fvx_.data();
  const float* fvy = fvy_.data();
  const float* fvz = fvz_.data();
  const float* frho = frho_.data();
  const float* fpr = fpr_.data();
  const double* fm = fm_.data();
  const float* feta = feta_.data();
  const float* fstress = fstress_.data();
  const float* fartificial = fartificial_.data();
  const std::size_t stress_stride = f_order_.size() + kLanes;
  const float* ftr = ftranspose_.data();  // like fstress_, 9 components (only with T::transpose)
  const float* bstress = bstress_.data();
  const std::size_t bstress_stride = b_order_.size() + kLanes;
  // 1 / W(dx): f_ij = W(r_ij) / W(dx) in the artificial-stress term.
  const auto inverse_w_dx = static_cast<float>(1.0 / kernel_.value(settings_.particle_spacing));
  const float* bx = bx_.data();
  const float* by = by_.data();
  const float* bz = bz_.data();
  const float* bwx = bwx_.data();
  const float* bwy = bwy_.data();
  const float* bwz = bwz_.data();
  const float* bvx = bvx_.data();
  const float* bvy = bvy_.data();
  const float* bvz = bvz_.data();
  const float* bvol = bvol_.data();
  const float* bpr = bpr_.data();
  const float* brho = brho_.data();
  double max_mu = 0, max_acceleration = 0;
  std::int64_t neighbour_count = 0;
  const auto count = static_cast<std::int64_t>(n);
  const std::int64_t chunks = (count + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) reduction(max : max_mu, max_acceleration) reduction(+ : neighbour_count)  if (n - f_image_source_.size() > kParallelThreshold)
  for (std::int64_t chunk = 0; chunk < chunks; ++chunk) {
    const std::int64_t first = chunk * kChunk, last = std::min(count, first + kChunk);
    with_best_isa([=, this, &max_mu, &max_acceleration, &neighbour_count] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto i = static_cast<std::uint32_t>(k);
        const std::uint32_t id = f_order_[i];
        if (id >= particles) continue;  // an image: read-only
        const float x = fx[i], y = fy[i], z = fz[i];
        const float vx = fvx[i], vy = fvy[i], vz = fvz[i];
        const float rho_i = frho[i], pr_i = fpr[i], full_i = ffull[i];
        float eta_i = 0;
        if constexpr (T::viscous) eta_i = feta[i];
        float p_i = 0;
        if constexpr (T::hydrostatic) p_i = pr_i * rho_i * rho_i;
        Sym6 s_i, s_i_rho2;  // S_i and S_i / rho_i^2
        if constexpr (T::stress) {
          s_i = load_sym6(fstress, stress_stride, i);
          const float a = 1.0f / (rho_i * rho_i);
          s_i_rho2 = {s_i.xx * a, s_i.yy * a, s_i.zz * a, s_i.xy * a, s_i.yz * a, s_i.zx * a};
        }
        Sym6 r_i;  // R_i, artificial stress over rho_i^2
        if constexpr (T::artificial) r_i = load_sym6(fartificial, stress_stride, i);
        Mat9 t_i;  // eta_i L~_i^T
        if constexpr (T::transpose) t_i = load_mat9(ftr, stress_stride, i);
        alignas(64) double ax[kLanes] = {}, ay[kLanes] = {}, az[kLanes] = {};
        alignas(64) float diffuse[kLanes] = {}, mu_max[kLanes] = {};
        alignas(64) std::int32_t neighbours[kLanes] = {};
        const Vec3& position = position_[id];
        for_neighbour_blocks(position, f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
          const std::int32_t self = i >= j0 && i - j0 < kLanes ? static_cast<std::int32_t>(i - j0) : -1;
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = x - fx[j], ry = y - fy[j], rz = z - fz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (l != self) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float m_j = static_cast<float>(fm[j]), rho_j = frho[j];
            const float dvx = vx - fvx[j], dvy = vy - fvy[j], dvz = vz - fvz[j];
            const float vr = dvx * rx + dvy * ry + dvz * rz;
            const float inverse_r2 = 1.0f / (r2 + eta2);
            const float mu = h * vr * inverse_r2;
            mu_max[l] = std::max(mu_max[l], inside ? std::abs(mu) : 0.0f);
            neighbours[l] += inside ? 1 : 0;
            const float sf = pair_scalar(m_j, pr_i, fpr[j], vr, inverse_r2, rho_i, rho_j, alpha_hc) * f;
            float tx = sf * rx, ty = sf * ry, tz = sf * rz;
            if constexpr (T::viscous) {
              const float viscous = m_j * (eta_i + feta[j]) / (rho_i * rho_j) * f * r2 * inverse_r2;
              tx += viscous * dvx;
              ty += viscous * dvy;
              tz += viscous * dvz;
            }
            if constexpr (T::transpose) {
              // div(eta L^T): m_j / (rho_i rho_j) (t_i + t_j) . grad W, with Morris's r^2 / (r^2 + eta^2).
              const Mat9 t_j = load_mat9(ftr, stress_stride, j);
              const float scale = m_j / (rho_i * rho_j) * f * r2 * inverse_r2;
              add_sum_dot(t_i, t_j, scale, rx, ry, rz, tx, ty, tz);
            }
            if constexpr (T::stress) {
              const Sym6 s_j = load_sym6(fstress, stress_stride, j);
              const float aj = 1.0f / (rho_j * rho_j);
              const Sym6 sum{m_j * (s_i_rho2.xx + s_j.xx * aj), m_j * (s_i_rho2.yy + s_j.yy * aj),
                             m_j * (s_i_rho2.zz + s_j.zz * aj), m_j * (s_i_rho2.xy + s_j.xy * aj),
                             m_j * (s_i_rho2.yz + s_j.yz * aj), m_j * (s_i_rho2.zx + s_j.zx * aj)};
              add_stress_dot(sum, f, rx, ry, rz, tx, ty, tz);
            }
            if constexpr (T::artificial) {
              // m_j (R_i + R_j) f_ij^4 . grad W, f_ij = W(r) / W(dx) (Monaghan 2000, n = 4).
              const float w = inside ? kernel_value<T::kernel>(r2, kernel) * inverse_w_dx : 0.0f;
              const float w2 = w * w, scale = m_j * w2 * w2;
              const Sym6 r_j = load_sym6(fartificial, stress_stride, j);
              const Sym6 sum{scale * (r_i.xx + r_j.xx), scale * (r_i.yy + r_j.yy), scale * (r_i.zz + r_j.zz),
                             scale * (r_i.xy + r_j.xy), scale * (r_i.yz + r_j.yz), scale * (r_i.zx + r_j.zx)};
              add_stress_dot(sum, f, rx, ry, rz, tx, ty, tz);
            }
            ax[l] += tx;
            ay[l] += ty;
            az[l] += tz;
            if constexpr (T::diffusion) {
              float psi = rho_j - rho_i;
              if constexpr (T::hydrostatic) {
                psi = dynamic_density_difference(p_i, fpr[j] * rho_j * rho_j, rho_i, rho_j,
                                                 gxf * rx + gyf * ry + gzf * rz, inverse_c2);
              }
              diffuse[l] += psi * (-f * r2) * inverse_r2 * m_j / rho_j * (full_i * ffull[j]);
            }
          }
        });
        std::int64_t fluid_neighbours = 0;  // the diffusion's own support (walls come next)
        for (std::uint32_t l = 0; l < kLanes; ++l) fluid_neighbours += neighbours[l];
        for_neighbour_blocks(position, b_cell_start_, bx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = x - bx[j], ry = y - by[j], rz = z - bz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float rho_b = brho[j], m_b = rho_b * bvol[j];
            const float vr = (vx - bwx[j]) * rx + (vy - bwy[j]) * ry + (vz - bwz[j]) * rz;
            const float inverse_r2 = 1.0f / (r2 + eta2);
            const float mu = h * vr * inverse_r2;
            mu_max[l] = std::max(mu_max[l], inside ? std::abs(mu) : 0.0f);
            neighbours[l] += inside ? 1 : 0;
            float ux = 0, uy = 0, uz = 0;
            if constexpr (T::viscous) {
              ux = vx - bvx[j];
              uy = vy - bvy[j];
              uz = vz - bvz[j];
            }
            Sym6 s_b;
            if constexpr (T::stress) s_b = load_sym6(bstress, bstress_stride, j);
            float tx, ty, tz;
            wall_pair<T>(m_b, rho_b, bpr[j], rho_i, pr_i, eta_i, s_i, s_b, t_i, f, rx, ry, rz, r2, vr, inverse_r2, ux,
                         uy, uz, alpha_hc, tx, ty, tz);
            ax[l] += tx;
            ay[l] += ty;
            az[l] += tz;
          }
        });
        double sum_x = 0, sum_y = 0, sum_z = 0, sum_diffuse = 0;
        float lane_mu = 0;
        std::int64_t lane_neighbours = 0;
        for (std::uint32_t l = 0; l < kLanes; ++l) {
          sum_x += ax[l];
          sum_y += ay[l];
          sum_z += az[l];
          sum_diffuse += diffuse[l];
          lane_mu = std::max(lane_mu, mu_max[l]);
          lane_neighbours += neighbours[l];
        }
        const Vec3 a(sum_x + gx, sum_y + gy, sum_z + gz);
        acceleration_[id] = a;
        out_drho_[i] = T::diffusion ? diffusion_scale * sum_diffuse : 0.0;
        max_mu = std::max(max_mu, double{lane_mu});
        max_acceleration = std::max(max_acceleration, a.norm());
        neighbour_count += lane_neighbours;
        if constexpr (T::diffusion) support_neighbours_[id] = static_cast<std::int32_t>(fluid_neighbours);
      }
    });
  }
  max_mu_ = max_mu;
  max_acceleration_ = max_acceleration;
  const std::size_t real = n - f_image_source_.size();
  mean_neighbours_ = real > 0 ? static_cast<double>(neighbour_count) / static_cast<double>(real) : 0.0;
}

void SphModel::compute_boundary_forces() {
  const std::size_t walls = boundary_.size();
  boundary_force_.assign(walls + b_image_source_.size(), Vec3::Zero());
  with_terms<false, true>(kernel_.type, any_gradient_, has_stress_, false, strain_rate_viscosity_,
                          DensityDiffusion::none, [&](auto terms) { boundary_forces(terms); });
  // The fluid's force on a wall image is its source's (action = reaction), in image order.
  for (std::size_t k = 0; k < b_image_source_.size(); ++k)
    boundary_force_[b_image_source_[k]] += boundary_force_[walls + k];
  boundary_force_.resize(walls);
}

// The same pair terms as in fluid_forces, from the wall particle's side: the force on
// the wall particle is minus the sum of the forces it puts on the fluid.
template <class T>
void SphModel::boundary_forces(T) {
  const std::size_t nb = b_order_.size();
  const KernelF kernel(kernel_);
  const auto support2 = static_cast<float>(kernel_.support() * kernel_.support());
  const auto eta2 = static_cast<float>(eta_squared_);
  const auto alpha_hc = static_cast<float>(settings_.artificial_viscosity * kernel_.h * sound_speed_);
  const float* fx = fx_.data();
  const float* fy = fy_.data();
  const float* fz = fz_.data();
  const float* fvx = fvx_.data();
  const float* fvy = fvy_.data();
  const float* fvz = fvz_.data();
  const float* frho = frho_.data();
  const float* fpr = fpr_.data();
  const float* feta = feta_.data();
  const float* fstress = fstress_.data();
  const std::size_t stress_stride = f_order_.size() + kLanes;
  const float* ftr = ftranspose_.data();
  const float* bstress = bstress_.data();
  const std::size_t bstress_stride = b_order_.size() + kLanes;
  // With images, the real fluid only: a wall (or wall image) sees each fluid particle once.
  const double* fm = periodic_.empty() ? fm_.data() : fm_wall_.data();
  const std::vector<Vec3>& b_position = periodic_.empty() ? boundary_.position : b_sort_position_;
  const auto count = static_cast<std::int64_t>(nb);
  const std::int64_t chunks = (count + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) if (nb - b_image_source_.size() > kParallelThreshold)
  for (std::int64_t chunk = 0; chunk < chunks; ++chunk) {
    const std::int64_t first = chunk * kChunk, last = std::min(count, first + kChunk);
    with_best_isa([=, this, &b_position] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto b = static_cast<std::size_t>(k);
        const std::uint32_t id = b_order_[b];
        const float x = bx_[b], y = by_[b], z = bz_[b];
        const float rho_b = brho_[b], m_b = rho_b * bvol_[b], pr_b = bpr_[b];
        Sym6 s_b;
        if constexpr (T::stress) s_b = load_sym6(bstress, bstress_stride, b);
        const float wx = bwx_[b], wy = bwy_[b], wz = bwz_[b];
        float vx_b = 0, vy_b = 0, vz_b = 0;
        if constexpr (T::viscous) {
          vx_b = bvx_[b];
          vy_b = bvy_[b];
          vz_b = bvz_[b];
        }
        alignas(64) double fbx[kLanes] = {}, fby[kLanes] = {}, fbz[kLanes] = {};
        const Vec3& position = b_position[id];
        for_neighbour_blocks(position, f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = fx[j] - x, ry = fy[j] - y, rz = fz[j] - z;  // r_ib, i the fluid particle
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float vx = fvx[j], vy = fvy[j], vz = fvz[j];
            const float vr = (vx - wx) * rx + (vy - wy) * ry + (vz - wz) * rz;
            const float inverse_r2 = 1.0f / (r2 + eta2);
            float ux = 0, uy = 0, uz = 0, eta_i = 0;
            Sym6 s_i;
            if constexpr (T::viscous) {
              ux = vx - vx_b;
              uy = vy - vy_b;
              uz = vz - vz_b;
              eta_i = feta[j];
            }
            if constexpr (T::stress) s_i = load_sym6(fstress, stress_stride, j);
            Mat9 t_i;
            if constexpr (T::transpose) t_i = load_mat9(ftr, stress_stride, j);
            float tx, ty, tz;
            wall_pair<T>(m_b, rho_b, pr_b, frho[j], fpr[j], eta_i, s_i, s_b, t_i, f, rx, ry, rz, r2, vr, inverse_r2, ux,
                         uy, uz, alpha_hc, tx, ty, tz);
            const double m_i = inside ? fm[j] : 0.0;
            fbx[l] -= m_i * tx;
            fby[l] -= m_i * ty;
            fbz[l] -= m_i * tz;
          }
        });
        double sum_x = 0, sum_y = 0, sum_z = 0;
        for (std::uint32_t l = 0; l < kLanes; ++l) {
          sum_x += fbx[l];
          sum_y += fby[l];
          sum_z += fbz[l];
        }
        boundary_force_[id] = Vec3(sum_x, sum_y, sum_z);
      }
    });
  }
}

// Continuity at x_n with the new velocities v_{n+1/2} (the density is a position-like
// variable of the leapfrog: with v_{n-1/2} the acoustic modes would grow).
void SphModel::compute_velocity_divergence(double dt) {
  const std::size_t n = f_order_.size();
  for (std::size_t s = 0; s < n; ++s) {
    const Vec3& v = velocity_[fluid_source(f_order_[s])];
    fvx_[s] = static_cast<float>(v.x());
    fvy_[s] = static_cast<float>(v.y());
    fvz_[s] = static_cast<float>(v.z());
  }
  with_terms(kernel_.type, false, false, false, false, DensityDiffusion::none, [&](auto terms) {
    if (credits_wall_work()) wall_compression(terms);  // read by velocity_divergence()
    velocity_divergence(terms, dt);
  });
}

template <class T>
void SphModel::velocity_divergence(T, double dt) {
  const std::size_t n = f_order_.size(), particles = position_.size();
  const KernelF kernel(kernel_);
  const auto support2 = static_cast<float>(kernel_.support() * kernel_.support());
  const float* fx = fx_.data();
  const float* fy = fy_.data();
  const float* fz = fz_.data();
  const float* fvx = fvx_.data();
  const float* fvy = fvy_.data();
  const float* fvz = fvz_.data();
  const double* fm = fm_.data();
  const float* bx = bx_.data();
  const float* by = by_.data();
  const float* bz = bz_.data();
  const float* bwx = bwx_.data();
  const float* bwy = bwy_.data();
  const float* bwz = bwz_.data();
  const float* bvol = bvol_.data();
  const float* brho = brho_.data();
  const bool credit_walls = credits_wall_work();
  const bool bounded = !wall_work_held_.empty();  // wall_work = "bounded" with boundary particles
  const float* bcredit = bcredit_.data();         // empty without credit_walls
  const auto count = static_cast<std::int64_t>(n);
  const std::int64_t chunks = (count + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) if (n - f_image_source_.size() > kParallelThreshold)
  for (std::int64_t chunk = 0; chunk < chunks; ++chunk) {
    const std::int64_t first = chunk * kChunk, last = std::min(count, first + kChunk);
    with_best_isa([=, this] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto i = static_cast<std::uint32_t>(k);
        if (f_order_[i] >= particles) continue;  // an image: read-only
        alignas(64) float credit[kLanes] = {};
        const float x = fx[i], y = fy[i], z = fz[i];
        const float vx = fvx[i], vy = fvy[i], vz = fvz[i];
        alignas(64) float drho[kLanes] = {};
        const Vec3& position = position_[f_order_[i]];
        for_neighbour_blocks(position, f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
          const std::int32_t self = i >= j0 && i - j0 < kLanes ? static_cast<std::int32_t>(i - j0) : -1;
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = x - fx[j], ry = y - fy[j], rz = z - fz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (l != self) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float vr = (vx - fvx[j]) * rx + (vy - fvy[j]) * ry + (vz - fvz[j]) * rz;
            drho[l] += static_cast<float>(fm[j]) * vr * f;
          }
        });
        for_neighbour_blocks(position, b_cell_start_, bx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = x - bx[j], ry = y - by[j], rz = z - bz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float vr = (vx - bwx[j]) * rx + (vy - bwy[j]) * ry + (vz - bwz[j]) * rz;
            drho[l] += brho[j] * bvol[j] * vr * f;
            if (credit_walls) credit[l] += (inside ? kernel_value<T::kernel>(r2, kernel) : 0.0f) * bcredit[j];
          }
        });
        double sum = 0, credited = 0;
        for (std::uint32_t l = 0; l < kLanes; ++l) {
          sum += drho[l];
          credited += credit[l];
        }
        if (bounded && credited != 0.0) {
          const double pressure = double{fpr_[i]} * frho_[i] * frho_[i];
          credited *= bounded_credit(pressure * credited * dt, wall_work_held_[f_order_[i]]);
        }
        out_drho_[i] += sum + double{frho_[i]} * frho_[i] / fm[i] * credited;
      }
    });
  }
}

// Energy-consistent walls (docs/physics.md, "Energy"). The wall term of the momentum,
// -m_b (p_i / rho_i^2 + p_w / rho_w^2) grad W, does work at the rate
//   -sum_b (m_b / rho_b^2) p_w drho_b/dt,  drho_b/dt = sum_f m_f (v_f - v_b).grad_f W_fb,
// the wall particle's own continuity rate. Its p_i part is what the fluid's continuity stores
// as compression; the p_w part nothing stored, and a column released beside walls gained
// 5e-4 of its energy. p_w = sum_f p_f W_bf / sum_f W_bf + (hydrostatic part), so crediting
//   drho_f/dt += rho_f^2 / m_f sum_b (m_b / rho_b^2) drho_b/dt W_bf / sum W_b
// to the fluid stores exactly the average's work: the transpose of the pressure average.
// Per wall slot this turns bcredit_ from 1 / sum W_b (boundary_state()) into
// (m_b / rho_b^2) drho_b/dt / sum W_b = V_b / rho_b drho_b/dt / sum W_b.
// The hydrostatic part stays unbalanced (the impact and tank runs never rose above E0 with it).
// wall_work = "stored" applies the whole credit; "bounded" lets bounded_credit() decide per
// fluid particle in velocity_divergence().
template <class T>
void SphModel::wall_compression(T) {
  const std::size_t nb = b_order_.size(), walls = boundary_.size();
  const KernelF kernel(kernel_);
  const auto support2 = static_cast<float>(kernel_.support() * kernel_.support());
  const float* fx = fx_.data();
  const float* fy = fy_.data();
  const float* fz = fz_.data();
  const float* fvx = fvx_.data();
  const float* fvy = fvy_.data();
  const float* fvz = fvz_.data();
  const double* fm = fm_.data();
  const auto count = static_cast<std::int64_t>(nb);
  const std::int64_t chunks = (count + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) if (nb - b_image_source_.size() > kParallelThreshold)
  for (std::int64_t chunk = 0; chunk < chunks; ++chunk) {
    const std::int64_t first = chunk * kChunk, last = std::min(count, first + kChunk);
    with_best_isa([=, this] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto s = static_cast<std::size_t>(k);
        const std::uint32_t id = b_order_[s];
        if (id >= walls) continue;  // an image: copied below
        if (bcredit_[s] == 0.0f) continue;
        const float x = bx_[s], y = by_[s], z = bz_[s];
        const float wx = bwx_[s], wy = bwy_[s], wz = bwz_[s];
        alignas(64) float rate[kLanes] = {};
        for_neighbour_blocks(boundary_.position[id], f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = fx[j] - x, ry = fy[j] - y, rz = fz[j] - z;
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float vr = (fvx[j] - wx) * rx + (fvy[j] - wy) * ry + (fvz[j] - wz) * rz;
            rate[l] += static_cast<float>(fm[j]) * vr * f;
          }
        });
        double total = 0;
        for (std::uint32_t l = 0; l < kLanes; ++l) total += rate[l];
        bcredit_[s] = static_cast<float>(double{bvol_[s]} / brho_[s] * total * bcredit_[s]);
      }
    });
  }
  for (std::size_t s = 0; s < nb; ++s) {
    if (b_order_[s] >= walls) bcredit_[s] = bcredit_[b_slot_of_[wall_source(b_order_[s])]];
  }
}

// Jaumann rate dS/dt = 2 G D' + W S - S W, W = (L - L^T)/2, of the elastic-plastic particles.
void SphModel::stress_rates() {
  const std::size_t n = f_order_.size();
  std::fill(stress_rate_.begin(), stress_rate_.end(), 0.0);
  for (std::size_t s = 0; s < n; ++s) {
    const std::uint32_t i = f_order_[s];
    if (i >= position_.size()) continue;  // an image
    double* rate = &stress_rate_[6 * i];
    const FluidMaterial& material = materials_[material_[i]];
    if (material.rheology != Rheology::elastic_plastic) continue;
    const double* L = &fgrad_[9 * s];
    Mat3 grad;
    grad << L[0], L[1], L[2], L[3], L[4], L[5], L[6], L[7], L[8];
    const Mat3 d = 0.5 * (grad + grad.transpose());
    const Mat3 w = 0.5 * (grad - grad.transpose());
    const Mat3 stress = unpack_sym6(&stress_[6 * i]);
    const Mat3 deviatoric = d - (d.trace() / 3.0) * Mat3::Identity();
    pack_sym6(2.0 * material.shear_modulus * deviatoric + w * stress - stress * w, rate);
  }
}

void SphModel::compute_internal_forces(double dt_previous) {
  (void)dt_previous;
  if (!periodic_.empty()) {
    wrap_positions();  // positions() is writable
    make_images();
  }
  build_grid();
  gather();
  compute_boundary_state();
  compute_velocity_gradients(false);
  compute_fluid_forces();
  compute_boundary_forces();
  const std::size_t n = f_order_.size();
  const double h = kernel_.h;
  double dt_cv = n > 0 ? h / (sound_speed_ + max_mu_) : h / sound_speed_;
  dt_cv = std::min(dt_cv, elastic_wave_dt_);
  const double dt_force =
      max_acceleration_ > 0 ? std::sqrt(h / max_acceleration_) : std::numeric_limits<double>::infinity();
  stable_dt_ = settings_.cfl * std::min({dt_cv, dt_force, min_viscous_dt_});
  forces_ready_ = true;
}

void SphModel::add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force) {
  if (force.size() != 3 * index.size()) {
    throw ModelInputError(
        fmt::format("sph_solver: {} particle indices but {} force values; 3 values per particle expected", index.size(),
                    force.size()));
  }
  if (external_force_.empty() && !index.empty()) external_force_.assign(size(), Vec3::Zero());
  for (std::size_t k = 0; k < index.size(); ++k) {
    const std::uint32_t i = index[k];
    if (i >= size()) {
      throw ModelInputError(fmt::format("sph_solver: force for particle {} but there are only {}", i, size()));
    }
    external_force_[i] += Vec3(force[3 * k], force[3 * k + 1], force[3 * k + 2]);
  }
}

void SphModel::integrate(double dt_previous, double dt) {
  assert(forces_ready_ && "compute_internal_forces() must run before integrate()");
  assert(dt > 0 && dt_previous >= 0);
  const bool first_step = dt_previous == 0;
  const double dt_update = first_step ? 0.5 * dt : 0.5 * (dt_previous + dt);
  const std::size_t n = size();
  const bool parallel = n > kParallelThreshold;
  const bool external = !external_force_.empty();
  const bool periodic = !periodic_.empty();
  update_settle_factors(dt);
  // Energies at the step, summed per block of kEnergyBlock particles, blocks in order.
  const std::size_t blocks = (n + kEnergyBlock - 1) / kEnergyBlock;
  energy_block_.assign(kEnergyTerms * blocks, 0.0);
  const auto block_count = static_cast<std::int64_t>(blocks);
#pragma omp parallel for schedule(static) if (parallel)
  for (std::int64_t block = 0; block < block_count; ++block) {
    const std::size_t first = static_cast<std::size_t>(block) * kEnergyBlock;
    const std::size_t last = std::min(n, first + kEnergyBlock);
    double kinetic = 0, potential = 0, elastic = 0, held = 0;
    for (std::size_t i = first; i < last; ++i) {
      if (!active_[i]) {
        if (external) external_force_[i].setZero();
        continue;
      }
      const FluidMaterial& material = materials_[material_[i]];
      potential += -mass_[i] * gravity_.dot(periodic ? Vec3(position_[i] - wrap_offset_[i]) : position_[i]);
      elastic += mass_[i] * material.eos.specific_energy(density_[i]);
      if (!wall_work_held_.empty()) held += wall_work_held_[i];
      Vec3 a = acceleration_[i];
      if (external) {
        a += external_force_[i] / mass_[i];
        external_force_[i].setZero();
      }
      Vec3 velocity = velocity_[i] + dt_update * a;
      if (const double settle = settle_factor_[body_[i]]; settle != 1.0) velocity *= settle;
      kinetic += first_step ? 0.5 * mass_[i] * velocity_[i].squaredNorm() : 0.5 * mass_[i] * velocity_[i].dot(velocity);
      velocity_[i] = velocity;
    }
    double* sums = &energy_block_[kEnergyTerms * static_cast<std::size_t>(block)];
    sums[0] = kinetic;
    sums[1] = potential;
    sums[2] = elastic;
    sums[3] = held;
  }
  compute_velocity_divergence(dt);
  if (has_stress_) {
    // The deviatoric stress is position-like too: its rate from L(x_n, v_{n+1/2}) (the fluid's
    // new velocities; the walls' no-slip velocities of compute_boundary_state()). With
    // L(v_{n-1/2}) the elastic modes grew: a column at rest reached 1.3 sqrt(gH) by
    // t = 4 sqrt(H/g) (docs/notes/sph.md, "Elastic-plastic stress update"). Only their gradients:
    // the others' were read by this step's forces and are not needed again.
    compute_velocity_gradients(true);
    stress_rates();
  }
  const auto sorted = static_cast<std::int64_t>(f_order_.size());
#pragma omp parallel for schedule(static) if (parallel)
  for (std::int64_t k = 0; k < sorted; ++k) {
    const auto s = static_cast<std::size_t>(k);
    if (f_order_[s] < n) density_[f_order_[s]] += dt * out_drho_[s];
  }
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (parallel)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (!active_[i]) continue;
    const FluidMaterial& material = materials_[material_[i]];
    position_[i] += dt * velocity_[i];
    if (has_stress_ && material.rheology == Rheology::elastic_plastic) {
      double* s = &stress_[6 * i];
      for (int q = 0; q < 6; ++q) s[q] += dt * stress_rate_[6 * i + static_cast<std::size_t>(q)];
      // Radial return onto the von Mises surface sqrt(3/2 S:S) = sigma_y.
      const double ss = s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + 2.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
      const double equivalent = std::sqrt(1.5 * ss);
      if (equivalent > material.yield_stress) {
        const double scale = material.yield_stress / equivalent;
        for (int q = 0; q < 6; ++q) s[q] *= scale;
      }
    }
    pressure_[i] = material.eos.pressure(density_[i]);
  }
  if (periodic) wrap_positions();
  Energies energies;
  for (std::size_t block = 0; block < blocks; ++block) {
    const double* sums = &energy_block_[kEnergyTerms * block];
    energies.kinetic += sums[0];
    energies.potential += sums[1];
    energies.elastic += sums[2];
    energies.wall_held += sums[3];
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!active_[i]) continue;
    if (!std::isfinite(position_[i].x() + position_[i].y() + position_[i].z() + density_[i])) {
      throw Error(
          fmt::format("sph_solver: particle {} is no longer finite (position {} {} {}, density {}) after a "
                      "step of {:.3e} s. Fix: lower [solvers.sph] beta or sph.cfl.",
                      i, position_[i].x(), position_[i].y(), position_[i].z(), density_[i], dt));
    }
    if (settings_.domain && !settings_.domain->contains(position_[i])) {
      active_[i] = 0;
      velocity_[i].setZero();
      ++lost_;
    }
  }
  energies_ = energies;
  time_ += dt;
  forces_ready_ = false;
}

}  // namespace sabo::sph
