// The coupler against a scripted sph_solver and fem_solver over a real ipc
// socket, in both SPH wall models: penalty (SPH particles as slave nodes,
// eqs. 3-6 with friction) and boundary particles (the FEM surface sampled for
// the fluid, the fluid's force on them returned to the FEM nodes).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <future>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>

#include "coupler/coupler.hpp"
#include "coupler_fixture.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "libsabo/geometry/surface_sampling.hpp"
#include "libsabo/io/traffic.hpp"
#include "libsabo/protocol/solver_link.hpp"
#include "libsabo/protocol/surface_codec.hpp"
#include "libsabo/protocol/wire.hpp"

using namespace sabo;
using namespace std::chrono_literals;

namespace {

constexpr double kDx = 0.1;            // m, SPH particle spacing
constexpr double kStiffness = 1e4;     // N/m, explicit SPH-FEM penalty stiffness
constexpr double kFriction = 0.3;      // SPH-FEM Coulomb coefficient
constexpr double kSphStableDt = 1e-3;  // s

// A 1 m x 1 m floor at z = 0, normal up, in 8 triangles.
geometry::SurfaceMesh floor_mesh() {
  scene::Shape shape;
  shape.type = scene::Shape::Type::plane;
  shape.origin = Vec3::Zero();
  shape.length = 1;
  shape.width = 1;
  shape.element_size = 0.5;
  auto mesh = geometry::triangulate(shape, "floor");
  mesh.face_bulk_modulus.assign(mesh.face_count(), 1e9);
  return mesh;
}

struct SphFixture : sabo::testing::CouplerFixture {
  void SetUp() override {
    CouplerFixture::SetUp();
    scene.run.end_time = 0.02;
    scene.run.output_interval = 0.01;
    scene.run.hang_timeout = 2.0;
    for (auto [name, density, youngs_modulus, poisson_ratio] :
         {std::tuple{"concrete", 2400.0, 30e9, 0.2}, std::tuple{"water", 1000.0, 2.2e9, 0.0}}) {
      scene::Material material;
      material.name = name;
      material.density = density;
      material.youngs_modulus = youngs_modulus;
      material.poisson_ratio = poisson_ratio;
      scene.materials.push_back(material);
    }
    scene::FluidBody water;
    water.name = "water";
    water.material = "water";
    scene.fluids.push_back(water);
    scene::Structure floor;
    floor.name = "floor";
    floor.material = "concrete";
    scene.structures.push_back(floor);
    scene.sph.particle_spacing = kDx;
    scene.sph.smoothing_ratio = 1.3;
    scene.sph_fem_default.normal_stiffness = kStiffness;
    scene.sph_fem_default.friction = kFriction;
    for (auto role : {sabo::Role::sph, sabo::Role::fem}) {
      scene::SolverSettings s;
      s.role = role;
      s.beta = 1.0;
      scene.solvers.push_back(s);
    }
  }

  nlohmann::json summary() const {
    std::ifstream file(dir / "summary.json");
    return nlohmann::json::parse(file);
  }

  // Rows of forces.csv for (part, source): the mean force of each output interval.
  std::vector<Vec3> force_rows(const std::string& part, const std::string& source) const {
    std::ifstream file(dir / "forces.csv");
    std::string line;
    std::getline(file, line);
    std::vector<Vec3> rows;
    while (std::getline(file, line)) {
      std::stringstream ss(line);
      std::vector<std::string> cell;
      for (std::string c; std::getline(ss, c, ',');) cell.push_back(c);
      if (cell.size() >= 6 && cell[1] == part && cell[2] == source) {
        rows.emplace_back(std::stod(cell[3]), std::stod(cell[4]), std::stod(cell[5]));
      }
    }
    return rows;
  }

  void run_boundary_exchange(std::uint64_t steps_back);
  void check_recorded_walls(const std::vector<sabo::v1::StepState>& sent_states,
                            const std::vector<sabo::v1::StepForces>& received_forces, std::uint64_t steps_back) const;
  void run_penalty_slide(sabo::v1::StepForces& last_sph);

  static sabo::v1::Register sph_registration(const std::vector<Vec3>& particles) {
    sabo::v1::Register r;
    r.set_protocol_version(protocol::kProtocolVersion);
    r.set_role(sabo::protocol::to_wire(sabo::Role::sph));
    r.set_name("scripted sph");
    r.set_pid(static_cast<std::uint32_t>(::getpid()));
    r.set_exposes_particles(true);
    auto* t = r.mutable_particles();
    for (std::size_t i = 0; i < particles.size(); ++i) {
      t->add_id(i), t->add_radius(0.5 * kDx), t->add_mass(1000 * kDx * kDx * kDx), t->add_material(1), t->add_body(0);
    }
    return r;
  }

  static sabo::v1::Register fem_registration() {
    sabo::v1::Register r;
    r.set_protocol_version(protocol::kProtocolVersion);
    r.set_role(sabo::protocol::to_wire(sabo::Role::fem));
    r.set_name("scripted fem");
    r.set_pid(static_cast<std::uint32_t>(::getpid()));
    r.set_exposes_surface(true);
    protocol::surface_to_message(floor_mesh(), 1, *r.mutable_surface());
    return r;
  }

  static void fill_sph_state(sabo::v1::StepState& state, std::uint64_t step, double time,
                             const std::vector<Vec3>& position, const Vec3& velocity) {
    state.Clear();
    state.set_step(step);
    state.set_time(time);
    state.set_stable_dt(kSphStableDt);
    for (std::size_t i = 0; i < position.size(); ++i) {
      state.add_index(static_cast<std::uint32_t>(i));
      for (int c = 0; c < 3; ++c) state.add_position(position[i][c]), state.add_velocity(velocity[c]);
    }
  }

  static void fill_fem_state(sabo::v1::StepState& state, std::uint64_t step, double time) {
    state.Clear();
    state.set_step(step);
    state.set_time(time);
    state.set_stable_dt(std::numeric_limits<double>::infinity());
  }
};

Vec3 sum3(const google::protobuf::RepeatedField<double>& values) {
  Vec3 sum = Vec3::Zero();
  for (int i = 0; i + 2 < values.size(); i += 3) sum += Vec3(values[i], values[i + 1], values[i + 2]);
  return sum;
}

}  // namespace

// Drives four sliding SPH particles 1 cm into the floor to the end; last_sph: the last forces on them.
void SphFixture::run_penalty_slide(sabo::v1::StepForces& last_sph) {
  scene.sph.wall_model = scene::SphSettings::WallModel::penalty;
  auto coupler = start_coupler();
  // Four particles of contact radius dx/2 = 0.05 m, 1 cm into the floor, sliding at 1 m/s.
  // Away from the triangles' diagonals: one face contact each.
  const std::vector<Vec3> particles{{-0.15, -0.3, 0.04}, {0.15, -0.3, 0.04}, {-0.15, 0.3, 0.04}, {0.15, 0.3, 0.04}};
  const Vec3 sliding(1.0, 0, 0);
  protocol::SolverLink sph(endpoint, 5000ms), fem(endpoint, 5000ms);
  fem.register_solver(fem_registration());
  sph.register_solver(sph_registration(particles));
  sabo::v1::StepState sph_state, fem_state;
  double time = 0;
  sabo::v1::StepForces last_fem;
  std::uint64_t steps = 0;
  for (std::uint64_t step = 0;; ++step) {
    fill_sph_state(sph_state, step, time, particles, sliding);
    fill_fem_state(fem_state, step, time);
    sph.send_state(sph_state);
    fem.send_state(fem_state);
    last_sph = sph.receive_forces(step);
    last_fem = fem.receive_forces(step);
    ASSERT_EQ(last_sph.force_size(), 12);
    EXPECT_EQ(last_sph.torque_size(), 0) << "SPH particles take no torque";
    EXPECT_DOUBLE_EQ(last_sph.dt(), kSphStableDt) << "dt = min(beta * stable_dt, contact limit)";
    const Vec3 on_particles = sum3(last_sph.force());
    const Vec3 on_floor = sum3(last_fem.node_force());
    EXPECT_LT((on_particles + on_floor).norm(), 1e-10 * on_particles.norm()) << "Newton, step " << step;
    ASSERT_FALSE(last_sph.interest_all());
    ASSERT_GE(last_sph.interest_size(), 1);
    steps = step + 1;
    if (last_sph.stop()) break;
    time += last_sph.dt();
  }
  sabo::v1::Goodbye goodbye;
  goodbye.set_steps(steps);
  goodbye.set_reason("completed");
  sph.send_goodbye(goodbye);
  fem.send_goodbye(goodbye);
  EXPECT_EQ(coupler.get(), coupler::kCompleted);
}

TEST_F(SphFixture, PenaltyWallPushesSphParticlesWithFrictionAndTheFloorFeelsTheReaction) {
  sabo::v1::StepForces last_sph;
  run_penalty_slide(last_sph);
  // Normal: k delta = 1e4 N/m * 0.01 m = 100 N per particle; after 20 steps of
  // 1 mm the tangential spring (k_t = k_n) would exceed mu F_n: sliding at 30 N.
  for (int i = 0; i < 4; ++i) {
    const Vec3 f(last_sph.force(3 * i), last_sph.force(3 * i + 1), last_sph.force(3 * i + 2));
    std::cout << "particle " << i << ": normal force measured " << f.z() << " N expected 100; tangential " << f.x()
              << " N expected " << -kFriction * 100 << "\n";
    EXPECT_NEAR(f.z(), kStiffness * 0.01, 1e-9);
    EXPECT_NEAR(f.x(), -kFriction * kStiffness * 0.01, 1e-9);
    EXPECT_NEAR(f.y(), 0, 1e-12);
  }
  const auto s = summary();
  std::cout << "Newton residual " << s["newton_third_law"]["max_relative_residual"] << "\n";
  EXPECT_LT(s["newton_third_law"]["max_relative_residual"].get<double>(), 1e-12);
  EXPECT_EQ(s["newton_third_law"]["violations"], 0);
  const auto rows = force_rows("floor", "fluid");
  ASSERT_FALSE(rows.empty());
  std::cout << "forces.csv floor/fluid last row: " << rows.back().transpose() << " N (expected 0.3*400, 0, -400)\n";
  EXPECT_NEAR(rows.back().z(), -400, 1e-6);
  EXPECT_NEAR(rows.back().x(), 120, 1e-6);
  bool listed = false;
  for (const auto& e : s["active_effects"]) listed = listed || e["effect"] == "sph_fem_penalty_contact";
  EXPECT_TRUE(listed);
}

// steps_back: 1, the fake answers for the boundary particles it just received
// (boundary_step absent); 2, for those of the reply before (boundary_step = n - 2).
void SphFixture::run_boundary_exchange(std::uint64_t steps_back) {
  scene.sph.wall_model = scene::SphSettings::WallModel::boundary_particles;
  scene.run.end_time = 0.005;
  // The walls and the fluid's forces on them go into traffic.h5 (docs/traffic.md).
  scene.recording.enabled = true;
  scene.recording.fields = {"boundary_particles", "boundary_force"};
  auto coupler = start_coupler();
  // One fluid particle dx/2 above the floor, moving from its edge (x = -0.5 m)
  // towards its centre by dx per step, so that the set of wall particles near
  // it grows; one far above (no wall near it).
  std::vector<Vec3> particles{{-0.5, 0.0, 0.05}, {0.0, 0.0, 5.0}};
  protocol::SolverLink sph(endpoint, 5000ms), fem(endpoint, 5000ms);
  fem.register_solver(fem_registration());
  sph.register_solver(sph_registration(particles));

  // What the coupler should send: every sampled particle within the support of the first fluid particle.
  const auto mesh = floor_mesh();
  const double support = scene.sph.kernel_support();
  const auto sampling = geometry::sample_surface(mesh, kDx, 3);
  auto expected_near = [&](const Vec3& fluid) {
    std::vector<Vec3> near;
    for (std::size_t k = 0; k < sampling.size(); ++k) {
      const Vec3 x = geometry::boundary_particle_position(mesh, sampling, k);
      if ((x - fluid).norm() <= support) near.push_back(x);
    }
    return near;
  };

  sabo::v1::StepState sph_state, fem_state;
  double time = 0;
  // The fake's answer for the particles of step k: a pressure-like push down
  // and a shear, different per particle and step.
  auto answer = [](std::size_t n, std::uint64_t k) {
    std::vector<double> f(3 * n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      f[3 * i] = 0.01 * static_cast<double>(i);
      f[3 * i + 2] = -1.0 - 0.1 * static_cast<double>(i % 4) - static_cast<double>(k);
    }
    return f;
  };
  std::vector<std::size_t> received;  // boundary particle count of each step's reply
  std::vector<double> returned;
  Vec3 returned_sum = Vec3::Zero();
  std::uint64_t steps = 0;
  std::vector<sabo::v1::StepState> sent_states;
  std::vector<sabo::v1::StepForces> received_forces;
  for (std::uint64_t step = 0;; ++step) {
    particles[0].x() = -0.5 + kDx * static_cast<double>(step);
    const auto expected = expected_near(particles[0]);
    fill_sph_state(sph_state, step, time, particles, Vec3::Zero());
    returned.clear();
    returned_sum.setZero();
    if (step >= steps_back) {
      const std::uint64_t k = step - steps_back;
      returned = answer(received[k], k);
      for (std::size_t i = 0; i < received[k]; ++i) {
        returned_sum += Vec3(returned[3 * i], returned[3 * i + 1], returned[3 * i + 2]);
      }
      if (steps_back == 2) sph_state.set_boundary_step(k);
    }
    sph_state.mutable_boundary_force()->Assign(returned.begin(), returned.end());
    fill_fem_state(fem_state, step, time);
    sph.send_state(sph_state);
    fem.send_state(fem_state);
    const auto forces = sph.receive_forces(step);
    const auto& fem_forces = fem.receive_forces(step);
    sent_states.push_back(sph_state);
    received_forces.push_back(forces);
    // The fluid gets no penalty force: the walls act through its own sums, and a StepForces lists only the
    // particles that carry a force.
    ASSERT_EQ(forces.index_size(), 0);
    ASSERT_EQ(forces.force_size(), 0);
    const auto n = static_cast<std::size_t>(forces.boundary_volume_size());
    received.push_back(n);
    ASSERT_EQ(n, expected.size()) << "step " << step;
    ASSERT_EQ(forces.boundary_position_size(), static_cast<int>(3 * n));
    // A rigid wall is at rest: its velocities and accelerations are not sent (empty means zero).
    ASSERT_EQ(forces.boundary_velocity_size(), 0);
    ASSERT_EQ(forces.boundary_normal_size(), static_cast<int>(3 * n));
    ASSERT_EQ(forces.boundary_acceleration_size(), 0);
    for (int k = 0; k < static_cast<int>(n); ++k) {
      const Vec3 x(forces.boundary_position(3 * k), forces.boundary_position(3 * k + 1),
                   forces.boundary_position(3 * k + 2));
      EXPECT_LT((x - expected[static_cast<std::size_t>(k)]).norm(), 1e-12);
      EXPECT_EQ(forces.boundary_normal(3 * k + 2), 1.0);
      EXPECT_DOUBLE_EQ(forces.boundary_volume(k), kDx * kDx * kDx);
    }
    // The floor feels exactly what the fluid put on the boundary particles of step n - steps_back.
    const Vec3 on_floor = sum3(fem_forces.node_force());
    std::cout << "steps back " << steps_back << ", step " << step << ": " << n << " boundary particles sent (expected "
              << expected.size() << "); floor force " << on_floor.transpose() << " N, returned boundary forces "
              << returned_sum.transpose() << " N\n";
    EXPECT_LT((on_floor - returned_sum).norm(), 1e-12 * (1 + returned_sum.norm()));
    ASSERT_FALSE(forces.interest_all());
    ASSERT_GE(forces.interest_size(), 1);
    for (const auto& box : forces.interest()) EXPECT_LT(box.max_z(), 1.0) << "the far particle need not be sent";
    steps = step + 1;
    if (forces.stop()) break;
    time += forces.dt();
  }
  sabo::v1::Goodbye goodbye;
  goodbye.set_steps(steps);
  sph.send_goodbye(goodbye);
  fem.send_goodbye(goodbye);
  EXPECT_EQ(coupler.get(), coupler::kCompleted);
  const auto s = summary();
  std::cout << "Newton residual " << s["newton_third_law"]["max_relative_residual"] << "\n";
  EXPECT_LT(s["newton_third_law"]["max_relative_residual"].get<double>(), 1e-12);
  EXPECT_EQ(s["newton_third_law"]["violations"], 0);
  const auto rows = force_rows("floor", "fluid");
  ASSERT_FALSE(rows.empty());
  EXPECT_LT(rows.back().z(), 0.0) << "the floor is pushed down by the fluid";
  bool listed = false;
  for (const auto& e : s["active_effects"]) listed = listed || e["effect"] == "sph_fem_boundary_particles";
  EXPECT_TRUE(listed);
  check_recorded_walls(sent_states, received_forces, steps_back);
}

// traffic.h5 holds, for every step, the wall particles the fluid received
// and the forces it returned, bit for bit, with consistent sizes: a replayed
// sph_solver gets its walls, the structure's side sees the fluid's forces.
void SphFixture::check_recorded_walls(const std::vector<sabo::v1::StepState>& sent_states,
                                      const std::vector<sabo::v1::StepForces>& received_forces,
                                      std::uint64_t steps_back) const {
  auto same = [](const auto& recorded, const auto& sent) {
    return std::equal(recorded.begin(), recorded.end(), sent.begin(), sent.end());
  };
  io::TrafficReader reader(dir / "traffic.h5");
  ASSERT_EQ(reader.steps("sph_solver").size(), sent_states.size());
  ASSERT_EQ(reader.force_steps("sph_solver").size(), received_forces.size());
  std::size_t recorded_walls = 0, recorded_wall_forces = 0;
  for (std::uint64_t step = 0; step < sent_states.size(); ++step) {
    const auto forces = reader.forces("sph_solver", step);
    const auto& received = received_forces[step];
    EXPECT_TRUE(same(forces.boundary_position(), received.boundary_position())) << "step " << step;
    EXPECT_TRUE(same(forces.boundary_velocity(), received.boundary_velocity())) << "step " << step;
    EXPECT_TRUE(same(forces.boundary_normal(), received.boundary_normal())) << "step " << step;
    EXPECT_TRUE(same(forces.boundary_acceleration(), received.boundary_acceleration())) << "step " << step;
    EXPECT_TRUE(same(forces.boundary_volume(), received.boundary_volume())) << "step " << step;
    EXPECT_EQ(forces.boundary_position_size(), 3 * forces.boundary_volume_size()) << "step " << step;
    EXPECT_EQ(forces.force_size(), 0) << "not selected, not recorded";
    recorded_walls += static_cast<std::size_t>(forces.boundary_volume_size());

    const auto state = reader.state("sph_solver", step);
    const auto& sent = sent_states[step];
    EXPECT_TRUE(same(state.boundary_force(), sent.boundary_force())) << "step " << step;
    EXPECT_EQ(state.has_boundary_step(), sent.has_boundary_step()) << "step " << step;
    EXPECT_EQ(state.boundary_step(), sent.boundary_step()) << "step " << step;
    EXPECT_EQ(state.position_size(), 0) << "not selected, not recorded";
    recorded_wall_forces += static_cast<std::size_t>(state.boundary_force_size() / 3);
    if (step >= steps_back) {
      // The forces answer the walls of StepForces boundary_step (n - 1 when absent).
      const std::uint64_t answered = state.has_boundary_step() ? state.boundary_step() : step - 1;
      EXPECT_EQ(answered, step - steps_back);
      EXPECT_EQ(state.boundary_force_size(), reader.forces("sph_solver", answered).boundary_position_size())
          << "step " << step;
    }
  }
  std::cout << "traffic.h5: " << sent_states.size() << " steps, " << recorded_walls << " wall particles and "
            << recorded_wall_forces << " wall forces recorded\n";
  EXPECT_GT(recorded_walls, 0u);
  EXPECT_GT(recorded_wall_forces, 0u);
}

TEST_F(SphFixture, BoundaryParticlesGoToTheFluidAndTheirForcesToTheNodes) {
  run_boundary_exchange(1);
}

TEST_F(SphFixture, BoundaryForcesMayAnswerTheReplyBeforeTheLast) {
  run_boundary_exchange(2);
}

TEST_F(SphFixture, PenaltyPairTakesTheInteractionNamingTheFluid) {
  scene::Interaction interaction;
  interaction.a = "floor";  // either order
  interaction.b = "water";
  interaction.fluid = true;
  interaction.contact = scene.sph_fem_default;
  interaction.contact.friction = 0.1;
  scene.interactions.push_back(interaction);
  sabo::v1::StepForces last_sph;
  run_penalty_slide(last_sph);
  std::cout << "tangential force with the interaction's mu = 0.1: measured " << last_sph.force(0)
            << " N expected -10\n";
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(last_sph.force(3 * i), -0.1 * kStiffness * 0.01, 1e-9);
}

TEST_F(SphFixture, WrongBoundaryForceCountEndsTheRunNamingTheSphSolver) {
  scene.sph.wall_model = scene::SphSettings::WallModel::boundary_particles;
  auto coupler = start_coupler();
  const std::vector<Vec3> particles{{0.0, 0.0, 0.05}};
  protocol::SolverLink sph(endpoint, 5000ms), fem(endpoint, 5000ms);
  fem.register_solver(fem_registration());
  sph.register_solver(sph_registration(particles));
  sabo::v1::StepState sph_state, fem_state;
  fill_sph_state(sph_state, 0, 0, particles, Vec3::Zero());
  fill_fem_state(fem_state, 0, 0);
  sph.send_state(sph_state);
  fem.send_state(fem_state);
  const double dt = sph.receive_forces(0).dt();
  fem.receive_forces(0);
  fill_sph_state(sph_state, 1, dt, particles, Vec3::Zero());
  for (int c = 0; c < 3; ++c) sph_state.add_boundary_force(1.0);  // one particle's worth, not all
  sph.send_state(sph_state);
  EXPECT_THROW(sph.receive_forces(1), StopRequested);
  EXPECT_EQ(coupler.get(), coupler::kSolverFailed);
  const auto s = summary();
  std::cout << "failure: " << s["failure"].get<std::string>() << "\n";
  EXPECT_NE(s["failure"].get<std::string>().find("sph_solver"), std::string::npos);
  EXPECT_NE(s["failure"].get<std::string>().find("boundary_force"), std::string::npos);
}

// Issue 18, item 3: a force the coupler computes that is not finite ends the run naming the entity before it
// reaches a solver (finite but extreme states, here particles 1 cm into the floor approaching it at 1e308 m/s
// against a normal dashpot, make the contact law overflow). Before, the forces went out as they were.
TEST_F(SphFixture, ANonFiniteContactForceEndsTheRunNamingTheEntity) {
  scene.sph.wall_model = scene::SphSettings::WallModel::penalty;
  scene.sph_fem_default.normal_damping_ratio = 0.5;
  auto coupler = start_coupler();
  const std::vector<Vec3> particles{{-0.15, -0.3, 0.04}, {0.15, -0.3, 0.04}};
  protocol::SolverLink sph(endpoint, 5000ms), fem(endpoint, 5000ms);
  fem.register_solver(fem_registration());
  sph.register_solver(sph_registration(particles));
  sabo::v1::StepState sph_state, fem_state;
  fill_sph_state(sph_state, 0, 0, particles, Vec3(0, 0, -1e308));
  fill_fem_state(fem_state, 0, 0);
  sph.send_state(sph_state);
  fem.send_state(fem_state);
  EXPECT_THROW(sph.receive_forces(0), StopRequested);
  EXPECT_EQ(coupler.get(), coupler::kSolverFailed);
  const auto s = summary();
  const std::string failure = s["failure"].get<std::string>();
  std::cout << "failure: " << failure << "\n";
  // The fem_solver registered first: its node forces are checked first.
  EXPECT_EQ(failure.rfind("coupler: the contact force on surface node 0 of the fem_solver at step 0 is not finite", 0),
            0u);
}
