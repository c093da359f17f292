#include "fem_solver/solid_body.hpp"

#include <algorithm>
#include <cassert>
#include <limits>

namespace sabo::fem {

SolidBody::SolidBody(HexMesh mesh, const MaterialParameters& material, double hourglass_scale)
    : SolidBody(std::move(mesh), material, hourglass_scale, HexFormulation::one_point) {}

SolidBody::SolidBody(HexMesh mesh, const MaterialParameters& material, HexFormulation formulation)
    : SolidBody(std::move(mesh), material, 1.0, formulation) {}

SolidBody::SolidBody(HexMesh mesh, const MaterialParameters& material, double hourglass_scale,
                     HexFormulation formulation)
    : mesh_(std::move(mesh)), material_(material), hourglass_scale_(hourglass_scale), formulation_(formulation) {
  const std::size_t nodes = mesh_.node.size();
  const std::size_t elements = mesh_.element.size();
  position_ = mesh_.node;
  velocity_.assign(nodes, Vec3::Zero());
  internal_force_.assign(nodes, Vec3::Zero());
  mass_.assign(nodes, 0.0);
  fixed_.assign(nodes, 0);
  state_.assign(elements, Hex8State{});
  if (formulation_ != HexFormulation::one_point) gauss_.assign(elements, Hex8GaussPoints{});
  active_.assign(elements, 1);
  element_force_.assign(8 * elements, Vec3::Zero());
  element_dt_.assign(elements, std::numeric_limits<double>::infinity());
  element_failed_.assign(elements, 0);
  for (std::size_t e = 0; e < elements; ++e) {
    HexNodes x;
    for (std::size_t a = 0; a < 8; ++a) x[a] = mesh_.node[mesh_.element[e][a]];
    const double volume = hex8_volume(x);
    state_[e].volume = volume;
    for (std::size_t a = 0; a < 8; ++a) mass_[mesh_.element[e][a]] += material_.density * volume / 8.0;
  }
  gather_ = NodeGather(nodes, mesh_.element);
  compute_internal_forces(0.0);
}

void SolidBody::fix(std::size_t node, unsigned dofs) {
  fixed_.at(node) = static_cast<std::uint8_t>(fixed_[node] | dofs);
  for (int d = 0; d < 3; ++d) {
    if ((dofs & (1u << d)) != 0) velocity_[node](d) = 0;
  }
}

std::size_t SolidBody::fix_in_box(const Aabb& box, unsigned dofs) {
  return fix_nodes_in_box(position_, box, [&](std::size_t i) { fix(i, dofs); });
}

void SolidBody::set_node_velocity(std::size_t node, const Vec3& velocity) {
  velocity_.at(node) = velocity;
  for (int d = 0; d < 3; ++d) {
    if ((fixed_[node] & (1u << d)) != 0) velocity_[node](d) = 0;
  }
}

void SolidBody::set_velocity(const Vec3& velocity) {
  for (std::size_t i = 0; i < velocity_.size(); ++i) set_node_velocity(i, velocity);
  kinetic_ = 0;
  for (std::size_t i = 0; i < velocity_.size(); ++i) kinetic_ += 0.5 * mass_[i] * velocity_[i].squaredNorm();
}

std::size_t SolidBody::compute_internal_forces(double dt_previous) {
  const auto elements = static_cast<std::ptrdiff_t>(mesh_.element.size());
  const double wave_speed = material_.wave_speed();
#pragma omp parallel for schedule(static) if (elements >= parallel_minimum_)
  for (std::ptrdiff_t signed_e = 0; signed_e < elements; ++signed_e) {
    const auto e = static_cast<std::size_t>(signed_e);
    HexNodes force;
    if (active_[e] == 0) {
      for (std::size_t a = 0; a < 8; ++a) element_force_[8 * e + a].setZero();
      element_dt_[e] = std::numeric_limits<double>::infinity();
      continue;
    }
    HexNodes x, v;
    for (std::size_t a = 0; a < 8; ++a) {
      x[a] = position_[mesh_.element[e][a]];
      v[a] = velocity_[mesh_.element[e][a]];
    }
    bool ok = false;
    switch (formulation_) {
      case HexFormulation::one_point:
        ok = hex8_internal_force(material_, hourglass_scale_, x, v, dt_previous, state_[e], force);
        break;
      case HexFormulation::fully_integrated:
        ok = hex8_full_internal_force(material_, x, v, dt_previous, state_[e], gauss_[e], force);
        break;
      case HexFormulation::enhanced_strain:
        ok = hex8_enhanced_internal_force(material_, x, v, dt_previous, state_[e], gauss_[e], force);
        break;
    }
    // An inverted element has failed too: it can carry no stress.
    element_failed_[e] = (!ok || (material_.erodes() && failed(material_, state_[e].point))) ? 1 : 0;
    for (std::size_t a = 0; a < 8; ++a) element_force_[8 * e + a] = force[a];
    element_dt_[e] = ok ? hex8_characteristic_length(x) / wave_speed : std::numeric_limits<double>::infinity();
  }
  const std::size_t newly_eroded =
      erode_failed_elements(element_failed_, state_, active_, element_dt_, erosion_, [&](std::size_t e) {
        for (std::size_t a = 0; a < 8; ++a) element_force_[8 * e + a].setZero();
      });
  const auto nodes = static_cast<std::ptrdiff_t>(position_.size());
#pragma omp parallel for schedule(static) if (nodes >= parallel_minimum_)
  for (std::ptrdiff_t signed_i = 0; signed_i < nodes; ++signed_i) {
    const auto i = static_cast<std::size_t>(signed_i);
    internal_force_[i] = gather_.sum(i, element_force_);
  }
  stable_dt_ = std::numeric_limits<double>::infinity();
  for (double dt : element_dt_) stable_dt_ = std::min(stable_dt_, dt);
  return newly_eroded;
}

void SolidBody::integrate(double dt_previous, double dt, std::span<const Vec3> external_force) {
  assert(external_force.empty() || external_force.size() == position_.size());
  const double dt_average = 0.5 * (dt_previous + dt);
  const auto nodes = static_cast<std::ptrdiff_t>(position_.size());
  std::vector<double> kinetic(position_.size()), work(position_.size());
#pragma omp parallel for schedule(static) if (nodes >= parallel_minimum_)
  for (std::ptrdiff_t signed_i = 0; signed_i < nodes; ++signed_i) {
    const auto i = static_cast<std::size_t>(signed_i);
    const Vec3 f_external = (external_force.empty() ? Vec3::Zero() : external_force[i]) + mass_[i] * gravity_;
    Vec3 acceleration = (f_external - internal_force_[i]) / mass_[i];
    for (int d = 0; d < 3; ++d) {
      if ((fixed_[i] & (1u << d)) != 0) acceleration(d) = 0;
    }
    const Vec3 old_velocity = velocity_[i];
    velocity_[i] += dt_average * acceleration;
    const Vec3 mid_velocity = 0.5 * (old_velocity + velocity_[i]);
    kinetic[i] = 0.5 * mass_[i] * mid_velocity.squaredNorm();
    Vec3 f_working = f_external;
    for (int d = 0; d < 3; ++d) {
      if ((fixed_[i] & (1u << d)) != 0) f_working(d) = 0;
    }
    work[i] = dt_average * f_working.dot(mid_velocity);
    position_[i] += dt * velocity_[i];
  }
  add_step_energies(kinetic, work, kinetic_, external_work_);
}

SolidEnergies SolidBody::energies() const {
  return body_energies(state_, active_, mass_, position_, gravity_, kinetic_, external_work_, erosion_);
}

BodyState SolidBody::save_state() const {
  BodyState out;
  const auto put = [&](double value) { out.real.push_back(value); };
  for (const auto* field : {&position_, &velocity_}) append_vectors(out, *field);
  for (const Hex8State& s : state_) for_each_value_of_hex(s, put);
  for (const Hex8GaussPoints& points : gauss_) {
    for (const MaterialPoint& point : points) for_each_value_of_point(point, put);
  }
  for (double value : {kinetic_, external_work_, erosion_.energy, stable_dt_}) put(value);
  out.active = active_;
  out.counters = {erosion_.topology_revision, erosion_.count};
  return out;
}

void SolidBody::restore_state(const BodyState& state, const std::string& what) {
  BodyStateReader reader(state, what);
  std::size_t per_element = 0;
  const Hex8State probe{};
  for_each_value_of_hex(probe, [&](const double&) { ++per_element; });
  std::size_t per_point = 0;
  const MaterialPoint probe_point{};
  for_each_value_of_point(probe_point, [&](const double&) { ++per_point; });
  reader.expect_sizes(6 * position_.size() + per_element * state_.size() + 8 * per_point * gauss_.size() + 4,
                      state_.size(), 2);
  for (auto* field : {&position_, &velocity_}) reader.read_vectors(*field);
  for (Hex8State& s : state_) for_each_value_of_hex(s, [&](double& value) { value = reader.next(); });
  for (Hex8GaussPoints& points : gauss_) {
    for (MaterialPoint& point : points) for_each_value_of_point(point, [&](double& value) { value = reader.next(); });
  }
  for (double* value : {&kinetic_, &external_work_, &erosion_.energy, &stable_dt_}) *value = reader.next();
  active_ = state.active;
  erosion_.topology_revision = state.counters[0];
  erosion_.count = static_cast<std::size_t>(state.counters[1]);
}

std::vector<std::size_t> SolidBody::inverted_elements() const {
  std::vector<std::size_t> inverted;
  for (std::size_t e = 0; e < mesh_.element.size(); ++e) {
    if (active_[e] == 0) continue;
    HexNodes x;
    for (std::size_t a = 0; a < 8; ++a) x[a] = position_[mesh_.element[e][a]];
    if (!(hex8_volume(x) > 0)) inverted.push_back(e);  // NaN too
  }
  return inverted;
}

}  // namespace sabo::fem
