// Continuity: drho/dt of every fluid particle from the velocity divergence at x_n with the
// new velocities, fluid and wall pairs, plus the walls' compression credit (walls.cpp,
// wall_compression()) that wall_work = "stored" or "bounded" applies. The density
// diffusion's part of drho/dt comes from the momentum pass (momentum.cpp).
#include <algorithm>
#include <cstdint>

#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/passes/pair_terms.hpp"
#include "sph_solver/passes/particle_for.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

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

}  // namespace

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
  if (decomposed()) exchange_velocities();
  if (credits_wall_work()) {
    compute_wall_compression();  // read by velocity_divergence()
    if (decomposed()) exchange_wall_credit();
  }
  with_terms(kernel_.type, false, false, false, false, DensityDiffusion::none,
             [&](auto terms) { velocity_divergence(terms, dt); });
}

template <class T>
void SphModel::velocity_divergence(T, double dt) {
  const std::size_t n = f_order_.size();
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
  const bool parallel = in_parallel(n - f_image_source_.size());
  particle_for(n, parallel, [=, this](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto i = static_cast<std::uint32_t>(k);
      if (!computes_fluid_slot(i)) continue;  // an image or a halo slot: read-only
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

}  // namespace sabo::sph
