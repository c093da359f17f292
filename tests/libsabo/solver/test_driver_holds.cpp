// The driver's side of hold exchanges (libsabo/solver/driver.hpp, docs/protocol.md "Hold exchanges"), against a
// scripted coupler on a real ipc socket: after a step with StepForces.holds = 2 the solver answers two holds
// without a step or a force computation, the first with the energies of its step, and sends the whole state it
// filled then (a change reported once, as the fem_solver's new topology, included) where it steps again. A hold
// that nobody announced, and a step where a hold was announced, end the solver with an error naming the step.
// Walls ahead, at the end: the boundary particles of a step taken ahead of its forces.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <future>
#include <optional>
#include <string>

#include "libsabo/protocol/socket.hpp"
#include "libsabo/scene/scene.hpp"
#include "libsabo/solver/driver.hpp"

using namespace sabo;
using namespace std::chrono_literals;

namespace {

// One particle moving with the steps; each fill after a step reports a new "topology" once.
struct FakeSolver : solver::CoupledSolver {
  double x = 0;
  int fills = 0, computes = 0, steps = 0;
  std::uint64_t revision = 0;
  bool changed = false;

  void describe(sabo::v1::Register& registration) override {
    registration.set_name("fake solver");
    registration.set_exposes_particles(true);
    registration.mutable_particles()->add_id(7);
  }
  double stable_dt() override { return 1e-3; }
  void fill_state(const solver::Interest& /*interest*/, sabo::v1::StepState& state) override {
    ++fills;
    state.add_index(0);
    for (const double v : {x, 0.0, 0.0}) state.add_position(v);
    for (const double v : {1.0, 0.0, 0.0}) state.add_velocity(v);
    state.mutable_energies()->set_kinetic(x);
    if (changed) {
      state.mutable_topology()->set_revision(revision);
      changed = false;
    }
  }
  void compute_internal_forces(double /*dt_previous*/) override { ++computes; }
  void apply_coupling_forces(const sabo::v1::StepForces& /*forces*/) override {}
  void write_output(std::uint64_t /*step*/, double /*time*/) override {}
  void integrate(double /*dt_previous*/, double dt) override {
    x += dt;
    ++steps;
    ++revision;
    changed = true;
  }
  [[nodiscard]] std::uint32_t max_substeps() const override { return 64; }
  void finish() override {}
};

struct ScriptedCoupler : ::testing::Test {
  std::filesystem::path dir;
  std::string endpoint;
  zmq::context_t context{1};
  protocol::Socket socket{context, zmq::socket_type::router};
  protocol::Inbound inbound;
  scene::Scene scene;
  solver::SolverOptions options;

  void SetUp() override {
    dir = std::filesystem::temp_directory_path() / ("sabo_driver_holds_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    endpoint = "ipc://" + (dir / "coupler.sock").string();
    socket.bind(endpoint);
    options.scene = dir / "scene.toml";
    std::ofstream(options.scene) << "format_version = 1\n";
    options.coupler_endpoint = endpoint;
    options.out_dir = dir;
  }
  void TearDown() override { std::filesystem::remove_all(dir); }

  template <class Message>
  Message receive(sabo::v1::MessageType type) {
    EXPECT_TRUE(socket.receive(inbound, 5000ms)) << "nothing from the solver";
    EXPECT_EQ(inbound.header.type, type);
    Message message;
    inbound.parse(message);
    return message;
  }
  sabo::v1::Register accept_registration() {
    auto registration = receive<sabo::v1::Register>(sabo::v1::MESSAGE_TYPE_REGISTER);
    sabo::v1::RegisterReply reply;
    reply.set_accepted(true);
    reply.set_protocol_version(protocol::kProtocolVersion);
    reply.set_end_time(1.0);
    reply.set_interest_all(true);
    socket.send(reply, inbound.peer);
    return registration;
  }
  sabo::v1::StepState state() { return receive<sabo::v1::StepState>(sabo::v1::MESSAGE_TYPE_STEP_STATE); }
  void send(sabo::v1::StepForces forces) {
    forces.set_interest_all(true);
    socket.send(forces, inbound.peer);
  }
};

sabo::v1::StepForces step_forces(std::uint64_t step, double dt, std::uint32_t holds) {
  sabo::v1::StepForces forces;
  forces.set_step(step);
  forces.set_dt(dt);
  forces.set_holds(holds);
  return forces;
}

sabo::v1::StepForces hold(std::uint64_t step) {
  sabo::v1::StepForces forces;
  forces.set_step(step);
  forces.set_hold(true);
  return forces;
}

}  // namespace

TEST_F(ScriptedCoupler, TwoHoldsAfterAStepThenTheWholeStateOfThatStep) {
  FakeSolver fake;
  auto solver_run = std::async(std::launch::async, [&] { return solver::run_solver(fake, scene, options, Role::dem); });
  accept_registration();

  EXPECT_FALSE(state().held());
  send(step_forces(0, 3e-3, 2));  // one step of 3 ms, then two holds

  const auto first = state();
  std::cout << "hold 1: held " << first.held() << ", time " << first.time() << " s, kinetic "
            << first.energies().kinetic() << " (expected 0.003), particles " << first.index_size() << " (expected 0)\n";
  EXPECT_TRUE(first.held());
  EXPECT_DOUBLE_EQ(first.time(), 3e-3);
  EXPECT_DOUBLE_EQ(first.energies().kinetic(), 3e-3);
  EXPECT_EQ(first.index_size(), 0);
  EXPECT_FALSE(first.has_topology());
  send(hold(1));

  const auto second = state();
  EXPECT_TRUE(second.held());
  EXPECT_FALSE(second.has_energies());
  EXPECT_DOUBLE_EQ(second.time(), 3e-3);
  send(hold(2));

  const auto whole = state();
  std::cout << "step 3: held " << whole.held() << ", particles " << whole.index_size() << ", topology revision "
            << whole.topology().revision() << " (expected 1: reported once, by the fill at the first hold)\n";
  EXPECT_FALSE(whole.held());
  EXPECT_EQ(whole.step(), 3u);
  EXPECT_DOUBLE_EQ(whole.time(), 3e-3);
  EXPECT_EQ(whole.index_size(), 1);
  EXPECT_DOUBLE_EQ(whole.position(0), 3e-3);
  ASSERT_TRUE(whole.has_topology());
  EXPECT_EQ(whole.topology().revision(), 1u);
  auto last = step_forces(3, 1e-3, 0);
  last.set_stop(true);
  send(last);
  receive<sabo::v1::Goodbye>(sabo::v1::MESSAGE_TYPE_GOODBYE);
  EXPECT_EQ(solver_run.get(), 0);
  std::cout << "fills " << fake.fills << " (2), force computations " << fake.computes << " (2), steps " << fake.steps
            << " (1)\n";
  EXPECT_EQ(fake.fills, 2);
  EXPECT_EQ(fake.computes, 2);
  EXPECT_EQ(fake.steps, 1);
}

TEST_F(ScriptedCoupler, AHoldNobodyAnnouncedAndAStepWhereAHoldWasEndTheSolver) {
  for (const bool announced : {false, true}) {
    FakeSolver fake;
    auto solver_run =
        std::async(std::launch::async, [&] { return solver::run_solver(fake, scene, options, Role::dem); });
    accept_registration();
    state();
    if (announced) {
      send(step_forces(0, 1e-3, 1));
      EXPECT_TRUE(state().held());
      send(step_forces(1, 1e-3, 0));  // a step where the hold was announced
    } else {
      send(hold(0));
    }
    const auto error = receive<sabo::v1::Error>(sabo::v1::MESSAGE_TYPE_ERROR);
    std::cout << "error: " << error.message() << "\n";
    EXPECT_NE(error.message().find(announced ? "StepForces of step 1 is not a hold" : "a hold that no StepForces"),
              std::string::npos);
    EXPECT_EQ(solver_run.get(), 1);
  }
}

// Walls ahead (docs/protocol.md, "Walls ahead"): a solver that registered walls_ahead takes a step's boundary
// particles from the StepForces that comes ahead of the step's forces, before those forces; boundary particles
// inside the step's own StepForces (a replay, a restart's catch-up) reach apply_coupling_forces as before.
namespace {

struct WallsSolver : FakeSolver {
  bool takes = true;
  std::vector<std::string> calls;  // in order: "walls N@step" and "forces N" (N boundary particles)
  [[nodiscard]] bool takes_walls_ahead() const override { return takes; }
  void take_walls_ahead(const sabo::v1::StepForces& walls) override {
    calls.push_back(fmt::format("walls {}@{}", walls.boundary_volume_size(), walls.step()));
  }
  void apply_coupling_forces(const sabo::v1::StepForces& forces) override {
    calls.push_back(fmt::format("forces {}", forces.boundary_volume_size()));
  }
};

sabo::v1::StepForces walls_ahead(std::uint64_t step, int particles) {
  sabo::v1::StepForces walls;
  walls.set_step(step);
  walls.set_walls_ahead(true);
  for (int k = 0; k < particles; ++k) {
    for (int c = 0; c < 3; ++c) walls.add_boundary_position(k);
    walls.add_boundary_volume(1e-6);
  }
  return walls;
}

}  // namespace

TEST_F(ScriptedCoupler, WallsAheadAreTakenBeforeTheStepsForcesAndInsideThemToo) {
  WallsSolver fake;
  auto solver_run = std::async(std::launch::async, [&] { return solver::run_solver(fake, scene, options, Role::sph); });
  EXPECT_TRUE(accept_registration().walls_ahead());

  state();
  send(walls_ahead(0, 2));
  send(step_forces(0, 1e-3, 0));
  state();
  auto merged = walls_ahead(1, 3);  // as a replay sends them: inside the step's StepForces
  merged.set_walls_ahead(false);
  merged.set_dt(1e-3);
  send(merged);
  state();
  send(walls_ahead(2, 1));
  auto last = step_forces(2, 1e-3, 0);
  last.set_stop(true);
  send(last);
  receive<sabo::v1::Goodbye>(sabo::v1::MESSAGE_TYPE_GOODBYE);
  EXPECT_EQ(solver_run.get(), 0);
  const std::vector<std::string> expected{"walls 2@0", "forces 0", "forces 3", "walls 1@2", "forces 0"};
  std::cout << "calls: " << fmt::format("{}", fmt::join(fake.calls, ", ")) << " (expected "
            << fmt::format("{}", fmt::join(expected, ", ")) << ")\n";
  EXPECT_EQ(fake.calls, expected);
}

TEST_F(ScriptedCoupler, WallsAheadThatDoNotFitEndTheSolver) {
  struct Case {
    bool takes;
    sabo::v1::StepForces first;
    std::optional<sabo::v1::StepForces> then;  // the StepForces after it, if any
    const char* expected;
  };
  auto with_forces = walls_ahead(0, 1);
  with_forces.add_index(0);
  for (int c = 0; c < 3; ++c) with_forces.add_force(1.0);
  auto walls_again = walls_ahead(0, 1);  // the step's own StepForces with the walls once more
  walls_again.set_walls_ahead(false);
  const Case cases[] = {
      {false, walls_ahead(0, 1), std::nullopt, "this solver registered walls_ahead = false"},
      {true, with_forces, std::nullopt, "carries more than the boundary particles"},
      {true, walls_ahead(0, 1), walls_ahead(0, 1), "two StepForces of step 0 carry walls ahead"},
      {true, walls_ahead(0, 1), walls_again, "carries boundary particles, which came ahead of it already"},
  };
  for (const Case& c : cases) {
    WallsSolver fake;
    fake.takes = c.takes;
    auto solver_run =
        std::async(std::launch::async, [&] { return solver::run_solver(fake, scene, options, Role::sph); });
    accept_registration();
    state();
    send(c.first);
    if (c.then) send(*c.then);
    const auto error = receive<sabo::v1::Error>(sabo::v1::MESSAGE_TYPE_ERROR);
    std::cout << "error: " << error.message() << "\n";
    EXPECT_NE(error.message().find(c.expected), std::string::npos) << error.message();
    EXPECT_EQ(solver_run.get(), 1);
  }
}
