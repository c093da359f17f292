// The DEM model (dem_model.hpp): the spheres' arrays sorted by cell, the pair-law table, walls, the
// neighbour lists, the contact loop, integration, the stable step and the contact histories. Over 800
// lines as one concept: every pass reads and writes the same cell-sorted arrays; the contact laws
// themselves are libsabo/physics'.
#include "dem_solver/dem_model.hpp"

#include <fmt/format.h>
#include <omp.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

#include "libsabo/core/error.hpp"
#include "libsabo/core/isa.hpp"
#include "libsabo/geometry/sphere_fill.hpp"
#include "libsabo/physics/stable_step.hpp"

namespace sabo::dem {
namespace {

std::uint64_t pair_key(std::uint32_t a, std::uint32_t b) {
  return (std::uint64_t{a} << 32) | b;
}

std::string origin_text(const scene::ParticleSet& set) {
  return fmt::format("{}:{}: particle set '{}'", set.origin.file.string(), set.origin.line, set.name);
}

// The Hertz-Mindlin constants of a pair law for bodies of (E, nu) a and b: E*, G* and sqrt(4 G* / E*).
void set_elastic_constants(DemModel::PairLaw& law, double youngs_a, double poisson_a, double youngs_b,
                           double poisson_b) {
  law.effective_modulus = physics::hertz_effective_modulus(youngs_a, poisson_a, youngs_b, poisson_b);
  law.effective_shear_modulus = physics::mindlin_effective_shear_modulus(youngs_a, poisson_a, youngs_b, poisson_b);
  law.stiffness_ratio_root = std::sqrt(4.0 * law.effective_shear_modulus / law.effective_modulus);
}

// Distance from x to a wall (m) and the wall's unit normal towards x there.
double wall_distance(const Wall& wall, const Vec3& x, Vec3& normal) {
  if (wall.kind == Wall::Kind::plane) {
    normal = wall.normal;
    return (x - wall.point).dot(normal);
  }
  const double ex = wall.b[0] - wall.a[0], ez = wall.b[1] - wall.a[1];
  const double length_squared = ex * ex + ez * ez;
  double t = length_squared > 0 ? ((x.x() - wall.a[0]) * ex + (x.z() - wall.a[1]) * ez) / length_squared : 0;
  t = std::clamp(t, 0.0, 1.0);
  const Vec3 offset(x.x() - (wall.a[0] + t * ex), 0.0, x.z() - (wall.a[1] + t * ez));
  const double distance = offset.norm();
  normal = distance > 0 ? Vec3(offset / distance) : Vec3::UnitZ();
  return distance;
}

// What one contact needs besides its law: geometry and the pair's effective inertia.
struct ContactInput {
  Vec3 normal;               // unit, from b to a
  double overlap;            // m, > 0
  Vec3 relative_velocity;    // of the contact points, a minus b, m/s
  Vec3 relative_spin;        // w_a - w_b, rad/s
  double effective_radius;   // m
  double effective_mass;     // kg
  double effective_inertia;  // kg m^2 (0: both fixed)
  double linear_stiffness;   // N/m, the linear law's k_n
  double tangential_ratio;   // k_t / k_n, linear
};

struct ContactOutput {
  Vec3 force;               // on a, N
  Vec3 rolling_torque;      // on a, N m
  Vec3 dissipative_force;   // on a, N
  Vec3 dissipative_torque;  // rolling part, on a, N m
  double elastic;           // J, springs after this evaluation (normal included)
  double spring_energy;     // J, tangential + rolling springs after this evaluation
  double slip_release;      // J
};

// The linear law (physics::spring_dashpot_force) or Hertz-Mindlin (physics::hertz_mindlin_force), then the
// rolling resistance (physics::rolling_spring_torque, or the viscous torque): the normal part with the law's
// constants precomputed, the tangential and the rolling springs physics' own inline functions. kLaw: 0 linear, 1 hertz,
// 2 from law.hertz. kRolling: 0 none, 1 constant, 2 viscous, 3 from law.rolling.
template <int kLaw, int kRolling>
[[gnu::always_inline]] inline ContactOutput contact(const DemModel::PairLaw& law, const ContactInput& in,
                                                    double dt_previous, Vec3& tangential, Vec3& rolling_history) {
  const bool hertz = kLaw == 2 ? law.hertz : kLaw == 1;
  const Vec3& n = in.normal;
  const double normal_speed = in.relative_velocity.dot(n);
  const Vec3 tangential_velocity = in.relative_velocity - normal_speed * n;
  double normal_stiffness, tangential_stiffness, normal_damping, tangential_damping, elastic_normal_force;
  double normal_elastic_energy;
  if (hertz) {
    const double root = std::sqrt(in.effective_radius * in.overlap);
    normal_stiffness = 2.0 * law.effective_modulus * root;
    tangential_stiffness = 8.0 * law.effective_shear_modulus * root;
    normal_damping = law.damping * std::sqrt(normal_stiffness * in.effective_mass);
    tangential_damping = normal_damping * law.stiffness_ratio_root;  // sqrt(S_t / S_n) = sqrt(4 G* / E*)
    elastic_normal_force = (2.0 / 3.0) * normal_stiffness * in.overlap;
    normal_elastic_energy = 0.4 * elastic_normal_force * in.overlap;
  } else {
    normal_stiffness = in.linear_stiffness;
    tangential_stiffness = in.tangential_ratio * normal_stiffness;
    normal_damping = physics::damping_coefficient(normal_stiffness, in.effective_mass, law.normal_damping_ratio);
    tangential_damping =
        physics::damping_coefficient(tangential_stiffness, in.effective_mass, law.tangential_damping_ratio);
    elastic_normal_force = normal_stiffness * in.overlap;
    normal_elastic_energy = 0.5 * elastic_normal_force * in.overlap;
  }
  const double normal_force = elastic_normal_force - normal_damping * normal_speed;

  const physics::TangentialForce tangential_part =
      physics::tangential_spring_force(tangential_stiffness, tangential_damping, law.friction, normal_force, n,
                                       tangential_velocity, dt_previous, tangential);
  ContactOutput out;
  out.slip_release = tangential_part.slip_spring_release;
  out.dissipative_force = -normal_damping * normal_speed * n + tangential_part.dissipative;
  out.force = normal_force * n + tangential_part.force;
  out.spring_energy = 0.5 * tangential_stiffness * tangential.squaredNorm();

  out.rolling_torque.setZero();
  out.dissipative_torque.setZero();
  const int rolling = kRolling == 3 ? law.rolling : kRolling;
  if (rolling == 1) {
    const double rolling_stiffness =
        physics::rolling_stiffness(normal_stiffness, law.rolling_friction, in.effective_radius);
    const physics::RollingSpring rolling_law{
        .stiffness = rolling_stiffness,
        .damping = physics::damping_coefficient(rolling_stiffness, in.effective_inertia, law.rolling_damping_ratio),
        .friction = law.rolling_friction,
        .effective_radius = in.effective_radius};
    const physics::RollingTorque rolling_part =
        physics::rolling_spring_torque(rolling_law, normal_force, in.relative_spin, dt_previous, rolling_history);
    out.rolling_torque = rolling_part.torque;
    out.dissipative_torque = rolling_part.dissipative_torque;
    out.slip_release += rolling_part.slip_spring_release;
    out.spring_energy += rolling_part.elastic_energy;
  } else if (rolling == 2) {
    out.rolling_torque =
        (-law.rolling_viscosity * in.effective_radius * in.effective_radius * std::max(normal_force, 0.0)) *
        in.relative_spin;
    out.dissipative_torque = out.rolling_torque;
  }
  out.elastic = normal_elastic_energy + out.spring_energy;
  return out;
}

}  // namespace

DemModel::DemModel(const scene::Scene& scene) : settings_(scene.dem_contact), gravity_(scene.run.gravity) {
  for (const auto& material : scene.materials) {
    material_names_.push_back(material.name);
    material_bulk_modulus_.push_back(material.bulk_modulus());
    material_youngs_.push_back(material.youngs_modulus);
    material_poisson_.push_back(material.poisson_ratio);
  }
  build_law_table(scene);

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
      filled = geometry::fill_region(set, obstacles);
      if (set.settle_time > 0) settle(scene, set, filled, obstacles);
      sort_by_cell(filled);
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
  inverse_mass_.resize(size());
  inverse_inertia_.resize(size());
  stiffness_term_.resize(size());
  for (std::uint32_t i = 0; i < size(); ++i) {
    update_inverse_mass(i);
    stiffness_term_[i] = material_bulk_modulus_[material_[i]] * radius_[i];
  }
  skin_ = kSkinFraction * largest_radius_;

  // Spheres of different sets must not start overlapping (fill sets avoid the others by construction;
  // settled sets rest on each other and on the obstacles with the overlaps of their contacts).
  if (size() > 0) {
    std::vector<std::uint8_t> settled(size(), 0);
    for (std::uint32_t i = 0; i < size(); ++i) settled[i] = scene.particle_sets[body_[i]].settle_time > 0 ? 1 : 0;
    cells_.build_points(position_, 2 * largest_radius_);
    for (std::uint32_t i = 0; i < size(); ++i) {
      cells_.for_each_near(position_[i], [&](std::uint32_t j) {
        if (j <= i || settled[i] || settled[j]) return;
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

  // Summed in the blocks and order of integrate(), so that a first step without motion gives the same bits.
  for (std::size_t first = 0; first < size(); first += kSumBlock) {
    BlockSums sums;
    for (std::size_t i = first; i < std::min(size(), first + kSumBlock); ++i) {
      const double inertia = 0.4 * mass_[i] * radius_[i] * radius_[i];
      sums.kinetic += 0.5 * mass_[i] * velocity_[i].squaredNorm() + 0.5 * inertia * spin_[i].squaredNorm();
      sums.potential -= mass_[i] * gravity_.dot(position_[i]);
    }
    energies_.kinetic += sums.kinetic;
    energies_.potential += sums.potential;
  }
  for (auto* values : {&sphere_elastic_, &sphere_released_}) values->assign(size(), 0);
  dissipative_force_.assign(size(), Vec3::Zero());
  dissipative_torque_.assign(size(), Vec3::Zero());
  sphere_contacts_.assign(size(), 0);
  sphere_wall_contacts_.assign(size(), 0);
  for (std::uint32_t i = 0; i < size(); ++i) {
    if (scene.particle_sets[body_[i]].fixed) set_fixed(i, true);
  }
}

void DemModel::sort_by_cell(std::vector<scene::Sphere>& spheres) {
  if (spheres.size() < 2) return;
  double largest = 0;
  Vec3 low = spheres.front().center;
  for (const auto& sphere : spheres) {
    largest = std::max(largest, sphere.radius);
    low = low.cwiseMin(sphere.center);
  }
  const double cell = 2 * largest;
  auto key = [&](const scene::Sphere& sphere) {
    const Vec3 c = ((sphere.center - low) / cell).array().floor();
    return std::array<double, 3>{c.z(), c.y(), c.x()};
  };
  std::stable_sort(spheres.begin(), spheres.end(),
                   [&](const scene::Sphere& x, const scene::Sphere& y) { return key(x) < key(y); });
}

void DemModel::build_law_table(const scene::Scene& scene) {
  material_count_ = scene.materials.size();
  pair_law_.resize(material_count_ * material_count_);
  bool any_linear = false, any_hertz = false;
  bool any_none = false, any_constant = false, any_viscous = false;
  for (std::size_t a = 0; a < material_count_; ++a) {
    for (std::size_t b = 0; b < material_count_; ++b) {
      const scene::DemContactLaw& source = settings_.law(material_names_[a], material_names_[b]);
      PairLaw& law = pair_law_[a * material_count_ + b];
      law.hertz = source.model == scene::DemLaw::hertz_mindlin;
      law.friction = source.friction;
      law.normal_damping_ratio = source.normal_damping_ratio;
      law.tangential_damping_ratio = source.tangential_damping_ratio;
      const auto& ma = scene.materials[a];
      const auto& mb = scene.materials[b];
      set_elastic_constants(law, ma.youngs_modulus, ma.poisson_ratio, mb.youngs_modulus, mb.poisson_ratio);
      law.damping = physics::hertz_damping_factor(source.restitution);
      law.rolling = !source.has_rolling() ? 0 : source.rolling == scene::RollingModel::constant ? 1 : 2;
      law.rolling_friction = source.rolling_friction;
      law.rolling_viscosity = source.rolling_viscosity;
      law.rolling_damping_ratio =
          law.hertz ? -physics::restitution_damping_ratio(source.restitution) : source.tangential_damping_ratio;
      any_linear = any_linear || !law.hertz;
      any_hertz = any_hertz || law.hertz;
      any_none = any_none || law.rolling == 0;
      any_constant = any_constant || law.rolling == 1;
      any_viscous = any_viscous || law.rolling == 2;
    }
  }
  law_kind_ = any_linear && any_hertz ? 2 : any_hertz ? 1 : 0;
  const int rolling_models = int{any_none} + int{any_constant} + int{any_viscous};
  rolling_kind_ = rolling_models > 1 ? 3 : any_constant ? 1 : any_viscous ? 2 : 0;
}

void DemModel::settle(const scene::Scene& scene, const scene::ParticleSet& set, std::vector<scene::Sphere>& spheres,
                      std::span<const scene::Sphere> obstacles) {
  // A model of this set alone, with the obstacles that reach into its region as fixed spheres.
  scene::Scene local = scene;
  local.particle_sets.clear();
  scene::ParticleSet moving = set;
  moving.kind = scene::ParticleSet::Kind::list;
  moving.spheres = spheres;
  moving.settle_time = 0;
  for (auto& sphere : moving.spheres) sphere.velocity.setZero();
  local.particle_sets.push_back(moving);
  scene::ParticleSet fixed = set;
  fixed.kind = scene::ParticleSet::Kind::list;
  fixed.name = set.name + "-obstacles";
  fixed.spheres.clear();
  for (const auto& sphere : obstacles) {
    const Vec3 low = set.region.min.array() - sphere.radius, high = set.region.max.array() + sphere.radius;
    if ((sphere.center.array() >= low.array()).all() && (sphere.center.array() <= high.array()).all()) {
      fixed.spheres.push_back(sphere);
    }
  }
  if (!fixed.spheres.empty()) local.particle_sets.push_back(fixed);
  DemModel model(local);
  for (std::size_t k = spheres.size(); k < model.size(); ++k) model.set_fixed(static_cast<std::uint32_t>(k), true);
  model.add_region_walls(set);
  // Half the stable step (which is already a tenth of a contact period, or a fifth of the Rayleigh time).
  const double dt = 0.5 * model.stable_dt();
  const auto steps = static_cast<std::int64_t>(std::ceil(set.settle_time / dt));
  double dt_previous = 0;
  for (std::int64_t n = 0; n < steps; ++n) {
    model.compute_internal_forces(dt_previous);
    model.integrate(dt_previous, dt);
    dt_previous = dt;
  }
  for (std::size_t k = 0; k < spheres.size(); ++k) {
    spheres[k].center = model.positions()[k];
    spheres[k].velocity = set.velocity;
    spheres[k].angular_velocity.setZero();
    if (!set.contains_sphere(spheres[k].center, 0.5 * spheres[k].radius)) {
      throw SceneError(fmt::format(
          "{}: after settling for {:g} s a sphere of radius {:g} m lies at ({:g}, {:g}, {:g}), outside the region: "
          "the settling did not stay bounded. Fix: give a longer-lived stable scene (smaller spheres' speeds), or "
          "report this as a bug.",
          origin_text(set), set.settle_time, spheres[k].radius, spheres[k].center.x(), spheres[k].center.y(),
          spheres[k].center.z()));
    }
  }
}

void DemModel::update_inverse_mass(std::uint32_t id) {
  inverse_mass_[id] = fixed_[id] ? 0.0 : 1.0 / mass_[id];
  inverse_inertia_[id] = fixed_[id] ? 0.0 : 1.0 / (0.4 * mass_[id] * radius_[id] * radius_[id]);
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
  if ((fixed_[id] != 0) != fixed) rebuild_ = true;  // pairs of two fixed spheres are left out of the list
  fixed_[id] = fixed ? 1 : 0;
  stable_dt_.reset();
  update_inverse_mass(id);
}

const scene::DemContactLaw& DemModel::law(std::uint32_t a, std::uint32_t b) const {
  return settings_.law(material_names_[material_[a]], material_names_[material_[b]]);
}

double DemModel::normal_stiffness(std::uint32_t a, std::uint32_t b) const {
  if (settings_.normal_stiffness) return *settings_.normal_stiffness;
  const double stiffness_a = stiffness_term_[a];
  const double stiffness_b = stiffness_term_[b];
  return settings_.normal_stiffness_scale * stiffness_a * stiffness_b / (stiffness_a + stiffness_b);
}

physics::SpringDashpot DemModel::contact_law(std::uint32_t a, std::uint32_t b) const {
  const PairLaw& pair = pair_law_[material_[a] * material_count_ + material_[b]];
  const double normal = normal_stiffness(a, b);
  const double tangential = settings_.tangential_stiffness_ratio * normal;
  const double inverse_mass_sum = inverse_mass_[a] + inverse_mass_[b];
  const double effective_mass = inverse_mass_sum > 0 ? 1.0 / inverse_mass_sum : 0.0;
  return physics::SpringDashpot{
      .normal_stiffness = normal,
      .normal_damping = physics::damping_coefficient(normal, effective_mass, pair.normal_damping_ratio),
      .tangential_stiffness = tangential,
      .tangential_damping = physics::damping_coefficient(tangential, effective_mass, pair.tangential_damping_ratio),
      .friction = pair.friction,
  };
}

physics::RollingSpring DemModel::rolling_law(std::uint32_t a, std::uint32_t b) const {
  const PairLaw& pair = pair_law_[material_[a] * material_count_ + material_[b]];
  const double effective_radius = radius_[a] * radius_[b] / (radius_[a] + radius_[b]);
  const double stiffness = physics::rolling_stiffness(normal_stiffness(a, b), pair.rolling_friction, effective_radius);
  const double inverse_inertia_sum = inverse_inertia_[a] + inverse_inertia_[b];
  const double effective_inertia = inverse_inertia_sum > 0 ? 1.0 / inverse_inertia_sum : 0.0;
  return physics::RollingSpring{
      .stiffness = stiffness,
      .damping = physics::damping_coefficient(stiffness, effective_inertia, pair.rolling_damping_ratio),
      .friction = pair.rolling_friction,
      .effective_radius = effective_radius,
  };
}

physics::HertzMindlin DemModel::hertz_law(std::uint32_t a, std::uint32_t b) const {
  const PairLaw& pair = pair_law_[material_[a] * material_count_ + material_[b]];
  const double inverse_mass_sum = inverse_mass_[a] + inverse_mass_[b];
  return physics::HertzMindlin{
      .effective_modulus = pair.effective_modulus,
      .effective_radius = radius_[a] * radius_[b] / (radius_[a] + radius_[b]),
      .effective_mass = inverse_mass_sum > 0 ? 1.0 / inverse_mass_sum : 0.0,
      .effective_shear_modulus = pair.effective_shear_modulus,
      .restitution = law(a, b).restitution,
      .friction = pair.friction,
  };
}

void DemModel::add_wall(const Wall& wall) {
  walls_.push_back(wall);
  rebuild_ = true;  // the walls near each sphere are listed with the neighbours
  for (std::size_t m = 0; m < material_count_; ++m) {
    PairLaw law = pair_law_[m * material_count_ + m];
    if (wall.youngs_modulus > 0) {
      set_elastic_constants(law, material_youngs_[m], material_poisson_[m], wall.youngs_modulus, wall.poisson_ratio);
    }
    wall_law_.push_back(law);
  }
  const std::size_t slots = size() * walls_.size();
  // Re-lay the per-sphere histories for the new wall count.
  std::vector<Vec3> tangential(slots, Vec3::Zero()), rolling(slots, Vec3::Zero());
  std::vector<std::uint8_t> in_contact(slots, 0);
  std::vector<double> energy(slots, 0);
  const std::size_t old_walls = walls_.size() - 1;
  for (std::size_t i = 0; i < size(); ++i) {
    for (std::size_t w = 0; w < old_walls; ++w) {
      tangential[i * walls_.size() + w] = wall_tangential_[i * old_walls + w];
      rolling[i * walls_.size() + w] = wall_rolling_[i * old_walls + w];
      in_contact[i * walls_.size() + w] = wall_in_contact_[i * old_walls + w];
      energy[i * walls_.size() + w] = wall_spring_energy_[i * old_walls + w];
    }
  }
  wall_tangential_ = std::move(tangential);
  wall_rolling_ = std::move(rolling);
  wall_in_contact_ = std::move(in_contact);
  wall_spring_energy_ = std::move(energy);
}

void DemModel::add_region_walls(const scene::ParticleSet& set) {
  const Aabb& box = set.region;
  if (set.polygon_xz.empty()) {
    for (int axis = 0; axis < 3; ++axis) {
      Wall low, high;
      low.point = box.min;
      low.normal = Vec3::Unit(axis);
      high.point = box.max;
      high.normal = -Vec3::Unit(axis);
      add_wall(low);
      add_wall(high);
    }
    return;
  }
  for (std::size_t k = 0; k < set.polygon_xz.size(); ++k) {
    Wall edge;
    edge.kind = Wall::Kind::segment_xz;
    edge.a = set.polygon_xz[k];
    edge.b = set.polygon_xz[(k + 1) % set.polygon_xz.size()];
    add_wall(edge);
  }
  Wall low, high;
  low.point = box.min;
  low.normal = Vec3::UnitY();
  high.point = box.max;
  high.normal = -Vec3::UnitY();
  add_wall(low);
  add_wall(high);
}

void DemModel::clear_walls() {
  walls_.clear();
  rebuild_ = true;
  wall_law_.clear();
  wall_tangential_.clear();
  wall_rolling_.clear();
  wall_in_contact_.clear();
  wall_spring_energy_.clear();
}

void DemModel::build_neighbours() {
  const auto n = static_cast<std::int64_t>(size());
  ++neighbour_builds_;
  rebuild_ = false;
  build_position_.assign(position_.begin(), position_.end());
  largest_displacement_squared_ = 0;
  displacement_known_ = true;
  std::vector<std::uint32_t> old_start = std::move(start_), old_neighbour = std::move(neighbour_);
  std::vector<Vec3> old_tangential = std::move(tangential_), old_rolling = std::move(rolling_);
  std::vector<std::uint8_t> old_in_contact = std::move(in_contact_);
  std::vector<double> old_energy = std::move(spring_energy_);
  start_.assign(size() + 1, 0);
  count_scratch_.assign(size(), 0);
  cells_.build_points(position_, 2 * largest_radius_ + skin_);
  auto near = [this](std::uint32_t i, std::uint32_t j) {
    if (j <= i || (fixed_[i] && fixed_[j])) return false;
    const double reach = radius_[i] + radius_[j] + skin_;
    return (position_[i] - position_[j]).squaredNorm() < reach * reach;
  };
  const bool from_pending = !pending_.empty();
  thread_neighbours_.resize(static_cast<std::size_t>(parallel_ ? omp_get_max_threads() : 1));
  // One search per sphere: each thread lists the neighbours of a contiguous range of spheres, then copies
  // them to their place once the counts are summed.
#pragma omp parallel if (parallel_)
  {
    const auto thread = static_cast<std::int64_t>(omp_get_thread_num());
    const auto threads = static_cast<std::int64_t>(omp_get_num_threads());
    const std::int64_t first = n * thread / threads, last = n * (thread + 1) / threads;
    std::vector<std::uint32_t>& local = thread_neighbours_[static_cast<std::size_t>(thread)];
    local.clear();
    for (std::int64_t k = first; k < last; ++k) {
      const auto i = static_cast<std::uint32_t>(k);
      const std::size_t begin = local.size();
      cells_.for_each_near(position_[i], [&](std::uint32_t j) {
        if (near(i, j)) local.push_back(j);
      });
      std::sort(local.begin() + static_cast<std::ptrdiff_t>(begin), local.end());
      count_scratch_[i] = static_cast<std::uint32_t>(local.size() - begin);
    }
#pragma omp barrier
#pragma omp single
    {
      for (std::size_t i = 0; i < size(); ++i) start_[i + 1] = start_[i] + count_scratch_[i];
      const std::size_t slots = start_.back();
      neighbour_.resize(slots);
      tangential_.assign(slots, Vec3::Zero());
      rolling_.assign(slots, Vec3::Zero());
      in_contact_.assign(slots, 0);
      spring_energy_.assign(slots, 0);
    }
    std::copy(local.begin(), local.end(), neighbour_.begin() + start_[static_cast<std::size_t>(first)]);
    // Carry the histories over: both lists are sorted by neighbour. A contact dropped from the list
    // (its spheres moved apart by more than the skin at once) releases its springs.
    for (std::int64_t k = first; k < last && !from_pending && !old_start.empty(); ++k) {
      const auto i = static_cast<std::uint32_t>(k);
      double released = 0;
      std::uint32_t s = start_[i];
      for (std::uint32_t old = old_start[i]; old < old_start[i + 1]; ++old) {
        if (!old_in_contact[old]) continue;
        while (s < start_[i + 1] && neighbour_[s] < old_neighbour[old]) ++s;
        if (s < start_[i + 1] && neighbour_[s] == old_neighbour[old]) {
          tangential_[s] = old_tangential[old];
          rolling_[s] = old_rolling[old];
          in_contact_[s] = 1;
          spring_energy_[s] = old_energy[old];
        } else {
          released += old_energy[old];
        }
      }
      sphere_released_[i] += released;
    }
  }
  if (from_pending) {
    for (const auto& [key, record] : pending_) {
      const auto a = static_cast<std::uint32_t>(key >> 32), b = static_cast<std::uint32_t>(key & 0xffffffffU);
      const auto first = neighbour_.begin() + start_[a], last = neighbour_.begin() + start_[a + 1];
      const auto found = std::lower_bound(first, last, b);
      if (found == last || *found != b) {
        dropped_released_ += record.spring_energy;  // no longer near: the contact opened
        continue;
      }
      const auto s = static_cast<std::size_t>(found - neighbour_.begin());
      tangential_[s] = record.tangential_displacement;
      rolling_[s] = record.rolling_torque;
      in_contact_[s] = 1;
      spring_energy_[s] = record.spring_energy;
    }
    pending_.clear();
  }

  // Reverse list, in slot order: where each slot's reaction goes.
  const std::size_t slots = start_.back();
  reverse_start_.assign(size() + 1, 0);
  for (std::size_t s = 0; s < slots; ++s) ++reverse_start_[neighbour_[s] + 1];
  for (std::size_t i = 0; i < size(); ++i) reverse_start_[i + 1] += reverse_start_[i];
  reaction_index_.resize(slots);
  count_scratch_.assign(reverse_start_.begin(), reverse_start_.end() - 1);
  for (std::size_t s = 0; s < slots; ++s) reaction_index_[s] = count_scratch_[neighbour_[s]]++;
  reaction_.assign(slots, Reaction{});
  rolling_reaction_.assign(rolling_kind_ != 0 ? slots : 0, RollingReaction{});

  // Walls within reach: a sphere farther than r + skin from a wall at the build moves more than skin / 2
  // (and so triggers a rebuild) before it touches it. A wall in contact since the last build is within r + skin / 2.
  wall_near_start_.assign(size() + 1, 0);
  wall_near_.clear();
  for (std::uint32_t i = 0; i < size(); ++i) {
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      Vec3 normal;
      if (wall_distance(walls_[w], position_[i], normal) < radius_[i] + skin_) {
        wall_near_.push_back(static_cast<std::uint32_t>(w));
      } else {
        assert(!wall_in_contact_[i * walls_.size() + w]);
      }
    }
    wall_near_start_[i + 1] = static_cast<std::uint32_t>(wall_near_.size());
  }
}

// The calling thread's spheres in a parallel region: contiguous, each thread's with as many list slots
// (`slot_start`: a sphere's first slot, then the total) as the others. Each thread keeps its part of the bed, as a
// rank of a domain decomposition does, and the bed's denser parts are shared out by their pairs.
std::pair<std::int64_t, std::int64_t> DemModel::thread_spheres(const std::vector<std::uint32_t>& slot_start) {
  assert(!slot_start.empty());
  const auto thread = static_cast<std::size_t>(omp_get_thread_num());
  const auto threads = static_cast<std::size_t>(omp_get_num_threads());
  const auto spheres = static_cast<std::int64_t>(slot_start.size() - 1);
  auto sphere_at = [&](std::size_t part) {
    const auto slot = static_cast<std::uint32_t>(std::uint64_t{slot_start.back()} * part / threads);
    return static_cast<std::int64_t>(std::lower_bound(slot_start.begin(), slot_start.end() - 1, slot) -
                                     slot_start.begin());
  };
  return {thread == 0 ? 0 : sphere_at(thread), thread + 1 == threads ? spheres : sphere_at(thread + 1)};
}

template <int kLaw, int kRolling>
void DemModel::pair_forces(double dt_previous) {
  const std::size_t wall_count = walls_.size();
  const double linear_stiffness = settings_.normal_stiffness.value_or(0);
  const bool explicit_stiffness = settings_.normal_stiffness.has_value();
  const double scale = settings_.normal_stiffness_scale;
  const double tangential_ratio = settings_.tangential_stiffness_ratio;
  // Each thread's spheres (thread_spheres) run by the copy of the loop compiled for the CPU's best
  // instruction set (libsabo/core/isa.hpp): about 1.17 times faster with FMA. Split by list slots: the
  // contacts per sphere differ across a bed (its floor, its surface), and a split by spheres left one thread
  // waiting (30 000 settled spheres on 2 threads: 1.35x); chunks of 64 spheres handed out dynamically mended
  // that, but each thread then touched the whole bed (1.20x slower than the split by slots; bench/RESULTS.md,
  // "DEM: each thread its part of the bed"). Each sphere's sums do not depend on which thread runs it: the same
  // bits.
#pragma omp parallel if (parallel_)
  {
    const auto [first, last] = thread_spheres(start_);
    with_best_isa([&] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto a = static_cast<std::uint32_t>(k);
        const Vec3 xa = position_[a], va = velocity_[a], wa = spin_[a];
        const double ra = radius_[a];
        const PairLaw* laws = &pair_law_[material_[a] * material_count_];
        Vec3 force = Vec3::Zero(), torque = Vec3::Zero(), dissipative_force = Vec3::Zero(),
             dissipative_torque = Vec3::Zero();
        double elastic = 0, released = 0;
        std::uint32_t contacts = 0;
        for (std::uint32_t s = start_[a]; s < start_[a + 1]; ++s) {
          const std::uint32_t b = neighbour_[s];
          const Vec3 separation = xa - position_[b];
          const double reach = ra + radius_[b];
          const double distance_squared = separation.squaredNorm();
          if (distance_squared >= reach * reach) {
            if (in_contact_[s]) {
              // The contact opened: its springs' energy goes with it.
              released += spring_energy_[s];
              in_contact_[s] = 0;
              spring_energy_[s] = 0;
              tangential_[s].setZero();
              if constexpr (kRolling != 0) rolling_[s].setZero();
              reaction_[reaction_index_[s]] = Reaction{};
              if constexpr (kRolling != 0) rolling_reaction_[reaction_index_[s]] = RollingReaction{};
            }
            continue;
          }
          ++contacts;
          const double distance = std::sqrt(distance_squared);
          ContactInput in;
          in.normal = distance > 0 ? Vec3(separation / distance) : Vec3::UnitZ();
          in.overlap = reach - distance;
          const double lever_a = ra - 0.5 * in.overlap, lever_b = radius_[b] - 0.5 * in.overlap;
          // arm_a = -lever_a n, arm_b = lever_b n.
          const Vec3 wb = spin_[b];
          in.relative_velocity = (va - lever_a * wa.cross(in.normal)) - (velocity_[b] + lever_b * wb.cross(in.normal));
          in.relative_spin = wa - wb;
          in.effective_radius = ra * radius_[b] / reach;
          in.effective_mass = 1.0 / (inverse_mass_[a] + inverse_mass_[b]);
          if constexpr (kRolling == 1 || kRolling == 3) {
            const double inverse_inertia_sum = inverse_inertia_[a] + inverse_inertia_[b];
            in.effective_inertia = 1.0 / inverse_inertia_sum;
          } else {
            in.effective_inertia = 0;
          }
          if constexpr (kLaw != 1) {
            in.linear_stiffness = explicit_stiffness ? linear_stiffness
                                                     : scale * stiffness_term_[a] * stiffness_term_[b] /
                                                           (stiffness_term_[a] + stiffness_term_[b]);
          } else {
            in.linear_stiffness = 0;
          }
          in.tangential_ratio = tangential_ratio;
          const ContactOutput out =
              contact<kLaw, kRolling>(laws[material_[b]], in, dt_previous, tangential_[s], rolling_[s]);
          in_contact_[s] = 1;
          spring_energy_[s] = out.spring_energy;
          elastic += out.elastic;
          released += out.slip_release;
          const Vec3 n_cross_f = in.normal.cross(out.force);
          const Vec3 n_cross_d = in.normal.cross(out.dissipative_force);
          force += out.force;
          torque += out.rolling_torque - lever_a * n_cross_f;
          dissipative_force += out.dissipative_force;
          dissipative_torque += out.dissipative_torque - lever_a * n_cross_d;
          Reaction& reaction = reaction_[reaction_index_[s]];
          reaction.force = -out.force;
          reaction.arm = lever_b * in.normal;
          reaction.dissipative_force = {static_cast<float>(-out.dissipative_force.x()),
                                        static_cast<float>(-out.dissipative_force.y()),
                                        static_cast<float>(-out.dissipative_force.z())};
          if constexpr (kRolling != 0) {
            RollingReaction& rolling = rolling_reaction_[reaction_index_[s]];
            rolling.torque = -out.rolling_torque;
            rolling.dissipative_torque = {static_cast<float>(-out.dissipative_torque.x()),
                                          static_cast<float>(-out.dissipative_torque.y()),
                                          static_cast<float>(-out.dissipative_torque.z())};
          }
        }
        std::uint32_t wall_contacts = 0;
        for (std::uint32_t listed = wall_near_start_[a]; listed < wall_near_start_[a + 1]; ++listed) {
          const std::uint32_t w = wall_near_[listed];
          const std::size_t slot = a * wall_count + w;
          Vec3 normal;
          const double distance = wall_distance(walls_[w], xa, normal);
          if (distance >= ra || fixed_[a]) {
            if (wall_in_contact_[slot]) {
              released += wall_spring_energy_[slot];
              wall_in_contact_[slot] = 0;
              wall_spring_energy_[slot] = 0;
              wall_tangential_[slot].setZero();
              wall_rolling_[slot].setZero();
            }
            continue;
          }
          ++wall_contacts;
          ContactInput in;
          in.normal = normal;
          in.overlap = ra - distance;
          const double lever = ra - 0.5 * in.overlap;
          in.relative_velocity = va - lever * wa.cross(normal);
          in.relative_spin = wa;
          in.effective_radius = ra;
          in.effective_mass = mass_[a];
          in.effective_inertia = 0.4 * mass_[a] * ra * ra;
          in.linear_stiffness = explicit_stiffness ? linear_stiffness : scale * stiffness_term_[a];
          in.tangential_ratio = tangential_ratio;
          // The law of the sphere's material with itself (a flat body of the same material has the E* and G*
          // of that pair), with the wall's own elastic constants where it has them.
          const ContactOutput out = contact<kLaw, kRolling>(wall_law_[w * material_count_ + material_[a]], in,
                                                            dt_previous, wall_tangential_[slot], wall_rolling_[slot]);
          wall_in_contact_[slot] = 1;
          wall_spring_energy_[slot] = out.spring_energy;
          elastic += out.elastic;
          released += out.slip_release;
          force += out.force;
          torque += out.rolling_torque - lever * normal.cross(out.force);
          dissipative_force += out.dissipative_force;
          dissipative_torque += out.dissipative_torque - lever * normal.cross(out.dissipative_force);
        }
        // Fixed spheres get no gravity: their force is the load the free spheres put on them.
        if (!fixed_[a]) force += mass_[a] * gravity_;
        force_[a] += force;
        torque_[a] += torque;
        dissipative_force_[a] = dissipative_force;
        dissipative_torque_[a] = dissipative_torque;
        sphere_elastic_[a] = elastic;
        sphere_released_[a] += released;
        sphere_contacts_[a] = contacts;
        sphere_wall_contacts_[a] = wall_contacts;
      }
    });
  }
  // Reactions, each sphere over the slots where it is b, in slot order (zero where not in contact).
  std::size_t contacts = 0, wall_contacts = 0;  // integer sums: exact in any order
#pragma omp parallel reduction(+ : contacts, wall_contacts) if (parallel_)
  {
    const auto [first, last] = thread_spheres(reverse_start_);
    with_best_isa([&] {
      for (std::int64_t k = first; k < last; ++k) {
        const auto b = static_cast<std::uint32_t>(k);
        contacts += sphere_contacts_[b];
        wall_contacts += sphere_wall_contacts_[b];
        Vec3 force = Vec3::Zero(), torque = Vec3::Zero(), dissipative_force = Vec3::Zero(),
             dissipative_torque = Vec3::Zero();
        for (std::uint32_t r = reverse_start_[b]; r < reverse_start_[b + 1]; ++r) {
          const Reaction& reaction = reaction_[r];
          const Vec3 dissipative(reaction.dissipative_force[0], reaction.dissipative_force[1],
                                 reaction.dissipative_force[2]);
          force += reaction.force;
          torque += reaction.arm.cross(reaction.force);
          dissipative_force += dissipative;
          dissipative_torque += reaction.arm.cross(dissipative);
          if constexpr (kRolling != 0) {
            const RollingReaction& rolling = rolling_reaction_[r];
            torque += rolling.torque;
            dissipative_torque +=
                Vec3(rolling.dissipative_torque[0], rolling.dissipative_torque[1], rolling.dissipative_torque[2]);
          }
        }
        force_[b] += force;
        torque_[b] += torque;
        dissipative_force_[b] += dissipative_force;
        dissipative_torque_[b] += dissipative_torque;
      }
    });
  }
  contact_count_ = contacts;
  wall_contact_count_ = wall_contacts;
}

void DemModel::compute_internal_forces(double dt_previous) {
  assert(dt_previous >= 0);
  parallel_ = size() >= kParallelThreshold;
  const auto n = static_cast<std::int64_t>(size());
  // Rebuild the neighbour list once a sphere may have come within reach of one not listed.
  // integrate() measures the displacements as it moves the spheres; positions() may have changed them since.
  if (!rebuild_ && build_position_.size() == size()) {
    if (!displacement_known_) {
      double largest_squared = 0;
#pragma omp parallel for schedule(static) reduction(max : largest_squared) if (parallel_)
      for (std::int64_t k = 0; k < n; ++k) {
        largest_squared = std::max(largest_squared, (position_[k] - build_position_[k]).squaredNorm());
      }
      largest_displacement_squared_ = largest_squared;
    }
    if (4 * largest_displacement_squared_ > skin_ * skin_) rebuild_ = true;
  } else {
    rebuild_ = true;
  }
  if (size() > 0 && rebuild_) build_neighbours();
  if (size() > 0) {
    switch (law_kind_ * 4 + rolling_kind_) {
      case 0: pair_forces<0, 0>(dt_previous); break;
      case 1: pair_forces<0, 1>(dt_previous); break;
      case 2: pair_forces<0, 2>(dt_previous); break;
      case 3: pair_forces<0, 3>(dt_previous); break;
      case 4: pair_forces<1, 0>(dt_previous); break;
      case 5: pair_forces<1, 1>(dt_previous); break;
      case 6: pair_forces<1, 2>(dt_previous); break;
      case 7: pair_forces<1, 3>(dt_previous); break;
      case 8: pair_forces<2, 0>(dt_previous); break;
      case 9: pair_forces<2, 1>(dt_previous); break;
      case 10: pair_forces<2, 2>(dt_previous); break;
      default: pair_forces<2, 3>(dt_previous); break;
    }
  }
  forces_ready_ = true;
}

void DemModel::add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force,
                                   std::span<const double> torque) {
  if (force.size() != 3 * index.size() || (!torque.empty() && torque.size() != 3 * index.size())) {
    throw ModelInputError(
        fmt::format("DEM forces: {} sphere ids but {} force and {} torque values (expected {} each, "
                    "torques optional)",
                    index.size(), force.size(), torque.size(), 3 * index.size()));
  }
  for (std::size_t k = 0; k < index.size(); ++k) {
    const std::uint32_t id = index[k];
    if (id >= size()) {
      throw ModelInputError(
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

  // Energies are summed per block of spheres, then the blocks in order: the same bits for any thread count.
  // Compiled for the baseline instruction set (no fused multiply-add), divided rather than multiplied by inverse
  // masses: the same bits as the Python solver of examples/python_dem (e2e_python_solver).
  const std::size_t blocks = (size() + kSumBlock - 1) / kSumBlock;
  block_sums_.resize(blocks);
  const auto block_count = static_cast<std::int64_t>(blocks);
  const bool measure = build_position_.size() == size();
  double largest_squared = 0;
#pragma omp parallel for schedule(static) reduction(max : largest_squared) if (parallel_)
  for (std::int64_t block = 0; block < block_count; ++block) {
    BlockSums sums;
    const std::size_t first = static_cast<std::size_t>(block) * kSumBlock;
    const std::size_t last = std::min(size(), first + kSumBlock);
    for (std::size_t i = first; i < last; ++i) {
      if (!fixed_[i]) {
        const double inertia = 0.4 * mass_[i] * radius_[i] * radius_[i];
        const Vec3 velocity = velocity_[i] + (dt_update / mass_[i]) * force_[i];
        const Vec3 spin = spin_[i] + (dt_update / inertia) * torque_[i];
        sums.kinetic += first_step
                            ? 0.5 * mass_[i] * velocity_[i].squaredNorm() + 0.5 * inertia * spin_[i].squaredNorm()
                            : 0.5 * mass_[i] * velocity_[i].dot(velocity) + 0.5 * inertia * spin_[i].dot(spin);
        sums.potential -= mass_[i] * gravity_.dot(position_[i]);
        // Power of the dissipative forces on this sphere over the step: their impulse times the mean of the
        // velocities before and after it (summed over both spheres of a pair: -F_d . mean relative velocity).
        sums.dissipated_power -=
            0.5 * (dissipative_force_[i].dot(velocity_[i] + velocity) + dissipative_torque_[i].dot(spin_[i] + spin));
        velocity_[i] = velocity;
        spin_[i] = spin;
        position_[i] += dt * velocity;
        if (measure) largest_squared = std::max(largest_squared, (position_[i] - build_position_[i]).squaredNorm());
      }
      force_[i].setZero();
      torque_[i].setZero();
      sums.elastic += sphere_elastic_[i];
      sums.released += sphere_released_[i];
      sphere_released_[i] = 0;
    }
    block_sums_[static_cast<std::size_t>(block)] = sums;
  }

  double dissipated_power = 0, elastic = 0, released = dropped_released_;
  energies_.kinetic = energies_.potential = 0;
  for (const BlockSums& sums : block_sums_) {
    energies_.kinetic += sums.kinetic;
    energies_.potential += sums.potential;
    dissipated_power += sums.dissipated_power;
    elastic += sums.elastic;
    released += sums.released;
  }
  dropped_released_ = 0;
  largest_displacement_squared_ = largest_squared;
  displacement_known_ = measure;
  energies_.elastic = elastic;
  energies_.dissipated += dt_update * dissipated_power + released;
  forces_ready_ = false;
}

double DemModel::stable_dt() const {
  // Called every coupled step; it changes only with the fixed spheres.
  if (!stable_dt_) stable_dt_ = compute_stable_dt();
  return *stable_dt_;
}

double DemModel::compute_stable_dt() const {
  double lightest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < size(); ++i) {
    if (!fixed_[i]) lightest = std::min(lightest, mass_[i]);
  }
  if (!std::isfinite(lightest)) return std::numeric_limits<double>::infinity();
  double largest_rolling = 0;
  for (const PairLaw& law : pair_law_) {
    if (law.rolling == 1) largest_rolling = std::max(largest_rolling, law.rolling_friction);
  }
  const bool any_linear = law_kind_ != 1, any_hertz = law_kind_ != 0;
  // The rolling spring on a sphere against a much larger one has k_r / I = 5.625 mu_r^2 k_n / m.
  const double rolling_factor = std::max(1.0, 5.625 * largest_rolling * largest_rolling);
  double dt = std::numeric_limits<double>::infinity();
  if (any_linear) {
    double stiffest = 0;
    if (settings_.normal_stiffness) {
      stiffest = *settings_.normal_stiffness;
    } else {
      // k_n grows with both K r: the stiffest pair joins the two largest K r.
      double largest = 0, second = 0;
      for (std::size_t i = 0; i < size(); ++i) {
        const double value = stiffness_term_[i];
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
    // Tangentially the contact point of a sphere moves with inverse mass 1/m + r^2/I = 3.5/m.
    stiffest *= std::max({1.0, 3.5 * settings_.tangential_stiffness_ratio, rolling_factor});
    dt = physics::spring_stable_dt(lightest, stiffest);
  }
  if (any_hertz) {
    // A fifth of the Rayleigh time of the smallest sphere, pi r sqrt(rho / G) / (0.1631 nu + 0.8766), the
    // usual bound for Hertz contacts: it is independent of the impact speed.
    for (std::size_t i = 0; i < size(); ++i) {
      if (fixed_[i]) continue;
      const double youngs = material_youngs_[material_[i]], nu = material_poisson_[material_[i]];
      const double shear = youngs / (2 * (1 + nu));
      const double density = mass_[i] / (4.0 / 3.0 * std::numbers::pi * radius_[i] * radius_[i] * radius_[i]);
      const double rayleigh = std::numbers::pi * radius_[i] * std::sqrt(density / shear) / (0.1631 * nu + 0.8766);
      dt = std::min(dt, 0.2 * rayleigh / std::sqrt(rolling_factor));
    }
  }
  return dt;
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
  std::vector<ContactRecord> records;
  if (!pending_.empty()) {
    for (const auto& [key, record] : pending_) records.push_back(record);
    return records;
  }
  for (std::uint32_t a = 0; a + 1 < start_.size(); ++a) {
    for (std::uint32_t s = start_[a]; s < start_[a + 1]; ++s) {
      if (!in_contact_[s]) continue;
      records.push_back(ContactRecord{a, neighbour_[s], tangential_[s], rolling_[s], spring_energy_[s]});
    }
  }
  return records;
}

void DemModel::restore(std::span<const ContactRecord> contacts, double dissipated_energy) {
  pending_.clear();
  pending_.reserve(contacts.size());
  for (const auto& contact : contacts) {
    if (contact.a >= contact.b || contact.b >= size()) {
      throw FileError(fmt::format("DEM checkpoint: contact ({}, {}) is not a pair of sphere ids a < b < {}", contact.a,
                                  contact.b, size()));
    }
    pending_.emplace_back(pair_key(contact.a, contact.b), contact);
  }
  std::sort(pending_.begin(), pending_.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  // The list is rebuilt at the next step with these histories in place of the current ones.
  start_.clear();
  rebuild_ = true;
  energies_.dissipated = dissipated_energy;
}

}  // namespace sabo::dem
