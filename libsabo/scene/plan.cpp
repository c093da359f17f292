#include "libsabo/scene/plan.hpp"

#include <cmath>

#include "libsabo/scene/estimate.hpp"
#include "libsabo/scene/names.hpp"

namespace sabo::scene {

nlohmann::json launch_plan(const Scene& scene, const std::filesystem::path& bin_dir) {
  const std::filesystem::path bin = std::filesystem::absolute(bin_dir).lexically_normal();
  nlohmann::json plan;
  plan["scene"] = scene.file.string();
  plan["end_time"] = scene.run.end_time;
  plan["output_interval"] = scene.run.output_interval;
  plan["hang_timeout"] = scene.run.hang_timeout;
  plan["registration_timeout"] = scene.run.registration_timeout;
  if (scene.run.max_dt) plan["max_dt"] = *scene.run.max_dt;
  plan["endpoint"] = scene.run.endpoint;
  plan["tcp_security"] = name_of(scene.run.tcp_security);
  if (!scene.run.connect_host.empty()) plan["connect_host"] = scene.run.connect_host;
  plan["restart"] = scene.run.restart ? "auto" : "off";
  plan["max_restarts"] = scene.run.max_restarts;

  nlohmann::json processes = nlohmann::json::array();
  processes.push_back({{"role", "coupler"}, {"command", {(bin / "coupler").string()}}});
  for (const Role role : kRoles) {
    const SolverSettings* solver = scene.solver(role);
    if (solver == nullptr) continue;
    nlohmann::json command = nlohmann::json::array();
    if (solver->command.empty()) {
      command.push_back((bin / role_name(role)).string());
    } else {
      for (const auto& word : solver->command) command.push_back(word);
    }
    nlohmann::json process = {{"role", role_name(role)}, {"command", command}, {"beta", solver->beta}};
    if (!solver->launcher.empty()) process["launcher"] = solver->launcher;
    if (solver->by_hand) process["by_hand"] = true;
    processes.push_back(std::move(process));
  }
  plan["processes"] = processes;

  std::size_t spheres = 0;
  for (const auto& set : scene.particle_sets) {
    spheres += set.kind == ParticleSet::Kind::list ? set.spheres.size() : set.count;
  }
  plan["bodies"] = {{"fluids", scene.fluids.size()},
                    {"particle_sets", scene.particle_sets.size()},
                    {"spheres", spheres},
                    {"structures", scene.structures.size()},
                    {"materials", scene.materials.size()}};
  const SceneEstimate e = estimate_scene(scene);
  plan["estimate"] = {{"fluid_particles", e.total_fluid_particles()},
                      {"wall_particles", e.wall_particles},
                      {"spheres", e.total_spheres()},
                      {"elements", e.total_elements()},
                      {"surface_triangles", e.total_surface_triangles()},
                      {"steps", e.steps},
                      {"dt", std::isfinite(e.dt) ? e.dt : 0.0},
                      {"dt_set_by", e.dt_what},
                      {"outputs", e.outputs},
                      {"memory_bytes", e.memory_bytes},
                      {"max_message_bytes", max_message_bytes(e)}};
  return plan;
}

}  // namespace sabo::scene
