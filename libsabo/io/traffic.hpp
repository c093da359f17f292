#pragma once
// Recording of the coupler's interface traffic into traffic.h5 (docs/design.md, "The traffic log")
// and reading it back. The layout is documented in docs/traffic.md:
//
//   /                       attrs: format = "sabo-traffic", format_version (traffic_format.hpp),
//                                  fields, every, first_step, last_step (-1: none)
//   /scene                  uint8: the scene file's text
//   /<role>/                one group per role ("sph_solver", "dem_solver", "fem_solver")
//     registration          uint8: serialized sabo.v1.Register messages, concatenated
//     registration_offset   uint64, registration_count uint64: one entry per Register
//     state/                StepState messages (solver -> coupler), one entry per recorded step in
//       step uint64, time float64, stable_dt float64
//       energies float64 (4 per step: kinetic, potential, elastic, dissipated)
//       timing float64 (2 per step: compute_seconds, wait_seconds), held uint8 (1: a held state)
//       <field>, <field>_offset, <field>_count   for each array field: the values of every
//                                                recorded step concatenated, and per step
//                                                where its slice starts and how long it is
//         fields: index uint32, position, velocity, angular_velocity, node_position,
//         node_velocity, boundary_force float64, boundary_step uint64 (0 or 1 value: the
//         optional field), particle_table and topology uint8 (serialized, present only
//         in steps where the message carried them)
//     forces/                StepForces messages (coupler -> solver)
//       step uint64, dt float64, flags uint8 (1 checkpoint, 2 output, 4 stop, 8 interest_all, 16 hold),
//       substeps uint8, holds uint8
//       <field>, <field>_offset, <field>_count   for index uint32, force, torque, node_force,
//                                                interest float64 (6 per box), boundary_position,
//                                                boundary_velocity, boundary_normal,
//                                                boundary_acceleration, boundary_volume float64
//
// Crash safety: the file is written in HDF5's single-writer/multiple-reader
// (SWMR) mode, which keeps it consistent on disk at every moment. Values are
// buffered in memory and written at each flush in commit order: values, then
// offsets and counts, then the other scalars, and the `step` datasets last, so
// that a step listed in `step` has all of its data on disk. After a crash the
// file opens with TrafficReader, with h5py as `h5py.File(path, "r", swmr=True)`,
// or with any reader after hdf5::clear_status_flags(path).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "libsabo/scene/scene.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::io {

// The array fields a Recording may select ("energies" selects the energies,
// "boundary_particles" the five StepForces boundary_* fields, "boundary_force"
// the StepState boundary_force and boundary_step).
[[nodiscard]] const std::vector<std::string>& traffic_field_names();

class TrafficRecorder {
 public:
  // Creates `file` (replacing it) with a group for each role of Role.
  // settings: which fields, every N-th step within [first_step, last_step],
  // flush_interval in wall seconds (0: flush at every end_step).
  // Throws SceneError for an unknown field name, LibraryError for HDF5 failures.
  TrafficRecorder(const std::filesystem::path& file, const scene::Recording& settings, const std::string& scene_text);
  // The same with an explicit list of role names.
  TrafficRecorder(const std::filesystem::path& file, const scene::Recording& settings, const std::string& scene_text,
                  const std::vector<std::string>& roles);
  // Continues the recording `file` of an interrupted run at step `continue_at.step` (a resume from the
  // checkpoints of that step): a new file takes every registration and every message of an earlier step from
  // it, then replaces it; what follows is recorded as usual. FileError when `file` does not open, is not a
  // recording, or was recorded with another scene text.
  struct ContinueAt {
    std::uint64_t step = 0;
  };
  TrafficRecorder(const std::filesystem::path& file, const scene::Recording& settings, const std::string& scene_text,
                  ContinueAt continue_at);
  TrafficRecorder(const TrafficRecorder&) = delete;
  TrafficRecorder& operator=(const TrafficRecorder&) = delete;
  ~TrafficRecorder();

  void record_registration(const std::string& role, const sabo::v1::Register& message);  // written at once
  void record_state(const std::string& role, const sabo::v1::StepState& message);        // solver -> coupler
  void record_forces(const std::string& role, const sabo::v1::StepForces& message);      // coupler -> solver
  // Flushes when flush_interval wall seconds have passed since the last flush
  // (or the buffers are large).
  void end_step(std::uint64_t step);
  void flush();  // writes everything recorded so far, in commit order
  void close();  // flushes and closes; idempotent; the destructor closes too

  [[nodiscard]] bool recorded(std::uint64_t step) const;  // whether `step` is within the settings
  [[nodiscard]] std::uint64_t bytes_written() const;      // payload bytes written to the file
  [[nodiscard]] const std::filesystem::path& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class TrafficReader {
 public:
  // Opens a recording, also one whose writer was killed (SWMR read).
  explicit TrafficReader(const std::filesystem::path& file);
  TrafficReader(const TrafficReader&) = delete;
  TrafficReader& operator=(const TrafficReader&) = delete;
  ~TrafficReader();

  [[nodiscard]] std::string scene_text() const;
  // What the recording's settings selected: the fields (traffic_field_names() when all were), and every
  // N-th step.
  [[nodiscard]] std::vector<std::string> recorded_fields() const;
  [[nodiscard]] std::uint64_t every() const;
  [[nodiscard]] std::vector<std::string> roles() const;  // roles with a registration or a recorded message
  [[nodiscard]] std::vector<std::uint64_t> steps(const std::string& role) const;        // recorded states
  [[nodiscard]] std::vector<std::uint64_t> force_steps(const std::string& role) const;  // recorded forces
  // Fields that were not recorded are empty. Throws FileError when `step` was
  // not recorded.
  [[nodiscard]] sabo::v1::StepState state(const std::string& role, std::uint64_t step) const;
  [[nodiscard]] sabo::v1::StepForces forces(const std::string& role, std::uint64_t step) const;
  // The last registration of `role`; throws FileError when there is none.
  [[nodiscard]] sabo::v1::Register registration(const std::string& role) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sabo::io
