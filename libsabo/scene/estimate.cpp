#include "libsabo/scene/estimate.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <numeric>
#include <string>

#include "libsabo/geometry/polygon.hpp"
#include "libsabo/physics/stable_step.hpp"

namespace sabo::scene {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Triangle edges along `length` for a target `element_size`, as geometry::grid_levels cuts them (1 for 0).
double cells(double length, double element_size) {
  return element_size > 0 && length > element_size ? std::ceil(length / element_size * (1 - 1e-12)) : 1.0;
}
// Hexahedra or shells along `length`, as fem::element_divisions cuts them (1 for 0).
double divisions(double length, double element_size) {
  return element_size > 0 ? std::max(1.0, std::round(length / element_size)) : 1.0;
}

// Bytes on the wire per entity (proto/sabo/v1/sabo.proto): fixed32 4, fixed64 and double 8.
constexpr double kTableBytes = 8 + 8 + 8 + 4 + 4;          // ParticleTable: id, radius, mass, material, body
constexpr double kSphStateBytes = 4 + 24 + 24;             // index, position, velocity
constexpr double kDemStateBytes = 4 + 24 + 24 + 24;        // and angular velocity
constexpr double kBoundaryForceBytes = 24;                 // per wall particle the sph_solver returns
constexpr double kTopologyNodeBytes = 8 + 24 + 8;          // node id, position, mass
constexpr double kTopologyFaceBytes = 12 + 4 + 4 + 8 * 3;  // corners, part, material, thickness, K, volume
constexpr double kNodeStateBytes = 24 + 24;                // node position and velocity
constexpr double kMessageSlack = 1 << 20;                  // part names, energies, headers

struct Surface {
  double nodes = 0, triangles = 0, area = 0;
  double nodes_bound = 0, triangles_bound = 0;
  double elements = 0;  // hexahedra or shells (deformable)
  bool shells = false;
  double element_length = kInfinity;  // m, the smallest element's length (deformable)
};

// A grid of na x nb cells on a face: its nodes and triangles.
void add_face(Surface& s, double na, double nb) {
  s.nodes += (na + 1) * (nb + 1);
  s.triangles += 2 * na * nb;
}

Surface structure_surface(const Structure& structure) {
  const Shape& shape = structure.shape;
  Surface s;
  const double es = shape.element_size;
  if (shape.type == Shape::Type::mesh || shape.type == Shape::Type::terrain) {
    const MeshSize& m = shape.mesh_size;
    const double scale = shape.scale;
    if (structure.rigid) {
      s.nodes = static_cast<double>(m.nodes);
      s.triangles = static_cast<double>(m.triangles);
      s.area = m.area * scale * scale;
    } else if (m.hexahedra > 0) {
      s.elements = static_cast<double>(m.hexahedra);
      s.nodes = static_cast<double>(m.nodes);
      s.triangles = 12 * std::pow(s.elements, 2.0 / 3.0);  // the exterior of a compact solid
      s.element_length = m.smallest * scale;
      s.area = s.triangles / 2 * s.element_length * s.element_length;
      s.nodes_bound = s.nodes;
      s.triangles_bound = 12 * s.elements;  // erosion can expose every face
    } else {
      s.elements = static_cast<double>(m.quads);
      s.shells = true;
      s.nodes = static_cast<double>(m.nodes);
      s.triangles = 2 * s.elements;
      s.element_length = m.smallest * scale;
      s.area = s.elements * s.element_length * s.element_length;
    }
  } else if (structure.rigid || structure.thickness > 0) {
    // Triangulated surfaces (rigid), or shells (deformable: their mid-surface, as quadrangles).
    const bool deformable = !structure.rigid;
    const auto n = [&](double length) { return deformable ? divisions(length, es) : cells(length, es); };
    const auto face = [&](double a, double b) {
      const double na = n(a), nb = n(b);
      add_face(s, na, nb);
      s.area += a * b;
      if (deformable) {
        s.elements += na * nb;
        s.element_length = std::min({s.element_length, a / na, b / nb});
      }
    };
    switch (shape.type) {
      case Shape::Type::plane: face(shape.length, shape.width); break;
      case Shape::Type::box: {
        const Vec3 e = shape.box.max - shape.box.min;
        if (deformable) {  // a building: four walls, floors - 1 slabs and a roof
          face(e.x(), e.z()), face(e.x(), e.z()), face(e.y(), e.z()), face(e.y(), e.z());
          for (std::size_t k = 0; k < std::max<std::size_t>(structure.floors, 1); ++k) face(e.x(), e.y());
        } else {
          for (int twice = 0; twice < 2; ++twice) face(e.x(), e.y()), face(e.y(), e.z()), face(e.z(), e.x());
        }
        break;
      }
      case Shape::Type::chute:
        face(shape.length, shape.width);
        if (shape.wall_height > 0) face(shape.length, shape.wall_height), face(shape.length, shape.wall_height);
        if (shape.end_wall_height > 0) face(shape.width, shape.end_wall_height);
        break;
      case Shape::Type::channel:
        for (std::size_t k = 0; k + 1 < shape.profile.size(); ++k) {
          const double length =
              std::hypot(shape.profile[k + 1][0] - shape.profile[k][0], shape.profile[k + 1][1] - shape.profile[k][1]);
          if (shape.floor) face(length, shape.width);
          if (shape.wall_height > 0) face(length, shape.wall_height), face(length, shape.wall_height);
        }
        if (shape.start_wall_height > 0) face(shape.width, shape.start_wall_height);
        if (shape.end_wall_height > 0) face(shape.width, shape.end_wall_height);
        break;
      case Shape::Type::mesh:
      case Shape::Type::terrain: break;
    }
    s.shells = deformable;
  } else {
    // A solid box of hexahedra (a slit dam takes fewer).
    const Vec3 e = shape.box.max - shape.box.min;
    const double nx = divisions(e.x(), es), ny = divisions(e.y(), es), nz = divisions(e.z(), es);
    s.elements = nx * ny * nz;
    s.nodes = (nx + 1) * (ny + 1) * (nz + 1);
    s.triangles = 4 * (nx * ny + ny * nz + nz * nx);
    s.area = 2 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
    s.element_length = std::min({e.x() / nx, e.y() / ny, e.z() / nz});
    s.nodes_bound = s.nodes;
    s.triangles_bound = 12 * s.elements;
  }
  s.nodes_bound = std::max(s.nodes_bound, s.nodes);
  s.triangles_bound = std::max(s.triangles_bound, s.triangles);
  return s;
}

// Lattice sites of spacing dx along a length (centres dx/2 inside), to a relative 1e-6 as the
// sph_solver's fill: estimate and bound.
double sites(double length, double dx) {
  return std::floor(length / dx * (1 + 1e-6));
}
double lattice(const Vec3& e, double dx) {
  return sites(e.x(), dx) * sites(e.y(), dx) * sites(e.z(), dx);
}
double lattice_bound(const Vec3& e, double dx) {
  return (sites(e.x(), dx) + 1) * (sites(e.y(), dx) + 1) * (sites(e.z(), dx) + 1);
}

const Material* find_material(const Scene& scene, const std::string& name) {
  for (const Material& m : scene.materials) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

double beta_of(const Scene& scene, Role role) {
  const SolverSettings* solver = scene.solver(role);
  return solver != nullptr ? solver->beta : 1.0;
}

struct Step {
  double dt = kInfinity;
  std::string what, key;
  void offer(double candidate, std::string candidate_what, std::string candidate_key) {
    if (candidate < dt) {
      dt = candidate;
      what = std::move(candidate_what);
      key = std::move(candidate_key);
    }
  }
};

}  // namespace

double SceneEstimate::total_fluid_particles() const {
  return std::accumulate(fluid_particles.begin(), fluid_particles.end(), 0.0);
}
double SceneEstimate::total_spheres() const {
  return std::accumulate(spheres.begin(), spheres.end(), 0.0);
}
double SceneEstimate::total_elements() const {
  return std::accumulate(elements.begin(), elements.end(), 0.0);
}
double SceneEstimate::total_surface_triangles() const {
  return std::accumulate(surface_triangles.begin(), surface_triangles.end(), 0.0);
}

SceneEstimate estimate_scene(const Scene& scene) {
  SceneEstimate out;
  Step step;
  const SphSettings& sph = scene.sph;
  const double dx = sph.particle_spacing;
  const bool walls = !scene.fluids.empty() && sph.wall_model == SphSettings::WallModel::boundary_particles;
  const double layers = dx > 0 ? std::ceil(sph.kernel_support() / dx - 1e-9) : 0.0;

  // sph_solver: the bodies' lattices.
  for (const FluidBody& body : scene.fluids) {
    double count = 0, bound = 0;
    if (dx > 0) {
      const Aabb b = body.bounds();
      const Vec3 extent = b.empty() ? Vec3::Zero() : Vec3(b.max - b.min);
      if (body.shape == FluidBody::Shape::box) {
        count = lattice(extent, dx);
      } else if (body.shape == FluidBody::Shape::inflow) {
        count = static_cast<double>(body.inflow.lattice(sph, scene.run.end_time).particles());
      } else {
        count = std::floor(geometry::polygon_area(body.profile) / (dx * dx)) * sites(body.width, dx);
      }
      bound = body.shape == FluidBody::Shape::inflow ? count : lattice_bound(extent, dx);
    }
    out.fluid_particles.push_back(count);
    out.fluid_particles_bound += bound;
  }
  if (!scene.fluids.empty() && dx > 0 && sph.sound_speed > 0) {
    step.offer(beta_of(scene, Role::sph) * scene.sph_acoustic_dt(),
               fmt::format("the sph_solver's acoustic step cfl h / c = {:g} x {:g} m / {:g} m/s", sph.cfl,
                           sph.smoothing_length(), sph.sound_speed),
               "sph.particle_spacing");
  }

  // dem_solver: the sets' spheres and their contact step.
  for (std::size_t k = 0; k < scene.particle_sets.size(); ++k) {
    const ParticleSet& set = scene.particle_sets[k];
    const bool list = set.kind == ParticleSet::Kind::list;
    out.spheres.push_back(list ? static_cast<double>(set.spheres.size()) : static_cast<double>(set.count));
    double smallest = kInfinity, surface = 0, surface_bound = 0;
    if (list) {
      for (const Sphere& sphere : set.spheres) {
        smallest = std::min(smallest, sphere.radius);
        surface += 4 * std::numbers::pi * sphere.radius * sphere.radius;
      }
      surface_bound = surface;
    } else {
      smallest = 0.5 * set.diameter_min;
      const double mean = 0.5 * (set.diameter_min + set.diameter_max);
      surface = static_cast<double>(set.count) * std::numbers::pi * mean * mean;
      surface_bound = static_cast<double>(set.count) * std::numbers::pi * set.diameter_max * set.diameter_max;
    }
    if (!scene.fluids.empty() && dx > 0 && scene.boundary_particle_set(set.name)) {
      out.wall_particles += surface * layers / (dx * dx);
      out.wall_particles_bound += 1.5 * surface_bound * layers / (dx * dx);
    }
    const Material* material = find_material(scene, set.material);
    if (material == nullptr || !(smallest > 0) || !std::isfinite(smallest)) continue;
    const DemContactLaw& law = scene.dem_contact.law(set.material, set.material);
    const std::string key = fmt::format("materials.{}.youngs_modulus", material->name);
    double dt = kInfinity;
    std::string what;
    if (law.model == DemLaw::hertz_mindlin) {
      const double nu = material->poisson_ratio;
      dt = 0.2 * std::numbers::pi * smallest * std::sqrt(material->density / material->shear_modulus()) /
           (0.1631 * nu + 0.8766);
      what = fmt::format("the dem_solver's Hertz step (a fifth of the Rayleigh time of a sphere of radius {:g} m)",
                         smallest);
    } else {
      const double mass = material->density * 4.0 / 3.0 * std::numbers::pi * smallest * smallest * smallest;
      const double stiffness = scene.dem_contact.normal_stiffness
                                   ? *scene.dem_contact.normal_stiffness
                                   : scene.dem_contact.normal_stiffness_scale * material->bulk_modulus() * smallest / 2;
      dt = physics::spring_stable_dt(mass, stiffness);
      what = fmt::format("the dem_solver's contact step 0.2 pi sqrt(m / k_n) of a sphere of radius {:g} m", smallest);
    }
    step.offer(beta_of(scene, Role::dem) * dt, what,
               scene.dem_contact.normal_stiffness && law.model != DemLaw::hertz_mindlin
                   ? std::string("contact.dem_dem.normal_stiffness")
                   : key);
  }

  // fem_solver: the structures' elements and contact surface; the coupler's wall particles.
  for (std::size_t k = 0; k < scene.structures.size(); ++k) {
    const Structure& structure = scene.structures[k];
    const Surface s = structure_surface(structure);
    out.elements.push_back(structure.rigid ? 0.0 : s.elements);
    out.surface_triangles.push_back(s.triangles);
    out.surface_nodes_bound += s.nodes_bound;
    out.surface_triangles_bound += s.triangles_bound;
    if (walls && dx > 0) {
      out.wall_particles += s.area * layers / (dx * dx);
      out.wall_particles_bound += 1.5 * s.area * (layers + 2) / (dx * dx) + 8 * s.nodes_bound * layers * layers;
    }
    if (structure.rigid) continue;
    const Material* material = find_material(scene, structure.material);
    if (material == nullptr || !std::isfinite(s.element_length) || !(s.element_length > 0)) continue;
    const double nu = material->poisson_ratio, e = material->youngs_modulus, rho = material->density;
    const double speed =
        s.shells ? std::sqrt(e / (rho * (1 - nu * nu))) : std::sqrt(e * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu)));
    step.offer(beta_of(scene, Role::fem) * s.element_length / speed,
               fmt::format("the fem_solver's step L / c of structure '{}': elements of {:g} m, waves of {:g} m/s",
                           structure.name, s.element_length, speed),
               fmt::format("materials.{}.youngs_modulus", material->name));
  }

  if (scene.run.max_dt) step.offer(*scene.run.max_dt, "run.max_dt", "run.max_dt");
  out.dt = step.dt;
  out.dt_what = step.what;
  out.dt_key = step.key;
  out.steps = std::isfinite(step.dt) && step.dt > 0 ? scene.run.end_time / step.dt : 0.0;
  out.outputs = scene.run.output_interval > 0 ? scene.run.end_time / scene.run.output_interval + 1 : 0.0;

  const auto processes = static_cast<double>(1 + scene.solvers.size());
  out.structure_bytes.assign(scene.structures.size(), 0.0);
  for (std::size_t k = 0; k < scene.structures.size(); ++k) {
    const Structure& structure = scene.structures[k];
    const bool is_shell = structure.thickness > 0 || structure.shape.mesh_size.quads > 0;
    out.structure_bytes[k] = structure.rigid ? out.surface_triangles[k] * kBytesPerSurfaceTriangle
                                             : out.elements[k] * (is_shell ? kBytesPerShell : kBytesPerHexahedron);
  }
  out.memory_bytes = processes * kBytesPerProcess + out.total_fluid_particles() * kBytesPerFluidParticle +
                     out.wall_particles * kBytesPerWallParticle + out.total_spheres() * kBytesPerSphere +
                     std::accumulate(out.structure_bytes.begin(), out.structure_bytes.end(), 0.0);

  // The largest frame each role sends: a registration, or a state that also carries a new table or topology.
  const double sph_message =
      out.fluid_particles_bound * (kSphStateBytes + kTableBytes) + out.wall_particles_bound * kBoundaryForceBytes;
  double dem_message = 0;
  for (double n : out.spheres) dem_message += n * (kDemStateBytes + kTableBytes);
  const double fem_message = out.surface_nodes_bound * (kNodeStateBytes + kTopologyNodeBytes) +
                             out.surface_triangles_bound * kTopologyFaceBytes;
  out.largest_message_bound = std::max({sph_message, dem_message, fem_message}) + kMessageSlack;
  return out;
}

std::int64_t max_message_bytes(const SceneEstimate& estimate) {
  const double bytes = 2 * estimate.largest_message_bound + 64.0 * (1 << 20);
  return bytes >= 9e18 ? std::numeric_limits<std::int64_t>::max() : static_cast<std::int64_t>(bytes);
}

double physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  double bytes = pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : 0.0;
  // A memory limit of the cgroup (cgroup v2) is this machine as far as the run is concerned.
  std::ifstream limit("/sys/fs/cgroup/memory.max");
  double value = 0;
  if (limit >> value && value > 0 && (bytes == 0 || value < bytes)) bytes = value;
  return bytes;
}

}  // namespace sabo::scene
