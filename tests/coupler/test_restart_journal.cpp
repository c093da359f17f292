// The coupler's restart journal: the forces come back as sent, a state's first differing field is named, and the
// journal starts again at a checkpoint's step.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>

#include "coupler/restart_journal.hpp"
#include "libsabo/protocol/socket.hpp"
#include "tests/support/scratch.hpp"

using sabo::coupler::RestartJournal;

namespace {

sabo::v1::StepState state_of(std::uint64_t step) {
  sabo::v1::StepState state;
  state.set_step(step);
  state.set_time(1e-3 * static_cast<double>(step));
  state.set_stable_dt(1e-3);
  for (std::uint32_t i = 0; i < 4; ++i) {
    state.add_index(i);
    for (int c = 0; c < 3; ++c) {
      state.add_position(0.1 * i + c + static_cast<double>(step));
      state.add_velocity(-0.2 * i);
    }
  }
  state.mutable_energies()->set_kinetic(3.0 + static_cast<double>(step));
  state.set_compute_seconds(0.01 * static_cast<double>(step));
  return state;
}

sabo::v1::StepForces forces_of(std::uint64_t step) {
  sabo::v1::StepForces forces;
  forces.set_step(step);
  forces.set_dt(1e-3);
  for (int k = 0; k < 12; ++k) forces.add_force(static_cast<double>(k) * 0.5 + static_cast<double>(step));
  forces.set_checkpoint(step == 1);
  return forces;
}

}  // namespace

constexpr std::uint64_t kLimit = 1'000'000'000;  // bytes: far above these tests' journals

TEST(RestartJournal, GivesBackTheForcesAndNamesTheFirstDifferingField) {
  RestartJournal journal(sabo::testing::scratch("journal/dem_solver.journal"), kLimit);
  for (std::uint64_t step = 0; step < 5; ++step) {
    journal.add_state(state_of(step));
    journal.add_forces(forces_of(step));
  }
  EXPECT_EQ(journal.first_step(), 0U);
  EXPECT_EQ(journal.end_step(), 5U);
  for (std::uint64_t step = 0; step < 5; ++step) {
    EXPECT_EQ(journal.forces(step).SerializeAsString(), forces_of(step).SerializeAsString()) << "step " << step;
  }
  auto same = state_of(3);
  same.set_compute_seconds(7.0);  // the timings of a restarted process differ and are not compared
  same.set_wait_seconds(2.0);
  EXPECT_EQ(journal.first_difference(same), "");
  auto moved = state_of(3);
  moved.set_position(5, std::nextafter(moved.position(5), 10.0));  // one bit
  EXPECT_EQ(journal.first_difference(moved), "position");
  auto hotter = state_of(2);
  hotter.mutable_energies()->set_kinetic(hotter.energies().kinetic() + 1e-12);
  EXPECT_EQ(journal.first_difference(hotter), "energies");
  auto fewer = state_of(4);
  fewer.mutable_index()->RemoveLast();
  EXPECT_EQ(journal.first_difference(fewer), "index");
}

TEST(RestartJournal, StartsAgainAtACheckpoint) {
  RestartJournal journal(sabo::testing::scratch("journal/fem_solver.journal"), kLimit);
  for (std::uint64_t step = 0; step < 3; ++step) {
    journal.add_state(state_of(step));
    journal.add_forces(forces_of(step));
  }
  std::uintmax_t interval_bytes = 0;  // of the first interval, the largest
  for (std::uint64_t step = 0; step < 3; ++step) interval_bytes += forces_of(step).SerializeAsString().size();
  journal.begin(3);
  EXPECT_FALSE(journal.covers(2));
  journal.add_state(state_of(3));
  EXPECT_FALSE(journal.covers(3)) << "its forces are not in yet";
  journal.add_forces(forces_of(3));
  EXPECT_TRUE(journal.covers(3));
  EXPECT_EQ(journal.forces(3).SerializeAsString(), forces_of(3).SerializeAsString());
  // The file is written again from its start (not truncated, which stalled large runs): it never grows past
  // the largest interval.
  for (std::uint64_t checkpoint = 4; checkpoint < 12; checkpoint += 2) {
    journal.begin(checkpoint);
    for (std::uint64_t step = checkpoint; step < checkpoint + 2; ++step) {
      journal.add_state(state_of(step));
      journal.add_forces(forces_of(step));
    }
    EXPECT_EQ(journal.forces(checkpoint + 1).SerializeAsString(), forces_of(checkpoint + 1).SerializeAsString());
  }
  EXPECT_EQ(std::filesystem::file_size(journal.path()), interval_bytes)
      << "the journal file holds at most the largest interval since a checkpoint";
}

TEST(RestartJournal, PastItsLimitItIsDroppedUntilTheNextCheckpoint) {
  // Room for two steps' forces and not three: the third drops the journal and empties its file.
  const std::uint64_t step_bytes = forces_of(0).SerializeAsString().size();
  RestartJournal journal(sabo::testing::scratch("journal/sph_solver.journal"), 2 * step_bytes + step_bytes / 2);
  for (std::uint64_t step = 0; step < 5; ++step) {
    journal.add_state(state_of(step));
    journal.add_forces(forces_of(step));
    EXPECT_EQ(journal.dropped(), step >= 2) << "step " << step;
  }
  std::cout << "a journal of " << journal.limit() << " bytes, " << step_bytes << " a step: dropped at step 2, its file "
            << std::filesystem::file_size(journal.path()) << " bytes (expected 0)\n";
  EXPECT_EQ(std::filesystem::file_size(journal.path()), 0u);
  EXPECT_FALSE(journal.covers(1));
  // A checkpoint takes it up again.
  journal.begin(5);
  EXPECT_FALSE(journal.dropped());
  journal.add_state(state_of(5));
  journal.add_forces(forces_of(5));
  EXPECT_TRUE(journal.covers(5));
  EXPECT_EQ(journal.forces(5).SerializeAsString(), forces_of(5).SerializeAsString());
}

TEST(RestartJournal, TakesTheBytesTheSocketSentWithoutSerializingAgain) {
  // The coupler hands the journal the body its send buffer handed to ZeroMQ (a large body, sent without a
  // copy); the journal gives back what was sent, as when it serializes the forces itself.
  sabo::protocol::SendBuffer buffer;
  sabo::v1::StepForces large = forces_of(0);
  for (int k = 0; k < 20'000; ++k) large.add_force(1e-3 * k);
  zmq::message_t body = buffer.wrap(large);
  ASSERT_EQ(buffer.last_body().size(), body.size()) << "a body of " << body.size() << " bytes goes without a copy";
  RestartJournal journal(sabo::testing::scratch("journal_bytes/sph_solver.journal"), kLimit);
  journal.add_state(state_of(0));
  journal.add_forces(large, buffer.last_body());
  journal.add_state(state_of(1));
  const sabo::v1::StepForces small = forces_of(1);
  (void)buffer.wrap(small);
  EXPECT_TRUE(buffer.last_body().empty()) << "a small body is copied; the journal serializes it";
  journal.add_forces(small, buffer.last_body());
  EXPECT_EQ(journal.forces(0).SerializeAsString(), large.SerializeAsString());
  EXPECT_EQ(journal.forces(1).SerializeAsString(), small.SerializeAsString());
}
