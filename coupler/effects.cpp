#include "coupler/effects.hpp"

#include <algorithm>
#include <set>

#include "libsabo/scene/names.hpp"

namespace sabo::coupler {

namespace {

double compute_seconds(const nlohmann::json& processes, const char* name) {
  const auto it = processes.find(name);
  if (it == processes.end() || !it->contains("compute_seconds")) return 0;
  return (*it)["compute_seconds"].get<double>();
}

const scene::Material& material_named(const scene::Scene& scene, const std::string& name) {
  return scene.materials[scene.material_index(name)];
}

}  // namespace

nlohmann::json solver_effects(const scene::Scene& scene, const nlohmann::json& processes) {
  using nlohmann::json;
  json effects = json::array();
  if (scene.needs(Role::dem)) {
    const auto& c = scene.dem_contact;
    effects.push_back({{"effect", "dem_dem_contact"},
                       {"process", "dem_solver"},
                       {"seconds", compute_seconds(processes, "dem_solver")}});
    if (c.friction > 0) effects.push_back({{"effect", "dem_sliding_friction"}, {"process", "dem_solver"}});
    if (c.rolling_friction > 0) effects.push_back({{"effect", "dem_rolling_friction"}, {"process", "dem_solver"}});
  }
  if (scene.needs(Role::sph)) {
    std::set<std::string> rheologies;
    for (const auto& fluid : scene.fluids)
      rheologies.insert(std::string(scene::name_of(material_named(scene, fluid.material).rheology)));
    effects.push_back({{"effect", "sph_fluid"},
                       {"process", "sph_solver"},
                       {"seconds", compute_seconds(processes, "sph_solver")},
                       {"rheologies", rheologies}});
    // Inflow hydrographs: each one's peak discharge and its volume over the run.
    json inflows = json::object();
    for (const auto& fluid : scene.fluids) {
      if (fluid.shape != scene::FluidBody::Shape::inflow) continue;
      inflows[fluid.name] = {{"peak_discharge", fluid.inflow.peak_discharge()},
                             {"volume", fluid.inflow.volume(0.0, scene.run.end_time)}};
    }
    if (!inflows.empty()) {
      effects.push_back({{"effect", "sph_inflow_hydrograph"}, {"process", "sph_solver"}, {"inflows", inflows}});
    }
  }
  if (scene.needs(Role::fem)) {
    const bool deformable = std::any_of(scene.structures.begin(), scene.structures.end(),
                                        [](const scene::Structure& s) { return !s.rigid; });
    effects.push_back({{"effect", deformable ? "fem_deformable_structures" : "fem_rigid_structures"},
                       {"process", "fem_solver"},
                       {"seconds", compute_seconds(processes, "fem_solver")}});
    bool plastic = false, erosion = false;
    for (const auto& s : scene.structures) {
      if (s.rigid) continue;
      const auto& m = material_named(scene, s.material);
      plastic = plastic || m.yield_stress.has_value();
      erosion = erosion || m.failure_strain.has_value();
    }
    if (plastic) effects.push_back({{"effect", "fem_plasticity"}, {"process", "fem_solver"}});
    if (erosion) effects.push_back({{"effect", "fem_erosion"}, {"process", "fem_solver"}});
    // Ground from elevation rasters: which raster, its size and its coordinate system, per structure.
    json rasters = json::object();
    for (const auto& s : scene.structures) {
      if (s.shape.type == scene::Shape::Type::terrain) rasters[s.name] = s.shape.raster;
    }
    if (!rasters.empty()) {
      effects.push_back({{"effect", "fem_terrain_from_raster"}, {"process", "fem_solver"}, {"rasters", rasters}});
    }
  }
  return effects;
}

}  // namespace sabo::coupler
