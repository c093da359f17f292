#include "sph_solver/energy_audit.hpp"

#include <cassert>

namespace sabo::sph {

void EnergyAudit::before_integrate(const SphModel& model, std::span<const std::uint32_t> index,
                                   std::span<const double> force) {
  assert(force.size() == 3 * index.size());
  wall_power_ = 0;
  const auto walls = model.boundary_forces();
  const auto& velocity = model.boundary().velocity;
  if (walls.size() == velocity.size()) {
    for (std::size_t k = 0; k < walls.size(); ++k) wall_power_ -= walls[k].dot(velocity[k]);
  }
  index_.clear();
  force_.clear();
  velocity_before_.clear();
  for (std::size_t k = 0; k < index.size(); ++k) {
    const Vec3 f(force[3 * k], force[3 * k + 1], force[3 * k + 2]);
    if (f.isZero(0.0) || index[k] >= model.size()) continue;
    index_.push_back(index[k]);
    force_.push_back(f);
    velocity_before_.push_back(model.velocities()[index[k]]);
  }
}

void EnergyAudit::after_integrate(const SphModel& model, double dt_previous, double dt) {
  const double dt_avg = dt_previous > 0 ? 0.5 * (dt_previous + dt) : 0.5 * dt;
  double work = wall_power_ * dt_avg;
  for (std::size_t k = 0; k < index_.size(); ++k) {
    const Vec3 mean_velocity = 0.5 * (velocity_before_[k] + model.velocities()[index_[k]]);
    work += dt_avg * force_[k].dot(mean_velocity);
  }
  const double total = model.energies().total();
  work += model.energies().inflow - previous_inflow_;
  previous_inflow_ = model.energies().inflow;
  dissipated_ += previous_total_ - total + work;
  work_in_ += work;
  previous_total_ = total;
  wall_power_ = 0;
  index_.clear();
  force_.clear();
  velocity_before_.clear();
}

}  // namespace sabo::sph
