#pragma once
// What the coupler keeps of one solver since its newest checkpoint, so that a
// restarted solver can be fed the same StepForces again and its states checked
// against the ones it sent before it died (docs/restart.md, "Catch-up"). The
// forces go to a file in RUN_DIR/checkpoints (a long interval of a large scene
// would not fit in memory); of each state a digest per field is held. The file
// is held to a size (scene run.restart_journal_limit): past it, the journal is
// dropped and its file emptied until the solver's next checkpoint, and the
// solver cannot be restarted until then (a run without checkpoints filled a
// disk with 82 GB of a surge's wall particles).
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "sabo/v1/sabo.pb.h"

namespace sabo::coupler {

class RestartJournal {
 public:
  // `file`: e.g. RUN_DIR/checkpoints/dem_solver.journal; starts empty at step 0. `limit`: bytes of forces
  // the file may hold.
  RestartJournal(std::filesystem::path file, std::uint64_t limit);

  // Drops everything and starts again at `step` (the solver has confirmed its checkpoint of that step).
  void begin(std::uint64_t step);
  // The state the solver sent for step `state.step()`, which must be the next step of the journal.
  void add_state(const sabo::v1::StepState& state);
  // The forces sent for that step; `serialized`: their bytes when the caller has them already (the socket's
  // send buffer), else empty and the journal serializes them.
  void add_forces(const sabo::v1::StepForces& forces, std::span<const std::uint8_t> serialized = {});

  [[nodiscard]] std::uint64_t first_step() const { return first_; }
  // One past the last step whose state and forces are both in the journal.
  [[nodiscard]] std::uint64_t end_step() const { return first_ + forces_.size(); }
  [[nodiscard]] bool covers(std::uint64_t step) const { return step >= first_ && step < end_step(); }
  // True from the step whose forces would have taken the file past its limit until the next begin(): nothing
  // is journalled, and no restart can be fed.
  [[nodiscard]] bool dropped() const { return dropped_; }
  [[nodiscard]] std::uint64_t limit() const { return limit_; }

  // The forces of a step the journal covers (asserted); FileError when the file cannot be read back.
  [[nodiscard]] sabo::v1::StepForces forces(std::uint64_t step);
  // The first field of `state` (of a step the journal covers) that differs from the state journalled for its
  // step, or empty when it is the same (the process's timings are not compared).
  [[nodiscard]] std::string first_difference(const sabo::v1::StepState& state) const;

  // Digests of a state's fields, in the order of field_names(): what two runs of the same physics share.
  [[nodiscard]] static std::vector<std::uint64_t> digests(const sabo::v1::StepState& state);
  [[nodiscard]] static const std::vector<std::string>& field_names();

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  // At the end of a completed run nothing can restart any more: the file goes.
  void remove();

 private:
  struct Span {
    std::uint64_t offset = 0, size = 0;
  };
  Span append(std::span<const char> bytes);
  std::string read(const Span& span);

  std::filesystem::path path_;
  std::fstream file_;
  std::uint64_t size_ = 0;  // bytes written
  std::uint64_t limit_ = 0;
  bool dropped_ = false;
  std::uint64_t first_ = 0;
  std::vector<std::vector<std::uint64_t>> states_;
  std::vector<Span> forces_;
  std::string scratch_;  // the serialized forces of the last step
};

}  // namespace sabo::coupler
