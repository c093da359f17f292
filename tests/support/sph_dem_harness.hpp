#pragma once
// The fluid, the boulders and an SPH-DEM pair coupled in one process, step for
// step as the coupler and the two solvers do it (docs/design.md, "An explicit, lock-step step"): states at x_n,
// the pair's compute and scatter, the boulders' boundary particles after the
// tank's own walls, the SPH and DEM forces, central-difference integration.
// No sockets, no FEM: the tank is a fixed set of wall particles for the fluid
// and plane walls for the spheres (DemModel::add_wall). Exact bookkeeping of
// the momentum and energy of both models for the conservation tests.
#include <Eigen/Geometry>
#include <chrono>
#include <memory>
#include <vector>

#include "coupler/contact/pair_factory.hpp"
#include "dem_solver/dem_model.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::testing {

class SphDemHarness {
 public:
  // `tank`: wall particles of the fluid's container (kept for the whole run, first in the list).
  SphDemHarness(const scene::Scene& scene, physics::BoundaryParticles tank)
      : scene_(scene), sph_(scene_), dem_(scene_), tank_(std::move(tank)) {
    auto pairs = coupler::make_contact_pairs(scene_);
    for (auto& p : pairs) {
      if (p->joins(sabo::Role::sph) && p->joins(sabo::Role::dem)) pairs_.push_back(std::move(p));
    }
    auto* ft = sph_registration_.mutable_particles();
    for (std::size_t i = 0; i < sph_.size(); ++i) {
      ft->add_id(i), ft->add_radius(0.5 * scene_.sph.particle_spacing), ft->add_mass(sph_.masses()[i]);
      ft->add_material(sph_.material_index()[i]), ft->add_body(sph_.body_index()[i]);
    }
    dem_registration_.set_exposes_angular_velocity(true);
    auto* dt = dem_registration_.mutable_particles();
    for (std::size_t j = 0; j < dem_.size(); ++j) {
      dt->add_id(j), dt->add_radius(dem_.radii()[j]), dt->add_mass(dem_.masses()[j]);
      dt->add_material(dem_.material_index()[j]), dt->add_body(dem_.body_index()[j]);
    }
    solvers_.set({sabo::Role::sph, 1.0, &sph_registration_, &sph_state_});
    solvers_.set({sabo::Role::dem, 1.0, &dem_registration_, &dem_state_});
    for (auto& p : pairs_) p->start(solvers_, replies_);
  }

  [[nodiscard]] sph::SphModel& sph() { return sph_; }
  [[nodiscard]] dem::DemModel& dem() { return dem_; }
  [[nodiscard]] double time() const { return time_; }
  [[nodiscard]] std::uint64_t steps() const { return step_; }
  [[nodiscard]] const coupler::ContactPair& pair(std::size_t k = 0) const { return *pairs_.at(k); }
  // The fluid's force on sphere j in the last step, N (every sphere is in the state, in id order).
  [[nodiscard]] Vec3 fluid_force_on_sphere(std::size_t j) const {
    const auto& f = replies_.particle_force(sabo::Role::dem);
    return 3 * j + 2 < f.size() ? Vec3(f[3 * j], f[3 * j + 1], f[3 * j + 2]) : Vec3::Zero();
  }

  // The fluid's torque on sphere j about its centre in the last step, N m (zero if the pair sends none).
  [[nodiscard]] Vec3 fluid_torque_on_sphere(std::size_t j) const {
    const auto& t = replies_.particle_torque(sabo::Role::dem);
    return 3 * j + 2 < t.size() ? Vec3(t[3 * j], t[3 * j + 1], t[3 * j + 2]) : Vec3::Zero();
  }

  // Total momentum at the half step of the last integrate, kg m/s; and what gravity and the tank
  // walls gave the fluid and the spheres since the start, plus the fluid's impulse on the boulders
  // that is still in flight (returned with the next state, delivered at the next step).
  [[nodiscard]] Vec3 momentum() const {
    Vec3 p = Vec3::Zero();
    for (std::size_t i = 0; i < sph_.size(); ++i) {
      if (sph_.active()[i]) p += sph_.masses()[i] * sph_.velocities()[i];
    }
    for (std::size_t j = 0; j < dem_.size(); ++j) p += dem_.masses()[j] * dem_.velocities()[j];
    return p;
  }
  [[nodiscard]] Vec3 initial_momentum() const { return initial_momentum_; }
  [[nodiscard]] Vec3 external_impulse() const { return gravity_impulse_ + tank_impulse_ + in_flight_; }
  [[nodiscard]] Vec3 gravity_impulse() const { return gravity_impulse_; }
  // A constant force on sphere j from the next step on, N, besides gravity and the fluid (e.g. its
  // submerged weight when the fluid carries no hydrostatic pressure); counted with gravity's impulse.
  void set_sphere_body_force(std::size_t j, const Vec3& force) {
    body_force_.resize(3 * dem_.size(), 0.0);
    body_index_.resize(dem_.size());
    for (std::size_t k = 0; k < body_index_.size(); ++k) body_index_[k] = static_cast<std::uint32_t>(k);
    for (int c = 0; c < 3; ++c) body_force_.at(3 * j + c) = force[c];
  }
  // Energy of both models (kinetic, potential, elastic; the SPH's held wall work and the
  // dissipation counted as gone) and of the pairs' springs, J, at the last step.
  [[nodiscard]] double energy() const { return energy_; }
  [[nodiscard]] double max_energy() const { return max_energy_; }
  [[nodiscard]] double initial_energy() const { return initial_energy_; }
  // Wall time so far in the pairs (compute and scatter: the coupler's share), in the SPH model
  // (forces and integration) and in the DEM model, s.
  [[nodiscard]] double pair_seconds() const { return pair_seconds_; }
  [[nodiscard]] double sph_seconds() const { return sph_seconds_; }
  [[nodiscard]] double dem_seconds() const { return dem_seconds_; }

  void step(double max_dt = std::numeric_limits<double>::infinity()) {
    if (step_ == 0) initial_momentum_ = momentum();
    using Clock = std::chrono::steady_clock;
    const auto since = [](Clock::time_point start) {
      return std::chrono::duration<double>(Clock::now() - start).count();
    };
    fill_states();
    auto start = Clock::now();
    for (auto& p : pairs_) p->compute(solvers_, {step_, time_, dt_previous_});
    double dt = std::min({sph_.stable_dt(), dem_.stable_dt(), max_dt});
    for (auto& p : pairs_) dt = std::min(dt, p->stable_dt());
    replies_.begin_step(solvers_, 0);
    for (auto& p : pairs_) p->scatter(solvers_, dt, replies_);
    pair_seconds_ += since(start);

    start = Clock::now();
    physics::BoundaryParticles walls = tank_;
    for (const physics::BoundaryParticles* part : replies_.boundary().parts()) append(walls, *part);
    sph_.set_boundary(std::move(walls));
    sph_.compute_internal_forces(dt_previous_);
    const auto& index = sph_state_.index();
    sph_.add_external_forces({index.data(), static_cast<std::size_t>(index.size())},
                             replies_.particle_force(sabo::Role::sph));
    sph_seconds_ += since(start);
    start = Clock::now();
    dem_.compute_internal_forces(dt_previous_);
    const auto& dem_index = dem_state_.index();
    dem_.add_external_forces({dem_index.data(), static_cast<std::size_t>(dem_index.size())},
                             replies_.particle_force(sabo::Role::dem), replies_.particle_torque(sabo::Role::dem));
    if (!body_force_.empty()) dem_.add_external_forces(body_index_, body_force_, {});
    dem_seconds_ += since(start);

    // The impulses of this step act over dt_avg, as both models integrate them.
    const double dt_avg = 0.5 * (dt_previous_ + dt);
    double mass = 0;
    for (std::size_t i = 0; i < sph_.size(); ++i) mass += sph_.active()[i] ? sph_.masses()[i] : 0.0;
    for (std::size_t j = 0; j < dem_.size(); ++j)
      mass += dem_.is_fixed(static_cast<std::uint32_t>(j)) ? 0.0 : dem_.masses()[j];
    gravity_impulse_ += dt_avg * mass * scene_.run.gravity;
    for (std::size_t j = 0; j < body_force_.size() / 3; ++j) {
      gravity_impulse_ += dt_avg * Vec3(body_force_[3 * j], body_force_[3 * j + 1], body_force_[3 * j + 2]);
    }
    const auto forces = sph_.boundary_forces();
    Vec3 on_tank = Vec3::Zero(), on_boulders = Vec3::Zero();
    for (std::size_t k = 0; k < forces.size(); ++k) (k < tank_.size() ? on_tank : on_boulders) += forces[k];
    tank_impulse_ -= dt_avg * on_tank;
    in_flight_ = -dt_avg * on_boulders;  // the boulders get it at the next step

    start = Clock::now();
    sph_.integrate(dt_previous_, dt);
    sph_seconds_ += since(start);
    start = Clock::now();
    dem_.integrate(dt_previous_, dt);
    dem_seconds_ += since(start);
    time_ += dt;
    dt_previous_ = dt;
    ++step_;
    energy_ = sph_.energies().total() + dem_.energies().total();
    for (const auto& p : pairs_) energy_ += p->energy().elastic;
    if (step_ == 1) initial_energy_ = max_energy_ = energy_;
    max_energy_ = std::max(max_energy_, energy_);
  }

 private:
  static void append(physics::BoundaryParticles& to, const physics::BoundaryParticles& from) {
    to.position.insert(to.position.end(), from.position.begin(), from.position.end());
    to.velocity.insert(to.velocity.end(), from.velocity.begin(), from.velocity.end());
    to.normal.insert(to.normal.end(), from.normal.begin(), from.normal.end());
    to.acceleration.insert(to.acceleration.end(), from.acceleration.begin(), from.acceleration.end());
    to.volume.insert(to.volume.end(), from.volume.begin(), from.volume.end());
  }

  void fill_states() {
    sph_state_.Clear();
    sph_state_.set_step(step_);
    for (std::size_t i = 0; i < sph_.size(); ++i) {
      if (!sph_.active()[i]) continue;
      sph_state_.add_index(static_cast<std::uint32_t>(i));
      for (int c = 0; c < 3; ++c) sph_state_.add_position(sph_.positions()[i][c]);
      for (int c = 0; c < 3; ++c) sph_state_.add_velocity(sph_.velocities()[i][c]);
    }
    // The forces the fluid put on the boulders' particles of the last step (they follow the tank's).
    const auto forces = sph_.boundary_forces();
    if (step_ > 0) {
      for (std::size_t k = tank_.size(); k < forces.size(); ++k) {
        for (int c = 0; c < 3; ++c) sph_state_.add_boundary_force(forces[k][c]);
      }
    }
    dem_state_.Clear();
    dem_state_.set_step(step_);
    for (std::size_t j = 0; j < dem_.size(); ++j) {
      dem_state_.add_index(static_cast<std::uint32_t>(j));
      for (int c = 0; c < 3; ++c) dem_state_.add_position(dem_.positions()[j][c]);
      for (int c = 0; c < 3; ++c) dem_state_.add_velocity(dem_.velocities()[j][c]);
      for (int c = 0; c < 3; ++c) dem_state_.add_angular_velocity(dem_.angular_velocities()[j][c]);
    }
  }

  scene::Scene scene_;
  sph::SphModel sph_;
  dem::DemModel dem_;
  physics::BoundaryParticles tank_;
  std::vector<std::unique_ptr<coupler::ContactPair>> pairs_;
  sabo::v1::Register sph_registration_, dem_registration_;
  sabo::v1::StepState sph_state_, dem_state_;
  coupler::Solvers solvers_;
  coupler::Replies replies_;
  double time_ = 0, dt_previous_ = 0;
  std::uint64_t step_ = 0;
  std::vector<double> body_force_;  // 3 per sphere, or empty
  std::vector<std::uint32_t> body_index_;
  Vec3 initial_momentum_ = Vec3::Zero(), gravity_impulse_ = Vec3::Zero(), tank_impulse_ = Vec3::Zero(),
       in_flight_ = Vec3::Zero();
  double energy_ = 0, initial_energy_ = 0, max_energy_ = 0;
  double pair_seconds_ = 0, sph_seconds_ = 0, dem_seconds_ = 0;
};

}  // namespace sabo::testing
