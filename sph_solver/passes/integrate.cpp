// Integration: the leapfrog step (sph_model.hpp, "Step contract"), the coupler's forces it
// adds, the settling phase's damping, the energies summed at the step, and the stable step.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>

#include "libsabo/core/error.hpp"
#include "sph_solver/exact_sum.hpp"
#include "sph_solver/passes/pair_terms.hpp"
#include "sph_solver/passes/particle_for.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// The energies at the step. Exact sums (exact_sum.hpp): the chunks, the threads and the ranks that add
// the terms do not change the bits.
// kInflowPending: what advance_inflows() brings in, which the next step's account takes.
enum EnergyTerm : std::size_t { kKinetic, kPotential, kElastic, kWallHeld, kInflow, kInflowPending, kEnergyTerms };
struct EnergySums {
  std::array<ExactSum, kEnergyTerms> term;
  void join(const EnergySums& other) {
    for (std::size_t t = 0; t < kEnergyTerms; ++t) term[t].join(other.term[t]);
  }
};

}  // namespace

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

double SphModel::forces_stable_dt() const {
  const bool any_fluid = decomposed() ? global_particles_ > 0 : !f_order_.empty();
  const double h = kernel_.h;
  double dt_cv = any_fluid ? h / (sound_speed_ + max_mu_) : h / sound_speed_;
  dt_cv = std::min(dt_cv, elastic_wave_dt_);
  const double dt_force =
      max_acceleration_ > 0 ? std::sqrt(h / max_acceleration_) : std::numeric_limits<double>::infinity();
  return settings_.cfl * std::min({dt_cv, dt_force, min_viscous_dt_});
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
  const bool parallel = in_parallel(n);
  const bool external = !external_force_.empty();
  const bool periodic = !periodic_.empty();
  update_settle_factors(dt);
  if (!inflows_.empty()) set_inflow_velocities(dt);
  // Energies at the step, with the new velocities.
  EnergySums totals = particle_reduce<Compile::baseline>(
      n, parallel, EnergySums{}, [&](std::int64_t begin, std::int64_t end, EnergySums& sums) {
        for (auto i = static_cast<std::size_t>(begin); i < static_cast<std::size_t>(end); ++i) {
          if (!active_[i]) {
            if (external) external_force_[i].setZero();
            continue;
          }
          const FluidMaterial& material = materials_[material_[i]];
          const double particle_potential =
              -mass_[i] * gravity_.dot(periodic ? Vec3(position_[i] - wrap_offset_[i]) : position_[i]);
          const double particle_elastic = mass_[i] * material.eos.specific_energy(density_[i]);
          sums.term[kPotential].add(particle_potential);
          sums.term[kElastic].add(particle_elastic);
          if (!wall_work_held_.empty()) sums.term[kWallHeld].add(wall_work_held_[i]);
          Vec3 a = acceleration_[i];
          if (external) {
            a += external_force_[i] / mass_[i];
            external_force_[i].setZero();
          }
          Vec3 velocity;
          if (active_[i] == kFree) {
            velocity = velocity_[i] + dt_update * a;
            if (const double settle = settle_factor_[body_[i]]; settle != 1.0) velocity *= settle;
          } else {
            velocity = buffer_velocity_[body_[i]];  // an inflow's buffer (inflow.hpp)
          }
          const double particle_kinetic =
              first_step ? 0.5 * mass_[i] * velocity_[i].squaredNorm() : 0.5 * mass_[i] * velocity_[i].dot(velocity);
          sums.term[kKinetic].add(particle_kinetic);
          if (active_[i] == kEntering) {
            sums.term[kInflow].add(particle_kinetic + particle_potential + particle_elastic);
          } else if (active_[i] == kBuffer) {
            const Vec3 holding = mass_[i] * ((velocity - velocity_[i]) / dt_update - a);
            sums.term[kInflow].add(0.5 * dt_update * holding.dot(velocity_[i] + velocity));
          }
          velocity_[i] = velocity;
        }
      });
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
  particle_for<Compile::baseline>(f_order_.size(), parallel, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto s = static_cast<std::size_t>(k);
      if (computes_fluid_slot(s)) density_[f_order_[s]] += dt * out_drho_[s];
    }
  });
  particle_for<Compile::baseline>(n, parallel, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
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
  });
  // The inflows' account is cumulative: the last step's, what came in since (advance_inflows() below adds
  // to the next step's) and this step's work.
  const double inflow_before = energies_.inflow + inflow_pending_;
  if (!inflows_.empty()) advance_inflows(dt, totals.term[kInflowPending]);
  if (periodic) wrap_positions();
  const std::size_t lost_before = lost_;
  for (std::size_t i = 0; i < n; ++i) {
    // A buffer's particles keep to the buffer's path (the scene holds it in the domain).
    if (active_[i] != kFree) continue;
    // A position that is not finite is no particle leaving the domain: the solver's check_stability()
    // (libsabo/solver/stability.hpp) stops the run on it.
    const bool finite = std::isfinite(position_[i].x() + position_[i].y() + position_[i].z());
    if (finite && settings_.domain && !settings_.domain->contains(position_[i])) {
      active_[i] = 0;
      velocity_[i].setZero();
      ++lost_;
    }
  }
  if (decomposed()) {
    // Every rank's sums (its particles only) and losses, exactly (limbs of 32 bits in integers).
    std::vector<std::int64_t> limbs(4 * kEnergyTerms + 1);
    for (std::size_t t = 0; t < kEnergyTerms; ++t) {
      const ExactSum::Limbs own = totals.term[t].limbs();
      std::copy(own.begin(), own.end(), limbs.begin() + static_cast<std::ptrdiff_t>(4 * t));
    }
    limbs.back() = static_cast<std::int64_t>(lost_ - lost_before);
    ranks_->sum(limbs);
    for (std::size_t t = 0; t < kEnergyTerms; ++t) {
      ExactSum::Limbs all;
      std::copy_n(limbs.begin() + static_cast<std::ptrdiff_t>(4 * t), 4, all.begin());
      totals.term[t] = ExactSum::from_limbs(all);
    }
    lost_ = lost_before + static_cast<std::size_t>(limbs.back());
  }
  inflow_pending_ = totals.term[kInflowPending].value();
  Energies energies;
  energies.kinetic = totals.term[kKinetic].value();
  energies.potential = totals.term[kPotential].value();
  energies.elastic = totals.term[kElastic].value();
  energies.wall_held = totals.term[kWallHeld].value();
  energies.inflow = inflow_before + totals.term[kInflow].value();
  energies_ = energies;
  time_ += dt;
  forces_ready_ = false;
}

}  // namespace sabo::sph
