#include "libsabo/scene/warnings.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>

#include "libsabo/scene/sensor_patch.hpp"

namespace sabo::scene {
namespace {

std::string located(const Origin& origin, const std::string& problem, const std::string& fix) {
  return fmt::format("{}:{}: key '{}': warning: {}. Fix: {}.", origin.file.string(), origin.line, origin.key, problem,
                     fix);
}

bool fluid_touches(const Scene& scene, const FluidBody& fluid, const Structure& structure) {
  // Boundary-particle walls sample every structure surface; the penalty walls follow the pair's settings.
  return scene.sph.wall_model == SphSettings::WallModel::boundary_particles ||
         scene.surface_contact(fluid.name, structure.name).enabled;
}

// A sensor box on a fluid-loaded face that is narrower along the face than the particle spacing dx: the
// patch holds at most a row of wall particles (or a few fluid contacts), so its reading jumps as the fluid
// particles pass and its mean pressure is not the local one. The patch's width along the face is taken as
// the middle extent of the box clipped to the part's bounds (exact for a face normal to an axis).
void warn_narrow_sensors(const Scene& scene, std::vector<std::string>& warnings) {
  if (scene.fluids.empty()) return;
  const double dx = scene.sph.particle_spacing;
  for (const Sensor& sensor : scene.sensors) {
    const auto patch = sensor_patch(scene.structures, sensor);
    if (!patch || patch->area <= 0) continue;
    const Vec3 lo = sensor.box->min.cwiseMax(patch->part_bounds.min);
    const Vec3 hi = sensor.box->max.cwiseMin(patch->part_bounds.max);
    std::array<double, 3> extent{hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z()};
    std::sort(extent.begin(), extent.end());
    const double width = extent[1];
    if (width >= dx && patch->area >= dx * dx) continue;
    warnings.push_back(located(
        sensor.origin,
        fmt::format("sensor \"{}\" covers {:.3g} m^2 of \"{}\", {:.3g} m wide along the face, narrower than the "
                    "particle spacing sph.particle_spacing = {:g} m: it holds at most a row of wall particles, so "
                    "its force jumps as fluid particles pass and its mean pressure is smeared over the kernel's "
                    "2h",
                    sensor.name, patch->area, sensor.part, width, dx),
        fmt::format("make the box at least {:g} m wide along the face (a few spacings for a steady pressure), or "
                    "refine sph.particle_spacing below the sensor's width",
                    dx)));
  }
}

// tcp without CURVE: whoever reaches the port joins the run (docs/security.md).
void warn_insecure_tcp(const Scene& scene, std::vector<std::string>& warnings) {
  if (!scene.run.tcp_in_clear(scene.run.endpoint)) return;
  const bool every_interface = scene.run.endpoint.starts_with("tcp://0.0.0.0:");
  warnings.push_back(
      located(scene.run.endpoint_origin,
              fmt::format("run.tcp_security = \"none\" over {}: any process that reaches the port{} can register as a "
                          "solver, read the run's state every step and send forces; nothing is encrypted",
                          scene.run.endpoint, every_interface ? ", on any interface of this machine," : ""),
              "remove tcp_security (CURVE is the default), or listen on this machine only with endpoint = \"tcp\""));
}

}  // namespace

std::vector<std::string> scene_warnings(const Scene& scene) {
  std::vector<std::string> warnings;
  const std::size_t bodies = scene.fluids.size() + scene.particle_sets.size() + scene.structures.size();
  for (const Structure& structure : scene.structures) {
    if (!structure.rigid && bodies == 1) continue;
    const bool by_set = std::any_of(scene.particle_sets.begin(), scene.particle_sets.end(), [&](const ParticleSet& s) {
      return scene.surface_contact(s.name, structure.name).enabled;
    });
    const bool by_fluid = std::any_of(scene.fluids.begin(), scene.fluids.end(),
                                      [&](const FluidBody& f) { return fluid_touches(scene, f, structure); });
    const bool by_structure = std::any_of(scene.structures.begin(), scene.structures.end(), [&](const Structure& o) {
      return scene.fem_fem_contact(structure.name, o.name).enabled;
    });
    if (by_set || by_fluid || by_structure) continue;
    std::vector<std::string> off;
    if (!scene.particle_sets.empty()) off.emplace_back("particle sets");
    if (!scene.fluids.empty()) off.emplace_back("fluids");
    if (scene.structures.size() > 1) off.emplace_back("other structures");
    const std::string why =
        off.empty() ? "the scene has no other body"
                    : fmt::format("none of the scene's {} has contact with it enabled", fmt::join(off, " and "));
    const std::string load = structure.rigid ? "a rigid structure that nothing touches does nothing"
                                             : "it feels its own weight and nothing else";
    warnings.push_back(located(structure.origin,
                               fmt::format("nothing can touch structure \"{}\": {}; {}", structure.name, why, load),
                               "give it a contact: an [[interactions]] pair that names it without `enabled = false` "
                               "(or remove the one that switches it off), [contact.fem_fem] `enabled = true` for "
                               "the other structures; or remove the structure"));
  }
  warn_narrow_sensors(scene, warnings);
  warn_insecure_tcp(scene, warnings);
  for (const SolverSettings& solver : scene.solvers) {
    if (solver.beta <= 1) continue;
    warnings.push_back(located(
        {solver.origin.file, solver.origin.line, solver.origin.key + ".beta"},
        fmt::format("beta = {:g} takes steps {:g} times the {}'s stable step: the run may become unstable", solver.beta,
                    solver.beta, role_name(solver.role)),
        "keep beta <= 1 unless you are looking for where the step breaks (the instability check stops the run at the "
        "step it does)"));
  }
  return warnings;
}

}  // namespace sabo::scene
