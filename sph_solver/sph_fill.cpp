// Particles of the scene's fluid bodies on a cubic lattice, with the
// hydrostatic initial state.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/polygon.hpp"
#include "libsabo/geometry/sphere_fill.hpp"
#include "libsabo/physics/cell_list.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// Layers of spacing dx in `extent`, to a relative 1e-6: a spacing written to 9 digits (h / 6 as
// 0.00666666667) must still give its 6 layers, not 5.
std::size_t lattice_count(double extent, double dx) {
  return static_cast<std::size_t>(std::floor(extent / dx * (1 + 1e-6)));
}

// Pressure at `depth` (m) below the free surface of a fluid at rest: dp/d(depth) = rho(p) g
// integrated with the EOS (RK4), so that the pressure carries the weight of the compressed
// column above; rho0 g depth falls short by half the compression (0.5 % at the bottom at
// c = 10 sqrt(g H)).
double hydrostatic_pressure(const EquationOfState& eos, double g, double depth) {
  constexpr int kSteps = 4;
  const double step = depth / kSteps;
  double p = 0;  // Pa, at the free surface
  for (int k = 0; k < kSteps; ++k) {
    const double k1 = eos.density(p) * g;
    const double k2 = eos.density(p + 0.5 * step * k1) * g;
    const double k3 = eos.density(p + 0.5 * step * k2) * g;
    const double k4 = eos.density(p + step * k3) * g;
    p += step * (k1 + 2.0 * k2 + 2.0 * k3 + k4) / 6.0;
  }
  return p;
}

// Leaves out the lattice points [first, end) of `body` that lie within dx/2 of a DEM sphere in contact
// with it (a boulder that starts inside the slurry has pushed it aside: no fluid particle is closer to
// its surface than to a wall's). The loader has refused spheres inside a fluid whose places are unknown.
void carve_spheres(const scene::Scene& scene, const scene::FluidBody& body,
                   const std::vector<std::optional<std::vector<scene::Sphere>>>& sets, double dx, std::size_t first,
                   std::vector<Vec3>& position) {
  std::vector<Vec3> centre;
  std::vector<double> reach;
  for (std::size_t s = 0; s < sets.size(); ++s) {
    if (!sets[s] || !scene.sph_dem_contact(body.name, scene.particle_sets[s].name).enabled) continue;
    for (const scene::Sphere& sphere : *sets[s]) {
      centre.push_back(sphere.center);
      reach.push_back(sphere.radius + 0.5 * dx);
    }
  }
  if (centre.empty()) return;
  physics::CellList grid;
  grid.build_points(centre, *std::max_element(reach.begin(), reach.end()));
  const auto inside = [&](const Vec3& p) {
    bool hit = false;
    grid.for_each_near(p, [&](std::uint32_t k) { hit = hit || (p - centre[k]).squaredNorm() < reach[k] * reach[k]; });
    return hit;
  };
  const auto kept = std::stable_partition(position.begin() + static_cast<std::ptrdiff_t>(first), position.end(),
                                          [&](const Vec3& p) { return !inside(p); });
  position.erase(kept, position.end());
}

// An inflow's pool (inflow.hpp): every layer its run can need, in the order they enter, each where it
// would be at the buffer's start (advance 0), at rest, with the density its buffer prescribes: the
// hydrostatic pressure of its row's depth below the section's top along `up` (gravity's component
// there), or the rest density. The model takes them in when they enter; the inflow's state (its pool's
// first id, lattice and those densities) goes into fill.inflows.
void fill_inflow_pool(const scene::Scene& scene, std::uint32_t body_index, const FluidMaterial& material,
                      bool with_stress, FluidFill& fill) {
  const scene::FluidBody& body = scene.fluids[body_index];
  InflowState inflow;
  inflow.name = body.name;
  inflow.body = body_index;
  inflow.first = static_cast<std::uint32_t>(fill.position.size());
  inflow.section = body.inflow;
  inflow.lattice = body.inflow.lattice(scene.sph, scene.run.end_time);
  inflow.spacing = scene.sph.particle_spacing;
  const double dx = inflow.spacing;
  const double g_across_bed = std::max(0.0, -scene.run.gravity.dot(body.inflow.up()));
  for (std::size_t row = 0; row < inflow.lattice.up; ++row) {
    const double depth = (static_cast<double>(inflow.lattice.up - row) - 0.5) * dx;
    inflow.row_density.push_back(body.hydrostatic
                                     ? material.eos.density(hydrostatic_pressure(material.eos, g_across_bed, depth))
                                     : material.eos.rest_density);
  }
  for (std::size_t layer = 0; layer < inflow.lattice.layers; ++layer) {
    for (std::size_t k = 0; k < inflow.lattice.per_layer(); ++k) {
      const double rho = inflow.row_density[k / inflow.lattice.across];
      fill.position.push_back(inflow.position(layer, k, 0.0));
      fill.velocity.push_back(Vec3::Zero());
      fill.density.push_back(rho);
      fill.pressure.push_back(material.eos.pressure(rho));
      fill.mass.push_back(rho * dx * dx * dx);  // as fill_fluids(): the lattice cell at its density
      if (with_stress) fill.stress.insert(fill.stress.end(), 6, 0.0);
    }
  }
  fill.inflows.push_back(std::move(inflow));
}

}  // namespace

FluidFill fill_fluids(const scene::Scene& scene, std::span<const FluidMaterial> materials,
                      const std::vector<std::uint32_t>& body_material) {
  FluidFill fill;
  // Stresses only where a body is elastic-plastic (else 48 bytes a particle for nothing).
  const bool with_stress = std::any_of(body_material.begin(), body_material.end(), [&](std::uint32_t m) {
    return materials[m].rheology == scene::Material::Rheology::elastic_plastic;
  });
  const double dx = scene.sph.particle_spacing;
  const double g = std::abs(scene.run.gravity.z());
  const auto spheres = geometry::initial_spheres(scene);
  for (std::size_t b = 0; b < scene.fluids.size(); ++b) {
    const scene::FluidBody& body = scene.fluids[b];
    const std::size_t first = fill.position.size();
    if (body.shape == scene::FluidBody::Shape::inflow) {
      fill_inflow_pool(scene, static_cast<std::uint32_t>(b), materials[body_material[b]], with_stress, fill);
      const auto count = fill.position.size() - first;
      fill.material.insert(fill.material.end(), count, body_material[b]);
      fill.body.insert(fill.body.end(), count, static_cast<std::uint32_t>(b));
      continue;
    }
    if (body.shape == scene::FluidBody::Shape::box) {
      const Vec3 extent = body.box.max - body.box.min;
      const std::size_t nx = lattice_count(extent.x(), dx), ny = lattice_count(extent.y(), dx),
                        nz = lattice_count(extent.z(), dx);
      for (std::size_t k = 0; k < nz; ++k) {
        for (std::size_t j = 0; j < ny; ++j) {
          for (std::size_t i = 0; i < nx; ++i) {
            fill.position.push_back(body.box.min + dx * Vec3(static_cast<double>(i) + 0.5, static_cast<double>(j) + 0.5,
                                                             static_cast<double>(k) + 0.5));
          }
        }
      }
    } else {
      double s_min = INFINITY, s_max = -INFINITY, z_min = INFINITY, z_max = -INFINITY;
      for (const auto& [s, z] : body.profile) {
        s_min = std::min(s_min, s);
        s_max = std::max(s_max, s);
        z_min = std::min(z_min, z);
        z_max = std::max(z_max, z);
      }
      const Vec3 across(-body.direction.y(), body.direction.x(), 0.0);
      const std::size_t ns = lattice_count(s_max - s_min, dx), nt = lattice_count(body.width, dx),
                        nz = lattice_count(z_max - z_min, dx);
      for (std::size_t k = 0; k < nz; ++k) {
        const double z = z_min + (static_cast<double>(k) + 0.5) * dx;
        for (std::size_t j = 0; j < nt; ++j) {
          const double t = -0.5 * body.width + (static_cast<double>(j) + 0.5) * dx;
          for (std::size_t i = 0; i < ns; ++i) {
            const double s = s_min + (static_cast<double>(i) + 0.5) * dx;
            if (!geometry::polygon_contains(body.profile, s, z)) continue;
            Vec3 p = body.profile_origin + s * body.direction + t * across;
            p.z() = z;
            fill.position.push_back(p);
          }
        }
      }
    }
    carve_spheres(scene, body, spheres, dx, first, fill.position);
    const std::size_t count = fill.position.size() - first;
    if (count == 0) {
      throw SceneError(
          fmt::format("{}:{}: fluids[{}] ('{}') holds no particle at the spacing dx = {} m. Fix: make "
                      "the body larger than dx on every axis or lower sph.particle_spacing.",
                      body.origin.file.string(), body.origin.line, b, body.name, dx));
    }
    // Hydrostatic state: pressure of the column of this body above each particle.
    const FluidMaterial& material = materials[body_material[b]];
    std::map<std::pair<std::int64_t, std::int64_t>, double> column_top;
    const auto column = [&](const Vec3& p) {
      return std::make_pair(static_cast<std::int64_t>(std::floor(p.x() / dx)),
                            static_cast<std::int64_t>(std::floor(p.y() / dx)));
    };
    if (body.hydrostatic) {
      for (std::size_t i = first; i < fill.position.size(); ++i) {
        auto [it, inserted] = column_top.try_emplace(column(fill.position[i]), fill.position[i].z());
        if (!inserted) it->second = std::max(it->second, fill.position[i].z());
      }
    }
    const double rest = material.eos.rest_density;
    for (std::size_t i = first; i < fill.position.size(); ++i) {
      double p = 0;
      if (body.hydrostatic) {
        p = hydrostatic_pressure(material.eos, g,
                                 column_top.at(column(fill.position[i])) + 0.5 * dx - fill.position[i].z());
      }
      const double rho = body.hydrostatic ? material.eos.density(p) : rest;
      // An elastic-plastic layer under gravity with a component along the bed (a slope by
      // tilted gravity) starts in its static state: dS_xz/dz = -rho g_x, so S_xz = p g_x / |g_z|
      // (likewise yz), returned onto the yield surface, rather than building it from S = 0
      // under a sudden load, whose dynamic overshoot can reach twice the static shear.
      double shear_xz = 0, shear_yz = 0;
      if (body.hydrostatic && material.rheology == scene::Material::Rheology::elastic_plastic && g > 0) {
        shear_xz = p * scene.run.gravity.x() / g;
        shear_yz = p * scene.run.gravity.y() / g;
        const double equivalent = std::sqrt(3.0 * (shear_xz * shear_xz + shear_yz * shear_yz));
        if (equivalent > material.yield_stress) {
          shear_xz *= material.yield_stress / equivalent;
          shear_yz *= material.yield_stress / equivalent;
        }
      }
      if (with_stress) fill.stress.insert(fill.stress.end(), {0.0, 0.0, 0.0, 0.0, shear_yz, shear_xz});
      fill.velocity.push_back(body.velocity);
      fill.density.push_back(rho);
      fill.pressure.push_back(material.eos.pressure(rho));
      // Mass rho dx^3: every particle's volume m / rho is its lattice cell, as a wall particle's
      // is. With rho0 dx^3 a compressed particle's volume falls short of its cell by rho / rho0 - 1
      // (p / (rho0 c^2), 1 % at the bottom of S4's tank), so the pressure sums, over the lattice,
      // left the bulk short of its weight by that much and pushed the fluid next to a wall
      // particle away from it by 6 % of g at the bottom (S4's start-up 5.2e-3 sqrt(gH); 1.4e-3 now).
      fill.mass.push_back(rho * dx * dx * dx);
      fill.material.push_back(body_material[b]);
      fill.body.push_back(static_cast<std::uint32_t>(b));
    }
  }
  return fill;
}

}  // namespace sabo::sph
