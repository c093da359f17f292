#include "dem_solver/dem_model.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

#include "dem_solver/sphere_fill.hpp"
#include "libsabo/core/error.hpp"

namespace sabo::dem {
namespace {

std::uint64_t pair_key(std::uint32_t a, std::uint32_t b) {
  return (std::uint64_t{a} << 32) | b;
}

std::string origin_text(const scene::ParticleSet& set) {
  return fmt::format("{}:{}: particle set '{}'", set.origin.file.string(), set.origin.line, set.name);
}

}  // namespace

DemModel::DemModel(const scene::Scene& scene) : settings_(scene.dem_contact), gravity_(scene.run.gravity) {
  for (const auto& material : scene.materials) material_bulk_modulus_.push_back(material.bulk_modulus());

  // Fill sets avoid every listed sphere and the spheres of earlier fill sets.
  std::vector<scene::Sphere> obstacles;
  for (const auto& set : scene.particle_sets) {
    if (set.kind == scene::ParticleSet::Kind::list)
      obstacles.insert(obstacles.end(), set.spheres.begin(), set.spheres.end());
  }
  for (std::size_t set_index = 0; set_index < scene.particle_sets.size(); ++set_index) {
    const auto& set = scene.particle_sets[set_index];
    body_names_.push_back(set.name);
    std::vector<scene::Sphere> filled;
    if (set.kind == scene::ParticleSet::Kind::fill) {
      filled = fill_region(set, obstacles);
      obstacles.insert(obstacles.end(), filled.begin(), filled.end());
    }
    const auto& spheres = set.kind == scene::ParticleSet::Kind::fill ? filled : set.spheres;
    const auto material = static_cast<std::uint32_t>(scene.material_index(set.material));
    const double density = scene.materials[material].density;
    for (const auto& sphere : spheres) {
      position_.push_back(sphere.center);
      velocity_.push_back(sphere.velocity);
      spin_.push_back(sphere.angular_velocity);
      radius_.push_back(sphere.radius);
      mass_.push_back(density * 4.0 / 3.0 * std::numbers::pi * sphere.radius * sphere.radius * sphere.radius);
      material_.push_back(material);
      body_.push_back(static_cast<std::uint32_t>(set_index));
      largest_radius_ = std::max(largest_radius_, sphere.radius);
    }
  }
  if (size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw SceneError(
        fmt::format("{}: {} DEM spheres exceed the 32-bit ids. Fix: fewer spheres.", scene.file.string(), size()));
  }
  force_.assign(size(), Vec3::Zero());
  torque_.assign(size(), Vec3::Zero());
  fixed_.assign(size(), 0);

  // Spheres of different sets must not start overlapping (fill sets avoid the others by construction).
  if (size() > 0) {
    cells_.build_points(position_, 2 * largest_radius_);
    for (std::uint32_t i = 0; i < size(); ++i) {
      cells_.for_each_near(position_[i], [&](std::uint32_t j) {
        if (j <= i) return;
        const double reach = radius_[i] + radius_[j];
        if ((position_[i] - position_[j]).norm() >= reach * (1 - 1e-6))
          return;  // decimal round-off of touching spheres
        const auto& set_i = scene.particle_sets[body_[i]];
        const auto& set_j = scene.particle_sets[body_[j]];
        throw SceneError(fmt::format(
            "{}: a sphere at ({:g}, {:g}, {:g}) overlaps a sphere at ({:g}, {:g}, {:g}) of {} by {:g} m. Fix: move "
            "or shrink one of them.",
            origin_text(set_i), position_[i].x(), position_[i].y(), position_[i].z(), position_[j].x(),
            position_[j].y(), position_[j].z(), body_[i] == body_[j] ? std::string("the same set") : origin_text(set_j),
            reach - (position_[i] - position_[j]).norm()));
      });
    }
  }

  for (std::uint32_t i = 0; i < size(); ++i) {
    const double inertia = 0.4 * mass_[i] * radius_[i] * radius_[i];
    energies_.kinetic += 0.5 * mass_[i] * velocity_[i].squaredNorm() + 0.5 * inertia * spin_[i].squaredNorm();
    energies_.potential -= mass_[i] * gravity_.dot(position_[i]);
  }
  sphere_kinetic_.assign(size(), 0);
  sphere_potential_.assign(size(), 0);
}

void DemModel::set_fixed(std::uint32_t id, bool fixed) {
  assert(id < size());
  if (fixed && !fixed_[id]) {
    const double inertia = 0.4 * mass_[id] * radius_[id] * radius_[id];
    energies_.kinetic -= 0.5 * mass_[id] * velocity_[id].squaredNorm() + 0.5 * inertia * spin_[id].squaredNorm();
    energies_.potential += mass_[id] * gravity_.dot(position_[id]);
    velocity_[id].setZero();
    spin_[id].setZero();
  } else if (!fixed && fixed_[id]) {
    energies_.potential -= mass_[id] * gravity_.dot(position_[id]);
  }
  fixed_[id] = fixed ? 1 : 0;
}

double DemModel::inverse_inertia(std::uint32_t id) const {
  return fixed_[id] ? 0.0 : 1.0 / (0.4 * mass_[id] * radius_[id] * radius_[id]);
}

double DemModel::normal_stiffness(std::uint32_t a, std::uint32_t b) const {
  if (settings_.normal_stiffness) return *settings_.normal_stiffness;
  const double stiffness_a = material_bulk_modulus_[material_[a]] * radius_[a];
  const double stiffness_b = material_bulk_modulus_[material_[b]] * radius_[b];
  return settings_.normal_stiffness_scale * stiffness_a * stiffness_b / (stiffness_a + stiffness_b);
}

physics::SpringDashpot DemModel::contact_law(std::uint32_t a, std::uint32_t b) const {
  const double normal = normal_stiffness(a, b);
  const double tangential = settings_.tangential_stiffness_ratio * normal;
  double effective_mass = 0;
  if (fixed_[a] && !fixed_[b]) {
    effective_mass = mass_[b];
  } else if (fixed_[b] && !fixed_[a]) {
    effective_mass = mass_[a];
  } else if (!fixed_[a] && !fixed_[b]) {
    effective_mass = mass_[a] * mass_[b] / (mass_[a] + mass_[b]);
  }
  return physics::SpringDashpot{
      .normal_stiffness = normal,
      .normal_damping = physics::damping_coefficient(normal, effective_mass, settings_.normal_damping_ratio),
      .tangential_stiffness = tangential,
      .tangential_damping =
          physics::damping_coefficient(tangential, effective_mass, settings_.tangential_damping_ratio),
      .friction = settings_.friction,
  };
}

physics::RollingSpring DemModel::rolling_law(std::uint32_t a, std::uint32_t b) const {
  const double effective_radius = radius_[a] * radius_[b] / (radius_[a] + radius_[b]);
  const double stiffness =
      physics::rolling_stiffness(normal_stiffness(a, b), settings_.rolling_friction, effective_radius);
  const double inverse_inertia_sum = inverse_inertia(a) + inverse_inertia(b);
  const double effective_inertia = inverse_inertia_sum > 0 ? 1.0 / inverse_inertia_sum : 0.0;
  return physics::RollingSpring{
      .stiffness = stiffness,
      .damping = physics::damping_coefficient(stiffness, effective_inertia, settings_.tangential_damping_ratio),
      .friction = settings_.rolling_friction,
      .effective_radius = effective_radius,
  };
}

void DemModel::find_contacts() {
  const auto n = static_cast<std::int64_t>(size());
  parallel_ = size() >= kParallelThreshold;
  contact_count_.assign(size(), 0);
  contact_offset_.assign(size() + 1, 0);
  if (n == 0) {
    pair_a_.clear();
    pair_b_.clear();
    return;
  }
  cells_.build_points(position_, 2 * largest_radius_);
  auto touching = [this](std::uint32_t i, std::uint32_t j) {
    if (j <= i || (fixed_[i] && fixed_[j])) return false;
    const double reach = radius_[i] + radius_[j];
    return (position_[i] - position_[j]).squaredNorm() < reach * reach;
  };
  // Two passes (count, then fill) so that the pair list is built in parallel in id order.
#pragma omp parallel for schedule(static) if (parallel_)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto i = static_cast<std::uint32_t>(k);
    std::uint32_t count = 0;
    cells_.for_each_near(position_[i], [&](std::uint32_t j) { count += touching(i, j) ? 1 : 0; });
    contact_count_[i] = count;
  }
  for (std::size_t i = 0; i < size(); ++i) contact_offset_[i + 1] = contact_offset_[i] + contact_count_[i];
  pair_a_.resize(contact_offset_.back());
  pair_b_.resize(contact_offset_.back());
#pragma omp parallel for schedule(static) if (parallel_)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto i = static_cast<std::uint32_t>(k);
    std::uint32_t slot = contact_offset_[i];
    cells_.for_each_near(position_[i], [&](std::uint32_t j) {
      if (!touching(i, j)) return;
      pair_a_[slot] = i;
      pair_b_[slot++] = j;
    });
    std::sort(pair_b_.begin() + contact_offset_[i], pair_b_.begin() + contact_offset_[i + 1]);
  }
}

void DemModel::compute_pair_forces(double dt_previous) {
  const std::size_t pairs = pair_a_.size();
  pair_force_.resize(pairs);
  pair_torque_a_.resize(pairs);
  pair_torque_b_.resize(pairs);
  pair_dissipative_torque_.resize(pairs);
  pair_relative_spin_.resize(pairs);
  pair_elastic_.resize(pairs);
  pair_dissipative_force_.resize(pairs);
  pair_relative_velocity_.resize(pairs);
  pair_arm_a_.resize(pairs);
  pair_arm_b_.resize(pairs);
  pair_dissipated_power_.resize(pairs);
  pair_slip_release_.resize(pairs);
  pair_history_.resize(pairs);
#pragma omp parallel for schedule(static) if (parallel_)
  for (std::int64_t p = 0; p < static_cast<std::int64_t>(pairs); ++p) {
    const std::uint32_t a = pair_a_[p];
    const std::uint32_t b = pair_b_[p];
    // The springs of a pair already in contact at the last evaluation, or new ones.
    const std::uint64_t key = pair_key(a, b);
    const auto found = std::lower_bound(previous_key_.begin(), previous_key_.end(), key);
    pair_history_[p] = (found != previous_key_.end() && *found == key)
                           ? previous_history_[static_cast<std::size_t>(found - previous_key_.begin())]
                           : PairHistory{};
    const Vec3 separation = position_[a] - position_[b];
    const double distance = separation.norm();
    const Vec3 normal = distance > 0 ? Vec3(separation / distance) : Vec3::UnitZ();  // from b to a
    const double overlap = radius_[a] + radius_[b] - distance;
    // Lever arms from the centres to the contact point, the middle of the overlap.
    const Vec3 arm_a = -(radius_[a] - 0.5 * overlap) * normal;
    const Vec3 arm_b = (radius_[b] - 0.5 * overlap) * normal;
    const Vec3 relative_velocity = (velocity_[a] + spin_[a].cross(arm_a)) - (velocity_[b] + spin_[b].cross(arm_b));
    const physics::ContactForce contact = physics::spring_dashpot_force(
        contact_law(a, b), overlap, normal, relative_velocity, dt_previous, pair_history_[p].tangential);
    const Vec3 relative_spin = spin_[a] - spin_[b];
    physics::RollingTorque rolling;
    if (settings_.rolling_friction > 0) {
      rolling = physics::rolling_spring_torque(rolling_law(a, b), contact.normal_force, relative_spin, dt_previous,
                                               pair_history_[p].rolling);
    }
    pair_force_[p] = contact.force;
    pair_torque_a_[p] = arm_a.cross(contact.force) + rolling.torque;
    pair_torque_b_[p] = arm_b.cross(Vec3(-contact.force)) - rolling.torque;
    pair_relative_spin_[p] = relative_spin;
    pair_elastic_[p] = contact.elastic_energy + rolling.elastic_energy;
    pair_slip_release_[p] = contact.slip_spring_release + rolling.slip_spring_release;
    pair_dissipative_force_[p] = contact.dissipative_force;
    pair_dissipative_torque_[p] = rolling.dissipative_torque;
    pair_relative_velocity_[p] = relative_velocity;
    pair_arm_a_[p] = arm_a;
    pair_arm_b_[p] = arm_b;
  }
  step_elastic_ = step_slip_release_ = 0;
  for (std::size_t p = 0; p < pairs; ++p) {
    step_elastic_ += pair_elastic_[p];
    step_slip_release_ += pair_slip_release_[p];
  }
  // Contacts that opened since the last step take their springs' energy with them.
  step_released_energy_ = 0;
  for (std::size_t q = 0, p = 0; q < previous_key_.size(); ++q) {
    const std::uint64_t key = previous_key_[q];
    while (p < pairs && pair_key(pair_a_[p], pair_b_[p]) < key) ++p;
    if (p < pairs && pair_key(pair_a_[p], pair_b_[p]) == key) continue;
    const auto a = static_cast<std::uint32_t>(key >> 32), b = static_cast<std::uint32_t>(key & 0xffffffffU);
    step_released_energy_ +=
        0.5 * contact_law(a, b).tangential_stiffness * previous_history_[q].tangential.displacement.squaredNorm();
    const double rolling_stiffness = rolling_law(a, b).stiffness;
    if (rolling_stiffness > 0) {
      step_released_energy_ += 0.5 * previous_history_[q].rolling.torque.squaredNorm() / rolling_stiffness;
    }
  }
  previous_key_.resize(pairs);
  for (std::size_t p = 0; p < pairs; ++p) previous_key_[p] = pair_key(pair_a_[p], pair_b_[p]);
  previous_history_.assign(pair_history_.begin(), pair_history_.end());
}

void DemModel::build_adjacency() {
  adjacency_start_.assign(size() + 1, 0);
  for (std::size_t p = 0; p < pair_a_.size(); ++p) {
    ++adjacency_start_[pair_a_[p] + 1];
    ++adjacency_start_[pair_b_[p] + 1];
  }
  for (std::size_t i = 0; i < size(); ++i) adjacency_start_[i + 1] += adjacency_start_[i];
  adjacency_pair_.resize(adjacency_start_.back());
  contact_count_.assign(adjacency_start_.begin(), adjacency_start_.end() - 1);  // reused as cursors
  for (std::size_t p = 0; p < pair_a_.size(); ++p) {
    adjacency_pair_[contact_count_[pair_a_[p]]++] = static_cast<std::uint32_t>(p);
    adjacency_pair_[contact_count_[pair_b_[p]]++] = static_cast<std::uint32_t>(p);
  }
}

void DemModel::compute_internal_forces(double dt_previous) {
  assert(dt_previous >= 0);
  find_contacts();
  compute_pair_forces(dt_previous);
  build_adjacency();
  const auto n = static_cast<std::int64_t>(size());
#pragma omp parallel for schedule(static) if (parallel_)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto i = static_cast<std::uint32_t>(k);
    // Fixed spheres get no gravity: their force is the load the free spheres put on them.
    Vec3 force = fixed_[i] ? Vec3::Zero() : Vec3(mass_[i] * gravity_);
    Vec3 torque = Vec3::Zero();
    for (std::uint32_t slot = adjacency_start_[i]; slot < adjacency_start_[i + 1]; ++slot) {
      const std::uint32_t p = adjacency_pair_[slot];
      if (pair_a_[p] == i) {
        force += pair_force_[p];
        torque += pair_torque_a_[p];
      } else {
        force -= pair_force_[p];
        torque += pair_torque_b_[p];
      }
    }
    force_[i] += force;
    torque_[i] += torque;
  }
  forces_ready_ = true;
}

void DemModel::add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force,
                                   std::span<const double> torque) {
  if (force.size() != 3 * index.size() || (!torque.empty() && torque.size() != 3 * index.size())) {
    throw ProtocolError(
        fmt::format("DEM forces: {} sphere ids but {} force and {} torque values (expected {} each, "
                    "torques optional)",
                    index.size(), force.size(), torque.size(), 3 * index.size()));
  }
  for (std::size_t k = 0; k < index.size(); ++k) {
    const std::uint32_t id = index[k];
    if (id >= size()) {
      throw ProtocolError(
          fmt::format("DEM forces: sphere id {} at position {} does not exist (there are {} spheres)", id, k, size()));
    }
    force_[id] += Vec3(force[3 * k], force[3 * k + 1], force[3 * k + 2]);
    if (!torque.empty()) torque_[id] += Vec3(torque[3 * k], torque[3 * k + 1], torque[3 * k + 2]);
  }
}

void DemModel::integrate(double dt_previous, double dt) {
  assert(forces_ready_ && "compute_internal_forces() must run before integrate()");
  assert(dt > 0 && dt_previous >= 0);
  const bool first_step = dt_previous == 0;
  const double dt_update = first_step ? 0.5 * dt : 0.5 * (dt_previous + dt);

  const auto n = static_cast<std::int64_t>(size());
  const auto pairs = static_cast<std::int64_t>(pair_a_.size());
#pragma omp parallel for schedule(static) if (parallel_)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto i = static_cast<std::uint32_t>(k);
    if (fixed_[i]) {
      sphere_kinetic_[i] = sphere_potential_[i] = 0;
    } else {
      const double inertia = 0.4 * mass_[i] * radius_[i] * radius_[i];
      const Vec3 velocity = velocity_[i] + (dt_update / mass_[i]) * force_[i];
      const Vec3 spin = spin_[i] + (dt_update / inertia) * torque_[i];
      sphere_kinetic_[i] = first_step
                               ? 0.5 * mass_[i] * velocity_[i].squaredNorm() + 0.5 * inertia * spin_[i].squaredNorm()
                               : 0.5 * mass_[i] * velocity_[i].dot(velocity) + 0.5 * inertia * spin_[i].dot(spin);
      sphere_potential_[i] = -mass_[i] * gravity_.dot(position_[i]);
      velocity_[i] = velocity;
      spin_[i] = spin;
      position_[i] += dt * velocity;
    }
    force_[i].setZero();
    torque_[i].setZero();
  }

  // Dissipated energy: the impulse of each dissipative force (and torque) times the
  // mean of the relative velocities before and after it (exact for one body: dKE = J . v_mean).
#pragma omp parallel for schedule(static) if (parallel_)
  for (std::int64_t p = 0; p < pairs; ++p) {
    const std::uint32_t a = pair_a_[p];
    const std::uint32_t b = pair_b_[p];
    const Vec3 relative_velocity =
        (velocity_[a] + spin_[a].cross(pair_arm_a_[p])) - (velocity_[b] + spin_[b].cross(pair_arm_b_[p]));
    const Vec3 relative_spin = spin_[a] - spin_[b];
    pair_dissipated_power_[p] = -0.5 * (pair_dissipative_force_[p].dot(pair_relative_velocity_[p] + relative_velocity) +
                                        pair_dissipative_torque_[p].dot(pair_relative_spin_[p] + relative_spin));
  }
  double dissipated_power = 0;
  for (std::size_t p = 0; p < pair_a_.size(); ++p) dissipated_power += pair_dissipated_power_[p];
  energies_.kinetic = energies_.potential = 0;
  for (std::size_t i = 0; i < size(); ++i) {
    energies_.kinetic += sphere_kinetic_[i];
    energies_.potential += sphere_potential_[i];
  }
  energies_.elastic = step_elastic_;
  energies_.dissipated += dt_update * dissipated_power + step_slip_release_ + step_released_energy_;
  forces_ready_ = false;
}

double DemModel::stable_dt() const {
  double lightest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < size(); ++i) {
    if (!fixed_[i]) lightest = std::min(lightest, mass_[i]);
  }
  if (!std::isfinite(lightest)) return std::numeric_limits<double>::infinity();
  double stiffest = 0;
  if (settings_.normal_stiffness) {
    stiffest = *settings_.normal_stiffness;
  } else {
    // k_n grows with both K r: the stiffest pair joins the two largest K r.
    double largest = 0, second = 0;
    for (std::size_t i = 0; i < size(); ++i) {
      const double value = material_bulk_modulus_[material_[i]] * radius_[i];
      if (value > largest) {
        second = largest;
        largest = value;
      } else if (value > second) {
        second = value;
      }
    }
    if (size() == 1) second = largest;
    stiffest = settings_.normal_stiffness_scale * largest * second / (largest + second);
  }
  // Tangentially the contact point of a sphere moves with inverse mass 1/m + r^2/I = 3.5/m; the
  // rolling spring on a sphere against a much larger one has k_r / I = 5.625 mu_r^2 k_n / m.
  const double mu_r = settings_.rolling_friction;
  stiffest *= std::max({1.0, 3.5 * settings_.tangential_stiffness_ratio, 5.625 * mu_r * mu_r});
  return 0.2 * std::numbers::pi * std::sqrt(lightest / stiffest);
}

Aabb DemModel::bounds() const {
  Aabb box;
  for (std::size_t i = 0; i < size(); ++i) {
    box.extend(Vec3(position_[i].array() - radius_[i]));
    box.extend(Vec3(position_[i].array() + radius_[i]));
  }
  return box;
}

std::vector<ContactRecord> DemModel::contact_histories() const {
  std::vector<ContactRecord> records(previous_key_.size());
  for (std::size_t p = 0; p < records.size(); ++p) {
    records[p] = ContactRecord{static_cast<std::uint32_t>(previous_key_[p] >> 32),
                               static_cast<std::uint32_t>(previous_key_[p] & 0xffffffffU),
                               previous_history_[p].tangential.displacement, previous_history_[p].rolling.torque};
  }
  return records;
}

void DemModel::restore(std::span<const ContactRecord> contacts, double dissipated_energy) {
  std::vector<std::pair<std::uint64_t, PairHistory>> sorted;
  sorted.reserve(contacts.size());
  for (const auto& contact : contacts) {
    if (contact.a >= contact.b || contact.b >= size()) {
      throw FileError(fmt::format("DEM checkpoint: contact ({}, {}) is not a pair of sphere ids a < b < {}", contact.a,
                                  contact.b, size()));
    }
    sorted.emplace_back(pair_key(contact.a, contact.b),
                        PairHistory{{contact.tangential_displacement}, {contact.rolling_torque}});
  }
  std::sort(sorted.begin(), sorted.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  previous_key_.resize(sorted.size());
  previous_history_.resize(sorted.size());
  for (std::size_t p = 0; p < sorted.size(); ++p) {
    previous_key_[p] = sorted[p].first;
    previous_history_[p] = sorted[p].second;
  }
  energies_.dissipated = dissipated_energy;
}

}  // namespace sabo::dem
