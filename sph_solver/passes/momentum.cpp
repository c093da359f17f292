// Momentum: the acceleration of every fluid particle from its fluid and wall pairs
// (pressure, Monaghan's artificial viscosity, the viscous stress, the elastic-plastic and
// artificial stresses) and gravity, with the density diffusion's drho/dt of the same pairs
// and the maxima the stable step needs.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/passes/pair_terms.hpp"
#include "sph_solver/passes/particle_for.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// What fluid_forces() reduces over the particles: the largest |h v_ij.r_ij / (r^2 + eta^2)|
// (m/s) and |a| (m/s^2) for the stable step, and the pairs inside the support for
// mean_neighbours(). Max and integer sum: the same on any number of threads.
struct StepMaxima {
  double mu = 0, acceleration = 0;
  std::int64_t neighbours = 0;
  void join(const StepMaxima& other) {
    mu = std::max(mu, other.mu);
    acceleration = std::max(acceleration, other.acceleration);
    neighbours += other.neighbours;
  }
};

}  // namespace

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
  const float* bsx = bsx_.data();
  const float* bsy = bsy_.data();
  const float* bsz = bsz_.data();
  const float* bvx = bvx_.data();
  const float* bvy = bvy_.data();
  const float* bvz = bvz_.data();
  const float* bvol = bvol_.data();
  const float* bpr = bpr_.data();
  const float* brho = brho_.data();
  const bool parallel = in_parallel(n - f_image_source_.size());
  const auto body = [=, this](std::int64_t first, std::int64_t last, StepMaxima& maxima) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto i = static_cast<std::uint32_t>(k);
      const std::uint32_t id = f_order_[i];
      if (!computes_fluid_slot(i)) continue;  // an image or a halo slot: read-only
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
      // Two copies of the wall loop: without a free-slip wall it reads no slip normal.
      const auto wall_neighbours = [&]<bool FreeSlip>() {
        for_neighbour_blocks(position, b_cell_start_, bx, [&](std::uint32_t j0, std::int32_t valid) {
#pragma omp simd
          for (std::int32_t l = 0; l < static_cast<std::int32_t>(kLanes); ++l) {
            const std::size_t j = std::size_t{j0} + static_cast<std::size_t>(l);
            const float rx = x - bx[j], ry = y - by[j], rz = z - bz[j];
            const float r2 = rx * rx + ry * ry + rz * rz;
            const bool inside = (l < valid) & (r2 < support2);
            const float f = inside ? gradient_factor<T::kernel>(r2, kernel) : 0.0f;
            const float rho_b = brho[j], m_b = rho_b * bvol[j];
            float vr = (vx - bwx[j]) * rx + (vy - bwy[j]) * ry + (vz - bwz[j]) * rz;
            if constexpr (FreeSlip) {
              vr = wall_approach(vr, vx - bwx[j], vy - bwy[j], vz - bwz[j], rx, ry, rz, bsx[j], bsy[j], bsz[j]);
            }
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
      };
      if (any_free_slip_) {
        wall_neighbours.template operator()<true>();
      } else {
        wall_neighbours.template operator()<false>();
      }
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
      maxima.mu = std::max(maxima.mu, double{lane_mu});
      maxima.acceleration = std::max(maxima.acceleration, a.norm());
      maxima.neighbours += lane_neighbours;
      if constexpr (T::diffusion) support_neighbours_[id] = static_cast<std::int32_t>(fluid_neighbours);
    }
  };
  const StepMaxima maxima = particle_reduce(n, parallel, StepMaxima{}, body);
  max_mu_ = maxima.mu;
  max_acceleration_ = maxima.acceleration;
  neighbour_pairs_ = maxima.neighbours;
  const std::size_t real = decomposed() ? owned_count_ : n - f_image_source_.size();
  mean_neighbours_ = real > 0 ? static_cast<double>(maxima.neighbours) / static_cast<double>(real) : 0.0;
}

}  // namespace sabo::sph
