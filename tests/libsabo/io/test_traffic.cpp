#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <random>
#include <thread>

#include "libsabo/core/error.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/io/traffic.hpp"
#include "libsabo/protocol/wire.hpp"
#include "tests/support/scratch.hpp"

namespace fs = std::filesystem;
using google::protobuf::util::MessageDifferencer;
using sabo::io::TrafficReader;
using sabo::io::TrafficRecorder;

namespace {

using sabo::testing::scratch;

// Deterministic message contents, so that a reader can check any step.
sabo::v1::StepState make_state(std::uint64_t step, int role_salt) {
  sabo::v1::StepState state;
  state.set_step(step);
  state.set_time(1e-4 * static_cast<double>(step));
  state.set_stable_dt(1e-4 + 1e-9 * role_salt);
  state.set_compute_seconds(0.001 * static_cast<double>(step % 7));
  state.set_wait_seconds(0.002);
  auto* energies = state.mutable_energies();
  energies->set_kinetic(static_cast<double>(step));
  energies->set_potential(-static_cast<double>(step));
  energies->set_elastic(0.5);
  energies->set_dissipated(0.25 * static_cast<double>(step));
  const std::uint32_t count = 50 + static_cast<std::uint32_t>((step * 37) % 200);  // varies per step
  for (std::uint32_t i = 0; i < count; ++i) {
    state.add_index(i * 2 + static_cast<std::uint32_t>(role_salt));
    for (int k = 0; k < 3; ++k) {
      const double value = static_cast<double>(step) + 1e-3 * i + 1e-7 * k + role_salt;
      state.add_position(value);
      state.add_velocity(-value);
      state.add_angular_velocity(2 * value);
    }
  }
  if (step % 10 == 0) {
    auto* table = state.mutable_particle_table();
    for (std::uint32_t i = 0; i < count; ++i) {
      table->add_id(1000 + i);
      table->add_radius(0.1);
      table->add_mass(1.0 + i);
      table->add_material(0);
      table->add_body(1);
    }
  }
  return state;
}

sabo::v1::StepState make_surface_state(std::uint64_t step) {
  sabo::v1::StepState state;
  state.set_step(step);
  state.set_time(1e-4 * static_cast<double>(step));
  state.set_stable_dt(1e300);
  state.mutable_energies();
  if (step % 5 == 2) state.set_held(true);  // the recorder keeps the flag whatever else the state holds
  for (int i = 0; i < 30; ++i) {
    state.add_node_position(static_cast<double>(step) + i);
    state.add_node_velocity(0.0);
  }
  if (step == 0) {
    auto* topology = state.mutable_topology();
    topology->set_revision(1);
    topology->add_node_id(5);
    topology->add_part_name("dam");
  }
  return state;
}

sabo::v1::StepForces make_forces(std::uint64_t step, const sabo::v1::StepState& state) {
  sabo::v1::StepForces forces;
  forces.set_step(step);
  forces.set_dt(1e-4);
  forces.set_output(step % 5 == 0);
  forces.set_stop(false);
  forces.set_checkpoint(step % 3 == 0);
  if (step % 4 == 1) forces.set_substeps(5);  // multirate: any whole number of steps, up to the driver's 64
  if (step % 4 == 2) forces.set_substeps(64);
  if (step % 4 == 3) forces.set_holds(3);  // hold exchanges: the next three are holds
  if (step % 7 == 4) forces.set_hold(true);
  *forces.mutable_index() = state.index();
  for (int i = 0; i < state.position_size(); ++i) {
    forces.add_force(0.5 * state.position(i));
    forces.add_torque(0.25 * state.position(i));
  }
  for (int i = 0; i < state.node_position_size(); ++i) forces.add_node_force(-state.node_position(i));
  auto* box = forces.add_interest();
  box->set_min_x(-1);
  box->set_max_z(static_cast<double>(step));
  return forces;
}

sabo::v1::Register make_registration(const std::string& name) {
  sabo::v1::Register message;
  message.set_protocol_version(1);
  message.set_role(sabo::protocol::to_wire(sabo::Role::dem));
  message.set_name(name);
  message.set_exposes_particles(true);
  message.set_stable_dt(1e-4);
  message.mutable_particles()->add_id(1);
  return message;
}

void expect_same(const google::protobuf::Message& expected, const google::protobuf::Message& actual) {
  std::string differences;
  MessageDifferencer differencer;
  differencer.ReportDifferencesToString(&differences);
  EXPECT_TRUE(differencer.Compare(expected, actual)) << differences;
}

// Steps [from, to) of a DEM role and an FEM surface role, both ways, each step ended.
void record_steps(TrafficRecorder& recorder, std::uint64_t from, std::uint64_t to) {
  for (std::uint64_t step = from; step < to; ++step) {
    const auto dem = make_state(step, 1);
    const auto fem = make_surface_state(step);
    recorder.record_state("dem_solver", dem);
    recorder.record_state("fem_solver", fem);
    recorder.record_forces("dem_solver", make_forces(step, dem));
    recorder.record_forces("fem_solver", make_forces(step, fem));
    recorder.end_step(step);
  }
}

sabo::scene::Recording every_step_settings() {
  sabo::scene::Recording settings;
  settings.flush_interval = 0;
  return settings;
}

}  // namespace

TEST(Traffic, RoundTripOfEveryField) {
  const fs::path path = scratch("round_trip.h5");
  const std::string scene_text = "format_version = 1\n[run]\nend_time = 1.0\n";
  std::uint64_t bytes = 0;
  {
    sabo::scene::Recording settings;
    settings.flush_interval = 1000;  // only close() flushes
    TrafficRecorder recorder(path, settings, scene_text);
    recorder.record_registration("dem_solver", make_registration("dem_solver 0.1.0"));
    recorder.record_registration("dem_solver", make_registration("dem_solver 0.1.0 restarted"));
    record_steps(recorder, 0, 25);
    recorder.close();
    recorder.close();  // idempotent
    bytes = recorder.bytes_written();
  }
  // Closed cleanly: any HDF5 reader opens it, not only SWMR readers.
  EXPECT_NO_THROW((void)sabo::io::hdf5::File::open(path));

  TrafficReader reader(path);
  EXPECT_EQ(reader.scene_text(), scene_text);
  EXPECT_EQ(reader.roles(), (std::vector<std::string>{"dem_solver", "fem_solver"}));
  EXPECT_EQ(reader.registration("dem_solver").name(), "dem_solver 0.1.0 restarted");
  expect_same(make_registration("dem_solver 0.1.0 restarted"), reader.registration("dem_solver"));
  EXPECT_THROW((void)reader.registration("fem_solver"), sabo::FileError);
  const auto steps = reader.steps("dem_solver");
  ASSERT_EQ(steps.size(), 25u);
  std::uint64_t position_bytes = 0;
  for (std::uint64_t step : steps) {
    const auto dem = make_state(step, 1);
    const auto fem = make_surface_state(step);
    position_bytes += dem.position_size() * sizeof(double);
    expect_same(dem, reader.state("dem_solver", step));
    expect_same(fem, reader.state("fem_solver", step));
    expect_same(make_forces(step, dem), reader.forces("dem_solver", step));
    expect_same(make_forces(step, fem), reader.forces("fem_solver", step));
  }
  EXPECT_TRUE(reader.state("dem_solver", 10).has_particle_table());
  EXPECT_FALSE(reader.state("dem_solver", 11).has_particle_table());
  // Five double fields of the size of `position` (three in states, two in
  // forces), the index, scalars and the surface role.
  std::cout << "bytes written: " << bytes << " (position payload " << position_bytes << ")\n";
  EXPECT_GT(bytes, 5 * position_bytes);
  EXPECT_LT(bytes, 7 * position_bytes);
  const std::string missing = [&] {
    try {
      (void)reader.state("dem_solver", 99);
    } catch (const sabo::FileError& error) {
      return std::string(error.what());
    }
    return std::string();
  }();
  EXPECT_NE(missing.find("step 99 was not recorded (25 steps recorded, from 0 to 24)"), std::string::npos) << missing;
  EXPECT_THROW((void)reader.steps("nobody"), sabo::FileError);
}

// A resumed run continues traffic.h5 at its checkpoint's step: the messages before it are kept, the later ones
// (recorded by the run that died) give way to the resumed run's, and the file reads as one uninterrupted run.
TEST(Traffic, ContinuesARecordingAtAStep) {
  const std::string scene_text = "format_version = 1\n[run]\nend_time = 1.0\n";
  const sabo::scene::Recording settings = every_step_settings();
  const fs::path uninterrupted = scratch("continue_reference.h5");
  {
    TrafficRecorder recorder(uninterrupted, settings, scene_text);
    recorder.record_registration("dem_solver", make_registration("dem_solver 0.1.0"));
    record_steps(recorder, 0, 40);
  }
  const fs::path continued = scratch("continue_resumed.h5");
  {
    // The run that died after step 29; the resume is at step 17, the step of a checkpoint.
    TrafficRecorder recorder(continued, settings, scene_text);
    recorder.record_registration("dem_solver", make_registration("dem_solver 0.1.0"));
    record_steps(recorder, 0, 30);
    recorder.flush();
  }
  {
    TrafficRecorder recorder(continued, settings, scene_text, TrafficRecorder::ContinueAt{17});
    record_steps(recorder, 17, 40);
  }
  const TrafficReader reference(uninterrupted);
  const TrafficReader reader(continued);
  EXPECT_EQ(reader.steps("dem_solver"), reference.steps("dem_solver"));
  EXPECT_EQ(reader.force_steps("fem_solver"), reference.force_steps("fem_solver"));
  expect_same(reference.registration("dem_solver"), reader.registration("dem_solver"));
  for (std::uint64_t step : reference.steps("dem_solver")) {
    for (const char* role : {"dem_solver", "fem_solver"}) {
      expect_same(reference.state(role, step), reader.state(role, step));
      expect_same(reference.forces(role, step), reader.forces(role, step));
    }
  }
  // Only what is needed: the recording of another scene text, or a file that is not one, is refused.
  auto error_of = [&](const fs::path& file, const std::string& text) {
    try {
      TrafficRecorder recorder(file, settings, text, TrafficRecorder::ContinueAt{5});
    } catch (const sabo::FileError& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  const std::string other_scene = error_of(continued, scene_text + "# changed\n");
  EXPECT_NE(other_scene.find("recorded with another scene text"), std::string::npos) << other_scene;
  const fs::path not_hdf5 = scratch("continue_not_hdf5.h5");
  std::ofstream(not_hdf5) << "not a recording";
  const std::string damaged = error_of(not_hdf5, scene_text);
  EXPECT_NE(damaged.find("the recording to continue does not open"), std::string::npos) << damaged;
  // The refused continuation left the recording as it was.
  EXPECT_EQ(TrafficReader(continued).steps("dem_solver"), reference.steps("dem_solver"));
}

TEST(Traffic, FieldSubsetAndStepRange) {
  const fs::path path = scratch("subset.h5");
  sabo::scene::Recording settings = every_step_settings();
  settings.fields = {"position", "node_force"};
  settings.every = 3;
  settings.first_step = 2;
  settings.last_step = 10;
  {
    TrafficRecorder recorder(path, settings, "");
    for (std::uint64_t step = 0; step < 20; ++step) {
      const auto dem = make_state(step, 0);
      recorder.record_state("dem_solver", dem);
      recorder.record_forces("dem_solver", make_forces(step, dem));
      recorder.end_step(step);
    }
  }
  TrafficReader reader(path);
  EXPECT_EQ(reader.steps("dem_solver"), (std::vector<std::uint64_t>{2, 5, 8}));
  EXPECT_EQ(reader.force_steps("dem_solver"), (std::vector<std::uint64_t>{2, 5, 8}));
  const auto original = make_state(5, 0);
  const auto state = reader.state("dem_solver", 5);
  EXPECT_EQ(state.position_size(), original.position_size());
  EXPECT_EQ(state.index_size(), original.index_size());  // needed to interpret positions
  EXPECT_EQ(state.velocity_size(), 0);
  EXPECT_EQ(state.angular_velocity_size(), 0);
  EXPECT_FALSE(state.has_energies());
  EXPECT_EQ(state.time(), original.time());
  const auto forces = reader.forces("dem_solver", 8);
  EXPECT_EQ(forces.force_size(), 0);
  EXPECT_EQ(forces.index_size(), 0);
  EXPECT_EQ(forces.dt(), 1e-4);
  EXPECT_THROW((void)reader.state("dem_solver", 3), sabo::FileError);
}

namespace {

// SPH walls (wall_model = boundary_particles): the number of wall particles
// changes from step to step, boundary_step is absent at steps 0 and 1.
std::uint32_t wall_count(std::uint64_t step) {
  return 20 + static_cast<std::uint32_t>((step * 13) % 40);
}

sabo::v1::StepForces make_wall_forces(std::uint64_t step) {
  sabo::v1::StepForces forces;
  forces.set_step(step);
  forces.set_dt(2e-5);
  for (std::uint32_t i = 0; i < wall_count(step); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double value = static_cast<double>(step) + 1e-3 * i + 1e-6 * k;
      forces.add_boundary_position(value);
      forces.add_boundary_velocity(-value);
      forces.add_boundary_normal(k == 2 ? 1.0 : 0.0);
      forces.add_boundary_acceleration(0.5 * value);
    }
    forces.add_boundary_volume(1e-6 * (1 + i % 3));
    // Free-slip flags at odd steps only (a scene without free-slip walls sends none).
    if (step % 2 == 1) forces.add_boundary_free_slip(i % 2);
  }
  return forces;
}

sabo::v1::StepState make_wall_state(std::uint64_t step) {
  sabo::v1::StepState state;
  state.set_step(step);
  state.set_stable_dt(2e-5);
  if (step >= 2) {
    state.set_boundary_step(step - 1);
    for (std::uint32_t i = 0; i < 3 * wall_count(step - 1); ++i) state.add_boundary_force(1e-2 * i - 0.1);
  }
  return state;
}

}  // namespace

TEST(Traffic, RoundTripOfSphWallFields) {
  const fs::path path = scratch("walls.h5");
  sabo::scene::Recording settings = every_step_settings();
  settings.fields = {"boundary_particles", "boundary_force"};
  {
    TrafficRecorder recorder(path, settings, "");
    for (std::uint64_t step = 0; step < 12; ++step) {
      recorder.record_state("sph_solver", make_wall_state(step));
      recorder.record_forces("sph_solver", make_wall_forces(step));
      recorder.end_step(step);
    }
  }
  TrafficReader reader(path);
  ASSERT_EQ(reader.steps("sph_solver").size(), 12u);
  for (std::uint64_t step = 0; step < 12; ++step) {
    const auto state = reader.state("sph_solver", step);
    expect_same(make_wall_forces(step), reader.forces("sph_solver", step));
    expect_same(make_wall_state(step), state);
    EXPECT_EQ(state.has_boundary_step(), step >= 2) << "step " << step;
  }
  // The fluid's forces of step n belong to the walls sent at step n - 1.
  const auto state = reader.state("sph_solver", 7);
  const auto walls = reader.forces("sph_solver", state.boundary_step());
  std::cout << "step 7: " << walls.boundary_volume_size() << " wall particles sent at step 6, "
            << state.boundary_force_size() / 3 << " wall forces received\n";
  EXPECT_EQ(state.boundary_force_size(), walls.boundary_position_size());
  EXPECT_EQ(walls.boundary_position_size(), 3 * walls.boundary_volume_size());

  // Not selected: no datasets at all (nothing recorded, nothing flushed).
  const fs::path lean = scratch("walls_not_selected.h5");
  settings.fields = {"position"};
  {
    TrafficRecorder recorder(lean, settings, "");
    recorder.record_state("sph_solver", make_wall_state(3));
    recorder.record_forces("sph_solver", make_wall_forces(3));
  }
  {
    const auto file = sabo::io::hdf5::File::open(lean);
    for (const char* name : {"boundary_force", "boundary_step"}) {
      EXPECT_FALSE(file.group("sph_solver").group("state").exists(name)) << name;
    }
    for (const char* name : {"boundary_position", "boundary_velocity", "boundary_normal", "boundary_acceleration",
                             "boundary_volume", "boundary_free_slip"}) {
      EXPECT_FALSE(file.group("sph_solver").group("forces").exists(name)) << name;
    }
  }
  TrafficReader lean_reader(lean);
  EXPECT_EQ(lean_reader.forces("sph_solver", 3).boundary_position_size(), 0);
  EXPECT_FALSE(lean_reader.state("sph_solver", 3).has_boundary_step());
}

TEST(Traffic, RejectsBadSettings) {
  sabo::scene::Recording settings;
  settings.fields = {"positon"};
  EXPECT_THROW(TrafficRecorder(scratch("bad.h5"), settings, ""), sabo::SceneError);
  settings.fields = {};
  settings.every = 0;
  EXPECT_THROW(TrafficRecorder(scratch("bad.h5"), settings, ""), sabo::SceneError);
  TrafficRecorder recorder(scratch("roles.h5"), every_step_settings(), "", {"dem_solver"});
  EXPECT_THROW(recorder.record_state("fem_solver", make_surface_state(0)), sabo::Error);
  recorder.close();
  EXPECT_THROW(recorder.record_state("dem_solver", make_state(0, 0)), sabo::Error);
  EXPECT_THROW(TrafficReader(scratch("absent.h5")), sabo::FileError);
}

// The flush cost at every step, measured against buffering between flushes.
TEST(Traffic, FlushCostPerStep) {
  constexpr std::uint64_t steps = 200;
  std::vector<sabo::v1::StepState> states;
  std::vector<sabo::v1::StepForces> forces;
  for (std::uint64_t step = 0; step < steps; ++step) {
    states.push_back(make_state(step, 1));
    forces.push_back(make_forces(step, states.back()));
  }
  auto run = [&](double flush_interval) {
    sabo::scene::Recording settings;
    settings.flush_interval = flush_interval;
    const auto start = std::chrono::steady_clock::now();
    TrafficRecorder recorder(scratch("cost.h5"), settings, "");
    const auto opened = std::chrono::steady_clock::now();
    for (std::uint64_t step = 0; step < steps; ++step) {
      recorder.record_state("dem_solver", states[step]);
      recorder.record_forces("dem_solver", forces[step]);
      recorder.end_step(step);
    }
    recorder.close();
    const auto end = std::chrono::steady_clock::now();
    return std::pair{std::chrono::duration<double>(opened - start).count(),
                     std::chrono::duration<double>(end - opened).count() / steps};
  };
  const auto [create_s, buffered_s] = run(1000);
  const auto [create2_s, flushed_s] = run(0);
  std::cout << "create: " << create_s * 1e3 << " ms; per step (~150 particles, 6 fields): buffered " << buffered_s * 1e6
            << " us, flushed every step " << flushed_s * 1e6 << " us; flush cost " << (flushed_s - buffered_s) * 1e6
            << " us per step\n";
  (void)create2_s;
  EXPECT_LT(flushed_s, 0.02);  // a flush per step must stay far below a coupling step's budget
}

// Crash safety: a child records with a flush at every step and is killed with
// SIGKILL at some moment; the file must open and hold every flushed step.
TEST(Traffic, SurvivesSigkillAtAnyMoment) {
  // What the child publishes: that its recorder exists, and the last step
  // whose end_step() returned.
  struct Progress {
    std::atomic<int> recording{0};
    std::atomic<std::int64_t> last_flushed{-1};
  };
  auto* progress = static_cast<Progress*>(
      mmap(nullptr, sizeof(Progress), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0));
  ASSERT_NE(progress, MAP_FAILED);
  // The first kill comes 5 ms after the start, most likely while the file is
  // being created; the others at random moments (printed, to reproduce a
  // failure) of 0-150 ms once the child records.
  std::mt19937 random(std::random_device{}());
  std::vector<int> kill_after_ms = {5};
  for (int i = 0; i < 5; ++i) kill_after_ms.push_back(std::uniform_int_distribution<int>(0, 150)(random));
  int attempts_with_steps = 0;
  for (std::size_t attempt = 0; attempt < kill_after_ms.size(); ++attempt) {
    const fs::path path = scratch("crash_" + std::to_string(attempt) + ".h5");
    new (progress) Progress();
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      int status = 0;
      try {
        TrafficRecorder recorder(path, every_step_settings(), "scene");
        progress->recording.store(1);
        recorder.record_registration("dem_solver", make_registration("dem"));
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        for (std::uint64_t step = 0; std::chrono::steady_clock::now() < deadline; ++step) {
          record_steps(recorder, step, step + 1);
          progress->last_flushed.store(static_cast<std::int64_t>(step));
        }
      } catch (...) {
        status = 3;
      }
      _exit(status);
    }
    if (attempt > 0) {
      const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      while (progress->recording.load() == 0 && std::chrono::steady_clock::now() < give_up) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(kill_after_ms[attempt]));
    ASSERT_EQ(kill(child, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the child ended on its own with status " << status;
    const std::int64_t flushed = progress->last_flushed.load();
    if (flushed >= 0) ++attempts_with_steps;
    std::cout << "attempt " << attempt << ": killed " << kill_after_ms[attempt] << " ms after "
              << (attempt == 0 ? "the start" : "recording began") << ", last flushed step " << flushed << "\n";
    if (!fs::exists(path)) {
      // Killed while creating the file: nothing was recorded yet.
      EXPECT_EQ(flushed, -1);
      continue;
    }
    auto check = [&](const char* how) {
      TrafficReader reader(path);
      const auto steps = reader.steps("dem_solver");
      const auto fem_steps = reader.steps("fem_solver");
      const auto force_steps = reader.force_steps("fem_solver");
      std::cout << "  " << how << ": " << steps.size() << " steps on disk\n";
      ASSERT_GE(static_cast<std::int64_t>(steps.size()), flushed + 1);
      ASSERT_GE(static_cast<std::int64_t>(force_steps.size()), flushed + 1);
      ASSERT_GE(static_cast<std::int64_t>(fem_steps.size()), flushed + 1);
      for (std::size_t i = 0; i < steps.size(); ++i) ASSERT_EQ(steps[i], i);
      if (!steps.empty()) expect_same(make_registration("dem"), reader.registration("dem_solver"));
      // The last steps on disk are complete and consistent; a sample of the others too.
      // Each stream is complete on its own: the streams are flushed one after another,
      // so a kill between them can leave a step's state on disk without its forces.
      const auto dem_force_steps = reader.force_steps("dem_solver");
      ASSERT_GE(static_cast<std::int64_t>(dem_force_steps.size()), flushed + 1);
      ASSERT_LE(dem_force_steps.size(), steps.size());
      for (std::size_t i = 0; i < steps.size(); ++i) {
        if (i + 5 < steps.size() && i % 17 != 0) continue;
        const auto dem = make_state(i, 1);
        expect_same(dem, reader.state("dem_solver", i));
        if (i < dem_force_steps.size()) expect_same(make_forces(i, dem), reader.forces("dem_solver", i));
      }
      for (std::size_t i = 0; i < force_steps.size(); ++i) {
        if (i + 3 < force_steps.size()) continue;
        expect_same(make_forces(i, make_surface_state(i)), reader.forces("fem_solver", i));
      }
    };
    check("SWMR read");
    // After clearing the status flags a killed writer leaves, a plain reader opens it too.
    EXPECT_THROW((void)sabo::io::hdf5::File::open(path), sabo::LibraryError);
    sabo::io::hdf5::clear_status_flags(path);
    EXPECT_NO_THROW((void)sabo::io::hdf5::File::open(path));
    check("after clear_status_flags");
  }
  EXPECT_GE(attempts_with_steps, 2) << "too few kills fell while steps were recorded";
  munmap(progress, sizeof(Progress));
}
