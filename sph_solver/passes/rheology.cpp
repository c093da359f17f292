// Stress and rheology: the effective viscosity of each law, the velocity gradient L (and the
// kernel-gradient-corrected L~ of the strain-rate viscosity) with the viscosity and viscous
// step it gives, and the Jaumann stress rate of the elastic-plastic fluids.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/passes/pair_terms.hpp"
#include "sph_solver/passes/particle_for.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// The kernel-gradient correction of the strain-rate viscosity (compute_velocity_gradients):
// the eigenvalues of the moment matrix M (1 in the bulk, about 1/2 across a free surface) are
// held at this or more, so that a particle with almost no neighbours along some direction
// (a splash) is amplified at most 1 / kMinGradientMoment times. A cube's corner particle has 0.19
// (Wendland C2, h = 1.5 dx) and is corrected in full.
constexpr double kMinGradientMoment = 0.1;

// What compute_velocity_gradients() reduces over the particles: the smallest viscous step
// rho h^2 / (8 eta), s. A min: the same on any number of threads.
struct ViscousStep {
  double dt = std::numeric_limits<double>::infinity();
  void join(const ViscousStep& other) { dt = std::min(dt, other.dt); }
};

// One neighbour slot in lane l of the velocity gradient's sums (compute_velocity_gradients): its kernel gradient
// times its volume, g (zero outside the support: `inside` false), the velocity difference dv, and the sums
// L += dv g^T (rows 0-8 of `lane`, row-major) and, with Moment, M -= g r^T (rows 9-14: xx yy zz xy yz zx).
template <KernelKind Kind, bool Moment>
[[gnu::always_inline]] inline void add_gradient_lane(float (&lane)[15][kLanes], std::int32_t l, bool inside, float rx,
                                                     float ry, float rz, float r2, float volume, float dvx, float dvy,
                                                     float dvz, const KernelF& kernel) {
  const float f = inside ? gradient_factor<Kind>(r2, kernel) * volume : 0.0f;
  const float gx = f * rx, gy = f * ry, gz = f * rz;
  lane[0][l] += dvx * gx, lane[1][l] += dvx * gy, lane[2][l] += dvx * gz;
  lane[3][l] += dvy * gx, lane[4][l] += dvy * gy, lane[5][l] += dvy * gz;
  lane[6][l] += dvz * gx, lane[7][l] += dvz * gy, lane[8][l] += dvz * gz;
  if constexpr (Moment) {
    lane[9][l] -= gx * rx, lane[10][l] -= gy * ry, lane[11][l] -= gz * rz;
    lane[12][l] -= gx * ry, lane[13][l] -= gy * rz, lane[14][l] -= gz * rx;
  }
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
  const auto support2 = static_cast<float>(kernel_.support() * kernel_.support());
  const double h = kernel_.h;
  const bool parallel = in_parallel(n - f_image_source_.size());
  const float *fx = fx_.data(), *fy = fy_.data(), *fz = fz_.data();
  const float *fvx = fvx_.data(), *fvy = fvy_.data(), *fvz = fvz_.data(), *frho = frho_.data();
  const double* fm = fm_.data();
  const float *bx = bx_.data(), *by = by_.data(), *bz = bz_.data(), *bvol = bvol_.data();
  const float *bvx = bvx_.data(), *bvy = bvy_.data(), *bvz = bvz_.data();
  const KernelF kernel(kernel_);
  // The pass for one kernel, with the moment matrix only for the correction (transpose): the lanes compute
  // only what is used.
  const auto reduce = [=, this]<KernelKind Kind, bool Moment>() {
    const auto body = [=, this](std::int64_t first, std::int64_t last, ViscousStep& step) {
      for (std::int64_t k = first; k < last; ++k) {
        const auto i = static_cast<std::size_t>(k);
        const FluidMaterial& material = materials_[fmat_[i]];
        // Images: copied below; halo slots: exchange_viscosities().
        if (!material.needs_velocity_gradient() || !computes_fluid_slot(i)) continue;
        if (elastic_plastic_only && material.rheology != Rheology::elastic_plastic) continue;
        // Per lane of the neighbour blocks: L (9, row-major) and, for the correction, M = -sum_j V_j F r r^T
        // (xx yy zz xy yz zx): L of the linear field v_j - v_i = G (x_j - x_i) is G M. Summed over the lanes
        // in lane order at the end: the same bits on any thread count.
        alignas(64) float lane[15][kLanes] = {};
        const float xf = fx[i], yf = fy[i], zf = fz[i], vxf = fvx[i], vyf = fvy[i], vzf = fvz[i];
        const Vec3& position = position_[f_order_[i]];
        for_neighbour_blocks(position, f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
          const std::int32_t self = i >= j0 && i - j0 < kLanes ? static_cast<std::int32_t>(i - j0) : -1;
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = xf - fx[j], ry = yf - fy[j], rz = zf - fz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (l != self) & (r2 < support2);
            add_gradient_lane<Kind, Moment>(lane, l, inside, rx, ry, rz, r2, static_cast<float>(fm[j]) / frho[j],
                                            fvx[j] - vxf, fvy[j] - vyf, fvz[j] - vzf, kernel);
          }
        });
        for_neighbour_blocks(position, b_cell_start_, bx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = xf - bx[j], ry = yf - by[j], rz = zf - bz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            add_gradient_lane<Kind, Moment>(lane, l, inside, rx, ry, rz, r2, bvol[j], bvx[j] - vxf, bvy[j] - vyf,
                                            bvz[j] - vzf, kernel);
          }
        });
        double L[9], M[6] = {};
        for (int q = 0; q < (Moment ? 15 : 9); ++q) {
          double sum = 0;
          for (std::uint32_t l = 0; l < kLanes; ++l) sum += lane[q][l];
          (q < 9 ? L[q] : M[q - 9]) = sum;
        }
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
        if (eta > 0) step.dt = std::min(step.dt, double{frho_[i]} * h * h / (8.0 * eta));
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
    };
    return particle_reduce(n, parallel, ViscousStep{}, body).dt;
  };
  const bool wendland = kernel_.type == KernelKind::wendland_c2;
  if (transpose) {
    min_viscous_dt_ = wendland ? reduce.template operator()<KernelKind::wendland_c2, true>()
                               : reduce.template operator()<KernelKind::cubic_spline, true>();
  } else {
    min_viscous_dt_ = wendland ? reduce.template operator()<KernelKind::wendland_c2, false>()
                               : reduce.template operator()<KernelKind::cubic_spline, false>();
  }
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

// Jaumann rate dS/dt = 2 G D' + W S - S W, W = (L - L^T)/2, of the elastic-plastic particles.
void SphModel::stress_rates() {
  const std::size_t n = f_order_.size();
  std::fill(stress_rate_.begin(), stress_rate_.end(), 0.0);
  for (std::size_t s = 0; s < n; ++s) {
    const std::uint32_t i = f_order_[s];
    if (!computes_fluid_slot(s)) continue;  // an image or a halo slot
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

}  // namespace sabo::sph
