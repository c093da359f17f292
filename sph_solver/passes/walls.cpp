// Walls as boundary particles (Adami, Hu & Adams 2012; docs/physics.md, "Walls"): the wall
// particles a step takes, the state extrapolated onto them from the fluid (pressure,
// density, no-slip velocity, the elastic-plastic stress), the force the fluid puts on each,
// and the credit that makes the walls' pressure work energy-consistent.
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "libsabo/core/error.hpp"
#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/passes/pair_terms.hpp"
#include "sph_solver/passes/particle_for.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// Kernel moments per wall slot for the stress extrapolation: W, W p, W e (3), W e e^T (6),
// W p e (3), W S_f (6), e = x_f - x_w.
constexpr std::size_t kWallMoments = 20;

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

}  // namespace

void SphModel::set_boundary(physics::BoundaryParticles boundary) {
  const std::size_t n = boundary.size();
  const auto sized = [n](const auto& values) { return values.empty() || values.size() == n; };
  if (!sized(boundary.velocity) || boundary.normal.size() != n || !sized(boundary.acceleration) ||
      boundary.volume.size() != n || !sized(boundary.free_slip)) {
    throw ModelInputError(
        fmt::format("boundary particles: {} positions but {} velocities, {} normals, {} "
                    "accelerations, {} volumes, {} free-slip flags; every array needs one entry per particle (the "
                    "velocities, accelerations and flags may be empty)",
                    n, boundary.velocity.size(), boundary.normal.size(), boundary.acceleration.size(),
                    boundary.volume.size(), boundary.free_slip.size()));
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
  any_free_slip_ = std::ranges::any_of(boundary.free_slip, [](std::uint8_t flag) { return flag != 0; });
  // Walls at rest (every rigid structure) keep no velocities and accelerations: 48 bytes a wall particle.
  for (auto* values : {&boundary.velocity, &boundary.acceleration}) {
    if (std::ranges::all_of(*values, [](const Vec3& v) { return v.isZero(0.0); })) std::vector<Vec3>().swap(*values);
  }
  boundary_ = std::move(boundary);
}

void SphModel::compute_boundary_state() {
  if (has_stress_) bmoment_.resize(kWallMoments * b_order_.size());
  with_terms(kernel_.type, any_gradient_, has_stress_, false, false, DensityDiffusion::none,
             [&](auto terms) { boundary_state(terms); });
  if (has_stress_) {
    // Alone, every entry is written (b_order_ holds every wall particle); on ranks, the walls of
    // other slabs stay 0 for reduce_step_maxima()'s sum.
    if (decomposed()) {
      boundary_stress_.assign(6 * boundary_.size(), 0.0);
    } else {
      boundary_stress_.resize(6 * boundary_.size());
    }
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
  const bool parallel = in_parallel(nb - b_image_source_.size());
  particle_for<Compile::baseline>(nb, parallel, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto s = static_cast<std::size_t>(k);
      const std::uint32_t id = b_order_[s];
      if (!computes_wall_slot(s)) continue;  // an image (copy_wall_image_state()) or a halo slot
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
        const Vec3 growth = double{brho_[s]} * (boundary_.acceleration_of(id) - gravity_) + grad_p;
        add_wall_shear(growth, n, -mean_e.dot(n), s_w);
      }
      const float components[6] = {s_w.xx, s_w.yy, s_w.zz, s_w.xy, s_w.yz, s_w.zx};
      for (std::size_t q = 0; q < 6; ++q) {
        bstress_[q * b_stride + s] = components[q];
        boundary_stress_[6 * id + q] = components[q];
      }
    }
  });
}

template <class T>
void SphModel::boundary_state(T) {
  const std::size_t nb = b_order_.size();
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
  // On ranks: over all ranks' fluid (distribute()).
  const bool one_material =
      decomposed() ? uniform_material_ >= 0
                   : std::all_of(fmat_.begin(), fmat_.begin() + static_cast<std::ptrdiff_t>(f_order_.size()),
                                 [&](std::uint32_t m) { return m == fmat_[0]; });
  const std::uint32_t first_material = decomposed() && uniform_material_ >= 0
                                           ? static_cast<std::uint32_t>(uniform_material_)
                                       : fmat_.empty() ? 0
                                                       : fmat_[0];
  const bool parallel = in_parallel(nb - b_image_source_.size());
  particle_for(nb, parallel, [=, this](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto s = static_cast<std::size_t>(k);
      const std::uint32_t id = b_order_[s];
      if (!computes_wall_slot(s)) continue;  // an image (copy_wall_image_state()) or a halo slot
      const Vec3 g_minus_a = gravity_ - boundary_.acceleration_of(id);
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
      std::uint32_t material = first_material;
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
    }
  });
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
  const bool parallel = in_parallel(nb - b_image_source_.size());
  particle_for(nb, parallel, [=, this, &b_position](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto b = static_cast<std::size_t>(k);
      if (!bmine_.empty() && bmine_[b] == 0) continue;  // a halo slot: its owner's
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
      // Two copies of the pair loop: without a free-slip wall it reads no slip normal.
      const auto fluid_neighbours = [&]<bool FreeSlip>() {
        float sx = 0, sy = 0, sz = 0;
        if constexpr (FreeSlip) {
          sx = bsx_[b];
          sy = bsy_[b];
          sz = bsz_[b];
        }
        for_neighbour_blocks(position, f_cell_start_, fx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = fx[j] - x, ry = fy[j] - y, rz = fz[j] - z;  // r_ib, i the fluid particle
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float vx = fvx[j], vy = fvy[j], vz = fvz[j];
            float vr = (vx - wx) * rx + (vy - wy) * ry + (vz - wz) * rz;
            if constexpr (FreeSlip) vr = wall_approach(vr, vx - wx, vy - wy, vz - wz, rx, ry, rz, sx, sy, sz);
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
      };
      if (any_free_slip_) {
        fluid_neighbours.template operator()<true>();
      } else {
        fluid_neighbours.template operator()<false>();
      }
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
  const bool parallel = in_parallel(nb - b_image_source_.size());
  particle_for(nb, parallel, [=, this](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto s = static_cast<std::size_t>(k);
      const std::uint32_t id = b_order_[s];
      if (!computes_wall_slot(s)) continue;  // an image (copied below) or a halo slot
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
  for (std::size_t s = 0; s < nb; ++s) {
    if (b_order_[s] >= walls) bcredit_[s] = bcredit_[b_slot_of_[wall_source(b_order_[s])]];
  }
}

void SphModel::compute_wall_compression() {
  with_terms(kernel_.type, false, false, false, false, DensityDiffusion::none,
             [&](auto terms) { wall_compression(terms); });
}

}  // namespace sabo::sph
