#include "libsabo/scene/scene.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

#include "libsabo/geometry/polygon.hpp"
#include "libsabo/physics/stable_step.hpp"

namespace sabo::scene {

bool Scene::needs(Role role) const {
  return solver(role) != nullptr;
}

const SolverSettings* Scene::solver(Role role) const {
  auto it = std::find_if(solvers.begin(), solvers.end(), [role](const SolverSettings& s) { return s.role == role; });
  return it == solvers.end() ? nullptr : &*it;
}

std::size_t Scene::material_index(const std::string& name) const {
  auto it = std::find_if(materials.begin(), materials.end(), [&](const Material& m) { return m.name == name; });
  assert(it != materials.end() && "material names are checked by the loader");
  return static_cast<std::size_t>(it - materials.begin());
}

namespace {

// E[d^3] for d uniform in [a, b].
double uniform_mean_cube(double a, double b) {
  return b > a ? (b * b * b * b - a * a * a * a) / (4.0 * (b - a)) : a * a * a;
}

// Squared distance from p to the segment [a, b] in the plane.
double segment_distance_squared(double px, double pz, const std::array<double, 2>& a, const std::array<double, 2>& b) {
  const double ex = b[0] - a[0], ez = b[1] - a[1];
  const double length_squared = ex * ex + ez * ez;
  double t = length_squared > 0 ? ((px - a[0]) * ex + (pz - a[1]) * ez) / length_squared : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double dx = px - (a[0] + t * ex), dz = pz - (a[1] + t * ez);
  return dx * dx + dz * dz;
}

}  // namespace

std::vector<double> ParticleSet::sieve_class_probabilities() const {
  std::vector<double> weight(sieve.size(), 0.0);
  double total = 0;
  for (std::size_t k = 1; k < sieve.size(); ++k) {
    const double share = sieve[k][1] - sieve[k - 1][1];
    // A mass share holds share / E[d^3] spheres per unit of d^3 (uniform diameters in the class).
    weight[k] = sieve_by_mass ? share / uniform_mean_cube(sieve[k - 1][0], sieve[k][0]) : share;
    total += weight[k];
  }
  if (total > 0) {
    for (double& w : weight) w /= total;
  }
  return weight;
}

double ParticleSet::mean_sphere_volume() const {
  double mean_cube = 0;
  switch (distribution) {
    case SizeDistribution::uniform: mean_cube = uniform_mean_cube(diameter_min, diameter_max); break;
    case SizeDistribution::normal: {
      // E[d^3] of the normal density restricted to [min, max] (Simpson's rule).
      constexpr int intervals = 400;
      const double h = (diameter_max - diameter_min) / intervals;
      double mass = 0, moment = 0;
      for (int k = 0; k <= intervals; ++k) {
        const double d = diameter_min + h * k;
        const double z = std::max(std_diameter, 1e-300);
        const double density = std::exp(-0.5 * ((d - mean_diameter) / z) * ((d - mean_diameter) / z));
        const double w = (k == 0 || k == intervals) ? 1.0 : (k % 2 == 1 ? 4.0 : 2.0);
        mass += w * density;
        moment += w * density * d * d * d;
      }
      mean_cube = mass > 0 ? moment / mass : uniform_mean_cube(diameter_min, diameter_max);
      break;
    }
    case SizeDistribution::sieve: {
      const auto probability = sieve_class_probabilities();
      for (std::size_t k = 1; k < sieve.size(); ++k) {
        mean_cube += probability[k] * uniform_mean_cube(sieve[k - 1][0], sieve[k][0]);
      }
      break;
    }
  }
  return std::numbers::pi / 6.0 * mean_cube;
}

double ParticleSet::region_volume() const {
  if (polygon_xz.empty()) return (region.max - region.min).prod();
  return geometry::polygon_area(polygon_xz) * (region.max.y() - region.min.y());
}

bool ParticleSet::contains_sphere(const Vec3& center, double radius) const {
  if ((center.array() - radius < region.min.array()).any() || (center.array() + radius > region.max.array()).any()) {
    return false;
  }
  if (polygon_xz.empty()) return true;
  const double x = center.x(), z = center.z();
  for (std::size_t k = 0, j = polygon_xz.size() - 1; k < polygon_xz.size(); j = k++) {
    if (segment_distance_squared(x, z, polygon_xz[k], polygon_xz[j]) < radius * radius) return false;
  }
  return geometry::polygon_contains(polygon_xz, x, z);
}

double InflowSection::discharge(double t) const {
  if (hydrograph.empty() || t < hydrograph.front()[0] || t > hydrograph.back()[0]) return 0.0;
  const auto after = std::upper_bound(hydrograph.begin(), hydrograph.end(), t,
                                      [](double time, const std::array<double, 2>& point) { return time < point[0]; });
  if (after == hydrograph.end()) return hydrograph.back()[1];
  const auto& [t1, q1] = *after;
  const auto& [t0, q0] = *(after - 1);
  return q0 + (q1 - q0) * (t - t0) / (t1 - t0);
}

double InflowSection::volume(double from, double to) const {
  double sum = 0;
  for (std::size_t k = 1; k < hydrograph.size(); ++k) {
    const double a = std::max(from, hydrograph[k - 1][0]), b = std::min(to, hydrograph[k][0]);
    if (b > a) sum += 0.5 * (discharge(a) + discharge(b)) * (b - a);  // exact: Q is linear on the segment
  }
  return sum;
}

InflowLattice InflowSection::lattice(const SphSettings& sph, double run_end) const {
  InflowLattice out;
  const double dx = sph.particle_spacing;
  if (!(dx > 0)) return out;
  out.across = static_cast<std::size_t>(std::max(1.0, std::round(width / dx)));
  out.up = static_cast<std::size_t>(std::max(1.0, std::round(depth / dx)));
  out.buffer_layers = sph.inflow_buffer_layers();
  out.area = static_cast<double>(out.per_layer()) * dx * dx;
  // Layer l enters the buffer once it has advanced X >= (l + 1/2 - buffer_layers) dx, X = volume / area: at
  // most buffer_layers + X / dx + 1/2 layers; one more for the rounding of X's sum.
  const double advance = volume(0.0, run_end) / out.area;
  out.layers = out.buffer_layers + static_cast<std::size_t>(std::ceil(advance / dx)) + 1;
  return out;
}

double InflowSection::peak_discharge() const {
  double peak = 0;
  for (const auto& point : hydrograph) peak = std::max(peak, point[1]);
  return peak;
}

Aabb FluidBody::bounds() const {
  if (shape == Shape::box) return box;
  if (shape == Shape::inflow) {
    Aabb section;
    for (const double a : {-0.5 * inflow.width, 0.5 * inflow.width}) {
      for (const double u : {0.0, inflow.depth})
        section.extend(inflow.position + a * inflow.across() + u * inflow.up());
    }
    return section;
  }
  Aabb bounds;
  const Vec3 across(-direction.y(), direction.x(), 0.0);
  for (const auto& [s, z] : profile) {
    for (const double t : {-0.5 * width, 0.5 * width}) {
      Vec3 p = profile_origin + s * direction + t * across;
      p.z() = z;
      bounds.extend(p);
    }
  }
  return bounds;
}

Vec3 Front::path_point(double s) const {
  if (kind == Kind::terrain && path.size() >= 2) {
    const auto after = std::upper_bound(path_s.begin() + 1, path_s.end() - 1, s);
    const auto k = static_cast<std::size_t>(after - path_s.begin()) - 1;
    const double f = std::clamp((s - path_s[k]) / (path_s[k + 1] - path_s[k]), 0.0, 1.0);
    return path[k] + f * (path[k + 1] - path[k]);
  }
  if (kind == Kind::axis || bed.empty()) return start + s * direction;
  double z = bed.front()[1];
  if (s >= bed.back()[0]) {
    z = bed.back()[1];
  } else if (s > bed.front()[0]) {
    const auto after = std::upper_bound(bed.begin(), bed.end(), s,
                                        [](double value, const std::array<double, 2>& p) { return value < p[0]; });
    const auto& a = *(after - 1);
    const auto& b = *after;
    z = a[1] + (b[1] - a[1]) * (s - a[0]) / (b[0] - a[0]);
  }
  return Vec3(start.x(), start.y(), 0) + s * direction + z * Vec3::UnitZ();
}

Front::Projection Front::project(const Vec3& x) const {
  if (kind != Kind::terrain || path.size() < 2) return {(x - start).dot(direction), direction};
  Projection best;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const Eigen::Vector2d a = path[k].head<2>(), b = path[k + 1].head<2>(), p = x.head<2>();
    const double length = path_s[k + 1] - path_s[k];
    const double t = std::clamp((p - a).dot(b - a) / (length * length), 0.0, 1.0);
    const double d = (p - (a + t * (b - a))).squaredNorm();
    if (d < nearest) {
      nearest = d;
      best.s = path_s[k] + t * length;
      best.tangent = (path[k + 1] - path[k]).normalized();
    }
  }
  return best;
}

const DemContactLaw& DemContact::law(const std::string& material_a, const std::string& material_b) const {
  for (const auto& pair : pairs) {
    if ((pair.material_a == material_a && pair.material_b == material_b) ||
        (pair.material_a == material_b && pair.material_b == material_a)) {
      return pair.law;
    }
  }
  return *this;
}

SurfaceContact Scene::surface_contact(const std::string& set, const std::string& structure) const {
  for (const auto& interaction : interactions) {
    if ((interaction.a == set && interaction.b == structure) || (interaction.a == structure && interaction.b == set)) {
      return interaction.contact;
    }
  }
  const bool is_fluid = std::any_of(fluids.begin(), fluids.end(), [&](const FluidBody& f) { return f.name == set; });
  return is_fluid ? sph_fem_default : dem_fem_default;
}

SurfaceContact Scene::fem_fem_contact(const std::string& a, const std::string& b) const {
  SurfaceContact off = fem_fem_default;
  off.enabled = false;
  const auto structure = [&](const std::string& name) -> const Structure* {
    for (const auto& s : structures) {
      if (s.name == name) return &s;
    }
    return nullptr;
  };
  const Structure* first = structure(a);
  const Structure* second = structure(b);
  if (a == b || first == nullptr || second == nullptr || (first->rigid && second->rigid)) return off;
  for (const auto& interaction : fem_fem_interactions) {
    if ((interaction.a == a && interaction.b == b) || (interaction.a == b && interaction.b == a)) {
      return interaction.contact;
    }
  }
  return fem_fem_default;
}

SphDemContact Scene::sph_dem_contact(const std::string& fluid, const std::string& set) const {
  for (const auto& interaction : sph_dem_interactions) {
    if (interaction.fluid == fluid && interaction.set == set) return interaction.contact;
  }
  return sph_dem_default;
}

bool Scene::boundary_particle_set(const std::string& set) const {
  return std::any_of(fluids.begin(), fluids.end(), [&](const FluidBody& fluid) {
    const SphDemContact contact = sph_dem_contact(fluid.name, set);
    return contact.enabled && contact.model == SphDemContact::Model::boundary_particles;
  });
}

bool Scene::sph_receives_boundary_particles() const {
  if (fluids.empty()) return false;
  if (sph.wall_model == SphSettings::WallModel::boundary_particles) return true;
  return std::any_of(particle_sets.begin(), particle_sets.end(),
                     [&](const ParticleSet& set) { return boundary_particle_set(set.name); });
}

double Scene::sph_acoustic_dt() const {
  return sph.cfl * sph.smoothing_length() / sph.sound_speed;
}

double Scene::sph_dem_pair_dt(const FluidBody& fluid, double stiffness) const {
  const double dx = sph.particle_spacing;
  const double mass = materials[material_index(fluid.material)].density * dx * dx * dx;
  return physics::spring_stable_dt(mass, stiffness);
}

double Scene::sph_dem_derived_stiffness(const FluidBody& fluid) const {
  const double dx = sph.particle_spacing;
  const double rho0 = materials[material_index(fluid.material)].density;
  const double own = rho0 * sph.sound_speed * sph.sound_speed * dx;
  // K such that 0.2 pi sqrt(rho0 dx^3 / K) equals the acoustic step.
  const double step = sph_acoustic_dt();
  const double cap = physics::stiffness_for_stable_dt(rho0 * dx * dx * dx, step);
  return std::min(own, cap);
}

}  // namespace sabo::scene
