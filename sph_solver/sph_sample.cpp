// SphModel::sample(): the fluid at a point, for gauges (docs/scene.md, [[gauges]]).
#include <Eigen/Cholesky>

#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// The moment matrix of the fit is taken as singular below this reciprocal condition number (positions
// scaled by 1 / h, so that its entries are of order 1).
constexpr double kMinFitCondition = 1e-6;

}  // namespace

template <class Visit>
void SphModel::for_fluid_within_support(const Vec3& point, Visit&& visit) const {
  if (f_cell_start_.empty() || !forces_ready_) return;
  const double support = kernel_.support();
  // Outside the grid (with one cell around it) no particle is within the support.
  const Vec3 grid_max =
      grid_origin_ + Vec3(static_cast<double>(nx_), static_cast<double>(ny_), static_cast<double>(nz_)) * support;
  if ((point.array() < grid_origin_.array() - support).any() || (point.array() > grid_max.array() + support).any()) {
    return;
  }
  const std::size_t particles = position_.size();
  const std::vector<Vec3>& sorted_position = periodic_.empty() ? position_ : f_sort_position_;
  const double support2 = support * support;
  for_neighbours(point.x(), point.y(), point.z(), f_cell_start_, [&](std::uint32_t slot) {
    const std::uint32_t slot_id = f_order_[slot];
    const Vec3& x = slot_id < particles ? position_[slot_id] : sorted_position[slot_id];
    if ((point - x).squaredNorm() < support2) visit(fluid_source(slot_id), x);
  });
}

double SphModel::kernel_sum(const Vec3& point) const {
  return remote_sampler_ ? remote_sampler_(point, true).kernel_sum : kernel_sum_here(point);
}

FluidSample SphModel::sample(const Vec3& point) const {
  return remote_sampler_ ? remote_sampler_(point, false) : sample_here(point);
}

double SphModel::kernel_sum_here(const Vec3& point) const {
  double sum = 0;
  for_fluid_within_support(point, [&](std::uint32_t id, const Vec3& x) {
    sum += mass_[id] / density_[id] * kernel_.value((point - x).norm());
  });
  return sum;
}

FluidSample SphModel::sample_here(const Vec3& point) const {
  // Weighted least squares of f_j = a + b . (x_j - x) / h over the neighbours: a is the value at x.
  Eigen::Matrix4d moment = Eigen::Matrix4d::Zero();
  Eigen::Matrix4d right = Eigen::Matrix4d::Zero();  // columns: pressure, velocity x, y, z
  FluidSample out;
  for_fluid_within_support(point, [&](std::uint32_t id, const Vec3& x) {
    const double weight = mass_[id] / density_[id] * kernel_.value((point - x).norm());
    const Eigen::Vector4d basis(1.0, (x.x() - point.x()) * kernel_.inverse_h, (x.y() - point.y()) * kernel_.inverse_h,
                                (x.z() - point.z()) * kernel_.inverse_h);
    const Eigen::Vector4d values(pressure_[id], velocity_[id].x(), velocity_[id].y(), velocity_[id].z());
    moment.noalias() += weight * basis * basis.transpose();
    right.noalias() += weight * basis * values.transpose();
    out.kernel_sum += weight;
  });
  if (out.kernel_sum < kDryKernelSum) return FluidSample{out.kernel_sum, 0.0, Vec3::Zero(), false};
  const Eigen::LDLT<Eigen::Matrix4d> fit(moment);
  Eigen::Vector4d value;
  if (fit.info() == Eigen::Success && fit.isPositive() && fit.rcond() > kMinFitCondition) {
    value = fit.solve(right).row(0).transpose();
    out.linear_fit = true;
  } else {
    value = right.row(0).transpose() / out.kernel_sum;  // Shepard: sum V W f / sum V W
  }
  out.pressure = value[0];
  out.velocity = Vec3(value[1], value[2], value[3]);
  return out;
}

}  // namespace sabo::sph
