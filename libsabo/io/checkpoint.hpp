#pragma once
// Checkpoint files of one process (docs/restart.md). A checkpoint of step n
// holds what the process needs to continue at step n with the same bits as if
// it had never stopped. Each process writes its own, into
// RUN_DIR/checkpoints/<role>_<n, 10 digits>.h5, under a temporary name first
// and renamed when complete, so that a file of that name is always whole; a
// store keeps the newest `keep` of its role and removes older ones.
//
// Every file carries the attributes a restart checks before it reads a value:
// format (kCheckpointFormat), role, step, time (s) and the scene's digest (of
// the scene file's text), so a checkpoint of another process, scene or format
// is refused with an error that names the file and what differs.
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "libsabo/core/error.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/io/vtk.hpp"

namespace sabo::io {

inline constexpr const char* kCheckpointFormat = "sabo-checkpoint-1";

// FNV-1a 64 of a text, as 16 hex digits: a scene's identity in its checkpoints.
[[nodiscard]] std::string text_digest(std::string_view text);
// The digest of a file's bytes; FileError when it cannot be read.
[[nodiscard]] std::string file_digest(const std::filesystem::path& path);

struct CheckpointInfo {
  std::filesystem::path path;
  std::uint64_t step = 0;
};

class CheckpointStore {
 public:
  // `folder`: RUN_DIR/checkpoints (created on the first write); `role`: e.g. "dem_solver".
  CheckpointStore(std::filesystem::path folder, std::string role, std::string scene_digest, std::size_t keep = 2);

  // Writes the checkpoint of `step` (t = `time` s): `fill` writes the process's state into the file's root
  // group; the identity attributes are set here. Replaces a checkpoint of the same step. Returns its path.
  std::filesystem::path write(std::uint64_t step, double time, const std::function<void(hdf5::File&)>& fill) const;

  // The complete checkpoints of this role in the folder, by step (none: empty).
  [[nodiscard]] std::vector<CheckpointInfo> list() const;
  // The newest, or the newest at or before `step`.
  [[nodiscard]] std::optional<CheckpointInfo> latest(std::optional<std::uint64_t> at_or_before = {}) const;
  // The checkpoint of exactly `step`; FileError naming the steps there are when there is none.
  [[nodiscard]] CheckpointInfo at(std::uint64_t step) const;

  // Opens a checkpoint for reading after checking its identity; FileError when it is not one of this role,
  // scene and format, or its step is not `info.step`.
  [[nodiscard]] hdf5::File open(const CheckpointInfo& info) const;
  // The same for a file of any name (its step: checkpoint_step()).
  [[nodiscard]] hdf5::File open_file(const std::filesystem::path& path) const;

  [[nodiscard]] const std::filesystem::path& folder() const { return folder_; }
  [[nodiscard]] const std::string& role() const { return role_; }

  [[nodiscard]] std::filesystem::path path_of(std::uint64_t step) const;

 private:
  std::filesystem::path folder_;
  std::string role_, scene_digest_;
  std::size_t keep_;
};

// The time (s) a checkpoint was written at.
[[nodiscard]] double checkpoint_time(const hdf5::File& file);
// The step a checkpoint resumes at.
[[nodiscard]] std::uint64_t checkpoint_step(const hdf5::File& file);

// Whole arrays in and out of a group of a checkpoint.
template <hdf5::Element T>
void write_array(hdf5::Group& group, const std::string& name, std::span<const T> values) {
  const std::uint64_t chunk = std::clamp<std::uint64_t>(values.size(), 1, 1U << 16);
  auto dataset = group.create_dataset<T>(name, chunk);
  dataset.append(values);
}
template <hdf5::Element T>
void write_array(hdf5::Group& group, const std::string& name, const std::vector<T>& values) {
  write_array(group, name, std::span<const T>(values));
}
// Throws sabo::LibraryError naming the file and the dataset when it is missing or of another type.
template <hdf5::Element T>
[[nodiscard]] std::vector<T> read_array(const hdf5::Group& group, const std::string& name) {
  return group.dataset(name).read_all<T>();
}
// The same, of exactly `size` values; FileError naming the dataset and both sizes otherwise (a checkpoint of
// another model).
template <hdf5::Element T>
[[nodiscard]] std::vector<T> read_array(const hdf5::Group& group, const std::string& name, std::size_t size) {
  auto values = read_array<T>(group, name);
  if (values.size() != size) {
    throw FileError(group.file_name() + ": " + group.path() + "/" + name + " holds " + std::to_string(values.size()) +
                    " values, this model needs " + std::to_string(size) +
                    ". Fix: restart from a checkpoint of this scene, unchanged");
  }
  return values;
}
// 3-vectors as 3 doubles each.
void write_vectors(hdf5::Group& group, const std::string& name, std::span<const Vec3> values);
void read_vectors(const hdf5::Group& group, const std::string& name, std::span<Vec3> out);
// As many vectors as the dataset holds (a FileError unless its size is a multiple of 3).
[[nodiscard]] std::vector<Vec3> read_vectors(const hdf5::Group& group, const std::string& name);
// A .pvd series' entries (its times and file names), so that a restarted process continues the series.
void write_series(hdf5::Group& group, const std::string& name, const vtk::TimeSeries& series);
void read_series(const hdf5::Group& group, const std::string& name, vtk::TimeSeries& series);
// The byte size of a file a process appends to (a CSV history), and on load the file cut back to it: the rows
// after the checkpoint are written again by the restarted process. Returns false when the file is not there (a
// restart into another folder, as a replay does: the process starts the file afresh); FileError when it is
// shorter than at the checkpoint (not the folder the checkpoint belongs to).
void write_file_size(hdf5::Group& group, const std::string& name, const std::filesystem::path& file);
bool truncate_to_saved_size(const hdf5::Group& group, const std::string& name, const std::filesystem::path& file);

}  // namespace sabo::io
