#include "coupler/contact/sph_dem_penalty_pair.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "coupler/contact/history_io.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/covering_boxes.hpp"
#include "libsabo/physics/stable_step.hpp"

namespace sabo::coupler {

namespace {

Vec3 vec3_at(const google::protobuf::RepeatedField<double>& field, std::size_t k) {
  const auto i = static_cast<int>(3 * k);
  return {field[i], field[i + 1], field[i + 2]};
}

bool spring_before(const SphDemPenaltyPair::Spring& a, const SphDemPenaltyPair::Spring& b) {
  return a.fluid != b.fluid ? a.fluid < b.fluid : a.sphere < b.sphere;
}

constexpr std::int64_t kParallelThreshold = 512;

}  // namespace

SphDemPenaltyPair::SphDemPenaltyPair(const scene::Scene& scene) : set_count_(scene.particle_sets.size()) {
  for (const auto& fluid : scene.fluids) {
    for (const auto& set : scene.particle_sets) {
      const scene::SphDemContact contact = scene.sph_dem_contact(fluid.name, set.name);
      Law law;
      law.enabled = contact.enabled && contact.model == scene::SphDemContact::Model::penalty;
      law.stiffness = contact.normal_stiffness.value_or(scene.sph_dem_derived_stiffness(fluid));
      law.damping_ratio = contact.normal_damping_ratio;
      law.friction = contact.friction;
      laws_.push_back(law);
    }
  }
}

void SphDemPenaltyPair::start(const Solvers& solvers, Replies& /*replies*/) {
  const SolverView& fluid = solvers.at(Role::sph);
  const SolverView& spheres = solvers.at(Role::dem);
  beta_ = std::min(fluid.beta, spheres.beta);
  const auto& ft = fluid.registration->particles();
  const auto& st = spheres.registration->particles();
  for (const double r : ft.radius()) max_fluid_radius_ = std::max(max_fluid_radius_, r);
  for (int i = 0; i < st.id_size(); ++i) {
    const std::uint32_t set = st.body(i);
    const bool meets_fluid =
        set < set_count_ && std::any_of(ft.body().begin(), ft.body().end(), [&](std::uint32_t b) {
          return static_cast<std::size_t>(b) * set_count_ + set < laws_.size() && law(b, set).enabled;
        });
    if (meets_fluid) max_sphere_radius_ = std::max(max_sphere_radius_, st.radius(i));
  }
}

void SphDemPenaltyPair::compute(const Solvers& solvers, const StepClock& clock) {
  const SolverView& fluid_view = solvers.at(Role::sph);
  const SolverView& sphere_view = solvers.at(Role::dem);
  const sabo::v1::StepState& fluid = *fluid_view.state;
  const sabo::v1::StepState& spheres = *sphere_view.state;
  const auto& ft = fluid_view.registration->particles();
  const auto& st = sphere_view.registration->particles();
  const auto nf = static_cast<std::size_t>(fluid.index_size());
  const auto ns = static_cast<std::size_t>(spheres.index_size());
  const bool spins = spheres.angular_velocity_size() == spheres.position_size();

  sphere_centre_.resize(ns);
  for (std::size_t k = 0; k < ns; ++k) sphere_centre_[k] = vec3_at(spheres.position(), k);
  const double cell = std::max(max_sphere_radius_ + 2 * max_fluid_radius_, 1e-12);
  grid_.build_points(sphere_centre_, cell);

  if (results_.size() < nf) results_.resize(nf);
  const double dt_previous = clock.dt_previous;
  const auto count = static_cast<std::int64_t>(nf);
#pragma omp parallel for schedule(dynamic, 256) if (count > kParallelThreshold)
  for (std::int64_t signed_i = 0; signed_i < count; ++signed_i) {
    const auto i = static_cast<std::size_t>(signed_i);
    ParticleResult& result = results_[i];
    result.contacts.clear();
    result.stable_dt = std::numeric_limits<double>::infinity();
    const int row = static_cast<int>(fluid.index(static_cast<int>(i)));
    const std::uint32_t body = ft.body(row);
    const double r_i = ft.radius(row), m_i = ft.mass(row);
    const std::uint64_t id_i = ft.id(row);
    const Vec3 x_i = vec3_at(fluid.position(), i), v_i = vec3_at(fluid.velocity(), i);
    grid_.for_each_near(x_i, [&](std::uint32_t k) {
      const int srow = static_cast<int>(spheres.index(static_cast<int>(k)));
      const std::uint32_t set = st.body(srow);
      if (set >= set_count_) return;
      const Law& pair = law(body, set);
      if (!pair.enabled) return;
      const double r_j = st.radius(srow), m_j = st.mass(srow);
      const Vec3 offset = x_i - sphere_centre_[k];
      const double d = offset.norm();
      const double reach = r_i + r_j;
      if (d >= reach + r_i) return;
      const double reduced_mass = m_i * m_j / (m_i + m_j);
      result.stable_dt = std::min(result.stable_dt, physics::spring_stable_dt(reduced_mass, pair.stiffness));
      if (d >= reach) return;
      const Vec3 n = d > 0 ? Vec3(offset / d) : Vec3::UnitZ();
      const Vec3 lever = r_j * n;
      const Vec3 w_j = spins ? vec3_at(spheres.angular_velocity(), k) : Vec3::Zero();
      const Vec3 relative_velocity = v_i - (vec3_at(spheres.velocity(), k) + w_j.cross(lever));
      physics::SpringDashpot law{};
      law.normal_stiffness = pair.stiffness;
      law.normal_damping = physics::damping_coefficient(pair.stiffness, reduced_mass, pair.damping_ratio);
      law.tangential_stiffness = pair.friction > 0 ? pair.stiffness : 0.0;
      law.tangential_damping = 0;
      law.friction = pair.friction;
      physics::TangentialHistory history;
      const std::uint64_t id_j = st.id(srow);
      if (pair.friction > 0) {
        const Spring key{id_i, id_j, Vec3::Zero()};
        const auto it = std::lower_bound(springs_.begin(), springs_.end(), key, spring_before);
        if (it != springs_.end() && it->fluid == id_i && it->sphere == id_j) history.displacement = it->displacement;
      }
      const physics::ContactForce f =
          physics::spring_dashpot_force(law, reach - d, n, relative_velocity, dt_previous, history);
      Contact contact;
      contact.sphere = k;
      contact.force = f.force;
      contact.lever = lever;
      contact.elastic = f.elastic_energy;
      contact.dissipated_power = -f.dissipative_force.dot(relative_velocity);
      contact.has_spring = pair.friction > 0;
      contact.tangential = history.displacement;
      result.contacts.push_back(contact);
    });
  }

  // Sums in particle order.
  fluid_force_.assign(3 * nf, 0.0);
  sphere_force_.assign(3 * ns, 0.0);
  sphere_torque_.assign(3 * ns, 0.0);
  balance_ = {};
  elastic_ = dissipated_power_ = 0;
  contacts_ = 0;
  double stable = std::numeric_limits<double>::infinity();
  next_springs_.clear();
  for (std::size_t i = 0; i < nf; ++i) {
    const ParticleResult& result = results_[i];
    stable = std::min(stable, result.stable_dt);
    const std::uint64_t id_i = ft.id(static_cast<int>(fluid.index(static_cast<int>(i))));
    for (const Contact& c : result.contacts) {
      const Vec3 torque = c.lever.cross(-c.force);
      for (int a = 0; a < 3; ++a) {
        fluid_force_[3 * i + static_cast<std::size_t>(a)] += c.force[a];
        sphere_force_[3 * c.sphere + static_cast<std::size_t>(a)] -= c.force[a];
        sphere_torque_[3 * c.sphere + static_cast<std::size_t>(a)] += torque[a];
      }
      balance_.scale += std::abs(c.force.x()) + std::abs(c.force.y()) + std::abs(c.force.z());
      elastic_ += c.elastic;
      dissipated_power_ += c.dissipated_power;
      ++contacts_;
      if (c.has_spring) {
        next_springs_.push_back(
            {id_i, st.id(static_cast<int>(spheres.index(static_cast<int>(c.sphere)))), c.tangential});
      }
    }
  }
  for (std::size_t i = 0; i + 2 < fluid_force_.size(); i += 3) {
    balance_.sum += Vec3(fluid_force_[i], fluid_force_[i + 1], fluid_force_[i + 2]);
  }
  for (std::size_t k = 0; k + 2 < sphere_force_.size(); k += 3) {
    balance_.sum += Vec3(sphere_force_[k], sphere_force_[k + 1], sphere_force_[k + 2]);
  }
  std::sort(next_springs_.begin(), next_springs_.end(), spring_before);
  springs_.swap(next_springs_);
  max_contacts_ = std::max(max_contacts_, contacts_);
  stable_dt_ = beta_ * stable;
}

void SphDemPenaltyPair::scatter(const Solvers& solvers, double /*dt*/, Replies& replies) {
  if (contacts_ == 0) return;
  replies.add_particle_forces(Role::sph, fluid_force_, {});
  const bool torque = solvers.at(Role::dem).registration->exposes_angular_velocity();
  replies.add_particle_forces(Role::dem, sphere_force_,
                              torque ? std::span<const double>(sphere_torque_) : std::span<const double>());
}

InterestRequest SphDemPenaltyPair::interest(Role role) const {
  if (role == Role::dem) return {.all = true, .boxes = {}};
  // Fluid particles within reach of the stable-step search at the next step: one sphere radius of
  // motion on top.
  std::vector<Aabb> boxes = geometry::covering_boxes(sphere_centre_, geometry::kMaxInterestBoxes);
  for (Aabb& box : boxes) box = box.inflated(2 * max_sphere_radius_ + 2 * max_fluid_radius_);
  return {.all = false, .boxes = std::move(boxes)};
}

nlohmann::json SphDemPenaltyPair::effect() const {
  return {{"effect", "sph_dem_penalty_contact"}, {"process", "coupler"}, {"max_simultaneous_contacts", max_contacts_}};
}

void SphDemPenaltyPair::save_history(io::hdf5::Group& group) const {
  std::vector<std::uint64_t> fluid, sphere;
  std::vector<double> displacement;
  for (const Spring& s : springs_) {
    fluid.push_back(s.fluid);
    sphere.push_back(s.sphere);
    displacement.insert(displacement.end(), {s.displacement.x(), s.displacement.y(), s.displacement.z()});
  }
  group.set_attribute("pair", std::string("sph_dem_penalty"));
  group.set_attribute("max_simultaneous_contacts", static_cast<std::int64_t>(max_contacts_));
  write_array(group, "spring_fluid", fluid);
  write_array(group, "spring_sphere", sphere);
  write_array(group, "spring_displacement", displacement);
}

void SphDemPenaltyPair::restore_history(const io::hdf5::Group& group) {
  if (group.string_attribute("pair") != "sph_dem_penalty") {
    throw FileError(fmt::format("{}: holds the history of the {} pair, not of the SPH-DEM penalty", group.path(),
                                group.string_attribute("pair")));
  }
  const auto fluid = read_array<std::uint64_t>(group, "spring_fluid");
  const auto sphere = read_array<std::uint64_t>(group, "spring_sphere");
  const auto displacement = read_array<double>(group, "spring_displacement");
  if (sphere.size() != fluid.size() || displacement.size() != 3 * fluid.size()) {
    throw FileError(fmt::format("{}: the spring arrays differ in length", group.path()));
  }
  std::vector<Spring> springs;
  for (std::size_t k = 0; k < fluid.size(); ++k) {
    springs.push_back(
        {fluid[k], sphere[k], Vec3(displacement[3 * k], displacement[3 * k + 1], displacement[3 * k + 2])});
  }
  if (!std::is_sorted(springs.begin(), springs.end(), spring_before)) {
    throw FileError(fmt::format("{}: the springs are not sorted by (fluid, sphere)", group.path()));
  }
  springs_ = std::move(springs);
  max_contacts_ = static_cast<std::size_t>(group.int_attribute("max_simultaneous_contacts"));
}

}  // namespace sabo::coupler
