#include "fem_solver/shell_body.hpp"

#include <algorithm>
#include <cassert>
#include <limits>

#include "libsabo/geometry/node_welder.hpp"

namespace sabo::fem {

void add_panel(ShellMesh& mesh, const Vec3& origin, const Vec3& edge1, const Vec3& edge2, std::size_t n1,
               std::size_t n2, double thickness, std::uint32_t material) {
  const auto base = static_cast<std::uint32_t>(mesh.node.size());
  for (std::size_t j = 0; j <= n2; ++j) {
    for (std::size_t i = 0; i <= n1; ++i) {
      mesh.node.push_back(origin + edge1 * (static_cast<double>(i) / static_cast<double>(n1)) +
                          edge2 * (static_cast<double>(j) / static_cast<double>(n2)));
    }
  }
  const auto id = [&](std::size_t i, std::size_t j) { return base + static_cast<std::uint32_t>(i + (n1 + 1) * j); };
  for (std::size_t j = 0; j < n2; ++j) {
    for (std::size_t i = 0; i < n1; ++i) {
      mesh.element.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
      mesh.thickness.push_back(thickness);
      mesh.material.push_back(material);
    }
  }
}

void weld(ShellMesh& mesh, double tolerance) {
  geometry::NodeWelder welder(tolerance);
  std::vector<std::uint32_t> renumber(mesh.node.size());
  for (std::size_t i = 0; i < mesh.node.size(); ++i) renumber[i] = welder.add(mesh.node[i]);
  for (auto& element : mesh.element) {
    for (auto& n : element) n = renumber[n];
  }
  mesh.node = welder.take_positions();
}

ShellBody::ShellBody(ShellMesh mesh, std::vector<MaterialParameters> materials, double hourglass_scale,
                     ShellFormulation formulation)
    : mesh_(std::move(mesh)),
      materials_(std::move(materials)),
      hourglass_scale_(hourglass_scale),
      formulation_(formulation) {
  const std::size_t nodes = mesh_.node.size(), elements = mesh_.element.size();
  assert(mesh_.thickness.size() == elements && mesh_.material.size() == elements);
  position_ = mesh_.node;
  velocity_.assign(nodes, Vec3::Zero());
  angular_velocity_.assign(nodes, Vec3::Zero());
  internal_force_.assign(nodes, Vec3::Zero());
  internal_moment_.assign(nodes, Vec3::Zero());
  mass_.assign(nodes, 0.0);
  inertia_.assign(nodes, 0.0);
  fixed_.assign(nodes, 0);
  state_.assign(elements, Shell4State{});
  if (formulation_ == ShellFormulation::fully_integrated) gauss_.assign(elements, Shell4GaussPoints{});
  active_.assign(elements, 1);
  element_failed_.assign(elements, 0);
  element_force_.assign(4 * elements, Vec3::Zero());
  element_moment_.assign(4 * elements, Vec3::Zero());
  element_dt_.assign(elements, std::numeric_limits<double>::infinity());
  for (std::size_t e = 0; e < elements; ++e) {
    QuadNodes x;
    for (std::size_t a = 0; a < 4; ++a) x[a] = mesh_.node[mesh_.element[e][a]];
    const double area = shell4_area(x), t = mesh_.thickness[e];
    const double m = materials_[mesh_.material[e]].density * area * t / 4.0;
    for (std::size_t a = 0; a < 4; ++a) {
      mass_[mesh_.element[e][a]] += m;
      inertia_[mesh_.element[e][a]] += m * (t * t + area) / 12.0;
    }
  }
  gather_ = NodeGather(nodes, mesh_.element);
  compute_internal_forces(0.0);
}

void ShellBody::fix(std::size_t node, unsigned dofs) {
  fixed_.at(node) = static_cast<std::uint8_t>(fixed_[node] | dofs);
  for (int d = 0; d < 3; ++d) {
    if ((dofs & (1u << d)) != 0) velocity_[node](d) = 0;
    if ((dofs & (8u << d)) != 0) angular_velocity_[node](d) = 0;
  }
}

std::size_t ShellBody::fix_in_box(const Aabb& box, unsigned dofs) {
  return fix_nodes_in_box(position_, box, [&](std::size_t i) { fix(i, dofs); });
}

void ShellBody::set_velocity(const Vec3& velocity) {
  kinetic_ = 0;
  for (std::size_t i = 0; i < velocity_.size(); ++i) {
    for (int d = 0; d < 3; ++d) velocity_[i](d) = (fixed_[i] & (1u << d)) != 0 ? 0.0 : velocity(d);
    kinetic_ += 0.5 * mass_[i] * velocity_[i].squaredNorm();
  }
}

std::size_t ShellBody::compute_internal_forces(double dt_previous) {
  const auto elements = static_cast<std::ptrdiff_t>(mesh_.element.size());
#pragma omp parallel for schedule(static) if (elements >= parallel_minimum_)
  for (std::ptrdiff_t signed_e = 0; signed_e < elements; ++signed_e) {
    const auto e = static_cast<std::size_t>(signed_e);
    QuadNodes force, moment;
    for (std::size_t a = 0; a < 4; ++a) {
      element_force_[4 * e + a].setZero();
      element_moment_[4 * e + a].setZero();
    }
    element_dt_[e] = std::numeric_limits<double>::infinity();
    if (active_[e] == 0) continue;
    QuadNodes x, v, w;
    for (std::size_t a = 0; a < 4; ++a) {
      x[a] = position_[mesh_.element[e][a]];
      v[a] = velocity_[mesh_.element[e][a]];
      w[a] = angular_velocity_[mesh_.element[e][a]];
    }
    const MaterialParameters& material = materials_[mesh_.material[e]];
    const bool ok = formulation_ == ShellFormulation::fully_integrated
                        ? shell4_full_internal_force(material, mesh_.thickness[e], x, v, w, dt_previous, state_[e],
                                                     gauss_[e], force, moment)
                        : shell4_internal_force(material, mesh_.thickness[e], hourglass_scale_, x, v, w, dt_previous,
                                                state_[e], force, moment);
    bool failed_now = !ok;
    if (ok && material.erodes()) {
      for (const auto& point : state_[e].point) failed_now = failed_now || failed(material, point);
    }
    element_failed_[e] = failed_now ? 1 : 0;
    if (!ok) continue;
    for (std::size_t a = 0; a < 4; ++a) {
      element_force_[4 * e + a] = force[a];
      element_moment_[4 * e + a] = moment[a];
    }
    element_dt_[e] = shell4_characteristic_length(x) / material.plate_wave_speed();
  }
  const std::size_t newly_eroded =
      erode_failed_elements(element_failed_, state_, active_, element_dt_, erosion_, [&](std::size_t e) {
        for (std::size_t a = 0; a < 4; ++a) {
          element_force_[4 * e + a].setZero();
          element_moment_[4 * e + a].setZero();
        }
      });
  const auto nodes = static_cast<std::ptrdiff_t>(position_.size());
#pragma omp parallel for schedule(static) if (nodes >= parallel_minimum_)
  for (std::ptrdiff_t signed_i = 0; signed_i < nodes; ++signed_i) {
    const auto i = static_cast<std::size_t>(signed_i);
    internal_force_[i] = gather_.sum(i, element_force_);
    internal_moment_[i] = gather_.sum(i, element_moment_);
  }
  stable_dt_ = std::numeric_limits<double>::infinity();
  for (double dt : element_dt_) stable_dt_ = std::min(stable_dt_, dt);
  return newly_eroded;
}

void ShellBody::integrate(double dt_previous, double dt, std::span<const Vec3> external_force) {
  const double dt_average = 0.5 * (dt_previous + dt);
  const auto nodes = static_cast<std::ptrdiff_t>(position_.size());
  std::vector<double> kinetic(position_.size()), work(position_.size());
#pragma omp parallel for schedule(static) if (nodes >= parallel_minimum_)
  for (std::ptrdiff_t signed_i = 0; signed_i < nodes; ++signed_i) {
    const auto i = static_cast<std::size_t>(signed_i);
    if (mass_[i] <= 0) continue;
    Vec3 f_external = mass_[i] * gravity_ - damping_ * mass_[i] * velocity_[i];
    if (!external_force.empty()) f_external += external_force[i];
    Vec3 acceleration = (f_external - internal_force_[i]) / mass_[i];
    Vec3 angular_acceleration = -internal_moment_[i] / inertia_[i] - damping_ * angular_velocity_[i];
    for (int d = 0; d < 3; ++d) {
      if ((fixed_[i] & (1u << d)) != 0) {
        acceleration(d) = 0;
        f_external(d) = 0;
      }
      if ((fixed_[i] & (8u << d)) != 0) angular_acceleration(d) = 0;
    }
    const Vec3 old_velocity = velocity_[i], old_angular = angular_velocity_[i];
    velocity_[i] += dt_average * acceleration;
    angular_velocity_[i] += dt_average * angular_acceleration;
    const Vec3 mid = 0.5 * (old_velocity + velocity_[i]);
    const Vec3 mid_angular = 0.5 * (old_angular + angular_velocity_[i]);
    kinetic[i] = 0.5 * mass_[i] * mid.squaredNorm() + 0.5 * inertia_[i] * mid_angular.squaredNorm();
    work[i] = dt_average * f_external.dot(mid);
    position_[i] += dt * velocity_[i];
  }
  add_step_energies(kinetic, work, kinetic_, external_work_);
}

SolidEnergies ShellBody::energies() const {
  return body_energies(state_, active_, mass_, position_, gravity_, kinetic_, external_work_, erosion_);
}

double ShellBody::drilling_energy() const {
  double sum = 0;
  for (std::size_t e = 0; e < gauss_.size(); ++e) {
    if (active_[e] != 0) sum += gauss_[e].drilling_energy;
  }
  return sum;
}

BodyState ShellBody::save_state() const {
  BodyState out;
  const auto put = [&](double value) { out.real.push_back(value); };
  for (const auto* field : {&position_, &velocity_, &angular_velocity_}) append_vectors(out, *field);
  for (const Shell4State& s : state_) for_each_value_of_shell(s, put);
  for (const Shell4GaussPoints& g : gauss_) for_each_value_of_shell_gauss(g, put);
  for (double value : {kinetic_, external_work_, erosion_.energy, stable_dt_}) put(value);
  out.active = active_;
  out.counters = {erosion_.topology_revision, erosion_.count};
  return out;
}

void ShellBody::restore_state(const BodyState& state, const std::string& what) {
  BodyStateReader reader(state, what);
  std::size_t per_element = 0;
  const Shell4State probe{};
  for_each_value_of_shell(probe, [&](const double&) { ++per_element; });
  std::size_t per_gauss = 0;
  const Shell4GaussPoints gauss_probe{};
  for_each_value_of_shell_gauss(gauss_probe, [&](const double&) { ++per_gauss; });
  reader.expect_sizes(9 * position_.size() + per_element * state_.size() + per_gauss * gauss_.size() + 4, state_.size(),
                      2);
  for (auto* field : {&position_, &velocity_, &angular_velocity_}) reader.read_vectors(*field);
  for (Shell4State& s : state_) for_each_value_of_shell(s, [&](double& value) { value = reader.next(); });
  for (Shell4GaussPoints& g : gauss_) for_each_value_of_shell_gauss(g, [&](double& value) { value = reader.next(); });
  for (double* value : {&kinetic_, &external_work_, &erosion_.energy, &stable_dt_}) *value = reader.next();
  active_ = state.active;
  erosion_.topology_revision = state.counters[0];
  erosion_.count = static_cast<std::size_t>(state.counters[1]);
}

}  // namespace sabo::fem
