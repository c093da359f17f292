#include "tests/support/one_boulder.hpp"

namespace sabo::testing {

void add_one_boulder(scene::Scene& scene) {
  scene::Material rock;
  rock.name = "rock";
  rock.density = 3000;
  rock.youngs_modulus = 30e9;
  rock.poisson_ratio = 0.3;
  scene.materials.push_back(rock);
  scene::ParticleSet set;
  set.name = "boulders";
  set.material = "rock";
  set.spheres.push_back({Vec3(0, 0, 1), 0.5, Vec3::Zero(), Vec3::Zero()});
  scene.particle_sets.push_back(set);
  scene::SolverSettings dem;
  dem.role = sabo::Role::dem;
  scene.solvers.push_back(dem);
}

sabo::v1::Register boulder_registration(const std::string& name) {
  sabo::v1::Register r;
  r.set_protocol_version(protocol::kProtocolVersion);
  r.set_role(sabo::protocol::to_wire(sabo::Role::dem));
  r.set_name(name);
  r.set_pid(static_cast<std::uint32_t>(::getpid()));
  r.set_exposes_particles(true);
  r.set_exposes_angular_velocity(true);
  auto* t = r.mutable_particles();
  t->add_id(0), t->add_radius(0.5), t->add_mass(1570.8), t->add_material(0), t->add_body(0);
  return r;
}

sabo::v1::StepState boulder_state(std::uint64_t step, double time, double stable_dt) {
  sabo::v1::StepState state;
  state.set_step(step);
  state.set_time(time);
  state.set_stable_dt(stable_dt);
  state.add_index(0);
  for (double v : {0.0, 0.0, 1.0}) state.add_position(v);
  for (int c = 0; c < 3; ++c) state.add_velocity(0), state.add_angular_velocity(0);
  return state;
}

}  // namespace sabo::testing
