#include "libsabo/io/checkpoint.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <regex>

#include "libsabo/core/error.hpp"

namespace sabo::io {

namespace {

// Durability across a machine that dies: the file's data, then the folder's entry for it.
void sync_path(const std::filesystem::path& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) return;  // best effort: the rename alone already keeps the file whole
  (void)::fsync(fd);
  (void)::close(fd);
}

std::string steps_text(const std::vector<CheckpointInfo>& list) {
  std::vector<std::uint64_t> steps;
  for (const auto& info : list) steps.push_back(info.step);
  return steps.empty() ? std::string("none") : fmt::format("{}", fmt::join(steps, ", "));
}

}  // namespace

std::string text_digest(std::string_view text) {
  std::uint64_t hash = 14695981039346656037ULL;
  for (const unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ULL;
  }
  return fmt::format("{:016x}", hash);
}

std::string file_digest(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(fmt::format("{}: cannot read the file to compute its digest", path.string()));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return text_digest(text);
}

CheckpointStore::CheckpointStore(std::filesystem::path folder, std::string role, std::string scene_digest,
                                 std::size_t keep)
    : folder_(std::move(folder)), role_(std::move(role)), scene_digest_(std::move(scene_digest)), keep_(keep) {
  if (keep_ == 0) keep_ = 1;
}

std::filesystem::path CheckpointStore::path_of(std::uint64_t step) const {
  return folder_ / fmt::format("{}_{:010}.h5", role_, step);
}

std::filesystem::path CheckpointStore::write(std::uint64_t step, double time,
                                             const std::function<void(hdf5::File&)>& fill) const {
  std::error_code error;
  std::filesystem::create_directories(folder_, error);
  if (error) {
    throw FileError(fmt::format("{}: cannot create the checkpoint folder: {}", folder_.string(), error.message()));
  }
  const std::filesystem::path final_path = path_of(step);
  std::filesystem::path partial = final_path;
  partial += ".partial";
  {
    hdf5::File file = hdf5::File::create(partial);
    file.set_attribute("format", kCheckpointFormat);
    file.set_attribute("role", role_);
    file.set_attribute("step", static_cast<std::int64_t>(step));
    file.set_attribute("time", time);
    file.set_attribute("scene_digest", scene_digest_);
    fill(file);
    file.flush();
    file.close();
  }
  sync_path(partial, false);
  std::filesystem::rename(partial, final_path, error);
  if (error) {
    throw FileError(fmt::format("{}: cannot rename the finished checkpoint to {}: {}", partial.string(),
                                final_path.string(), error.message()));
  }
  sync_path(folder_, true);
  // Keep the newest `keep_`; a restart reads the newest that every process has.
  auto all = list();
  if (all.size() > keep_) {
    for (std::size_t k = 0; k + keep_ < all.size(); ++k) std::filesystem::remove(all[k].path, error);
  }
  return final_path;
}

std::vector<CheckpointInfo> CheckpointStore::list() const {
  std::vector<CheckpointInfo> out;
  std::error_code error;
  if (!std::filesystem::is_directory(folder_, error)) return out;
  const std::regex name(fmt::format("{}_([0-9]{{10}})\\.h5", role_));
  for (const auto& entry : std::filesystem::directory_iterator(folder_, error)) {
    std::smatch match;
    const std::string file = entry.path().filename().string();
    if (!std::regex_match(file, match, name)) continue;
    out.push_back({entry.path(), std::stoull(match[1].str())});
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.step < b.step; });
  return out;
}

std::optional<CheckpointInfo> CheckpointStore::latest(std::optional<std::uint64_t> at_or_before) const {
  const auto all = list();
  for (auto it = all.rbegin(); it != all.rend(); ++it) {
    if (!at_or_before || it->step <= *at_or_before) return *it;
  }
  return std::nullopt;
}

CheckpointInfo CheckpointStore::at(std::uint64_t step) const {
  const auto all = list();
  for (const auto& info : all) {
    if (info.step == step) return info;
  }
  throw FileError(fmt::format("{}: no checkpoint of {} at step {} (there are: {})", folder_.string(), role_, step,
                              steps_text(all)));
}

hdf5::File CheckpointStore::open(const CheckpointInfo& info) const {
  hdf5::File file = open_file(info.path);
  const auto step = checkpoint_step(file);
  if (step != info.step) {
    throw FileError(fmt::format("{}: holds step {}, its name says {}. Fix: do not rename checkpoint files",
                                info.path.string(), step, info.step));
  }
  return file;
}

hdf5::File CheckpointStore::open_file(const std::filesystem::path& path) const {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    throw FileError(fmt::format("{}: no such checkpoint file (the {} writes RUN_DIR/checkpoints/{}_<step>.h5)",
                                path.string(), role_, role_));
  }
  hdf5::File file;
  try {
    file = hdf5::File::open(path);
  } catch (const LibraryError& library) {
    throw FileError(
        fmt::format("{}: not a Sabo checkpoint: it does not open as HDF5 ({}). Fix: restart from a "
                    "file of RUN_DIR/checkpoints that Sabo wrote",
                    path.string(), library.what()));
  }
  const auto text = [&](const char* name) {
    return file.has_attribute(name) ? file.string_attribute(name) : std::string("(none)");
  };
  const std::string where = path.string();
  if (text("format") != kCheckpointFormat) {
    throw FileError(
        fmt::format("{}: not a Sabo checkpoint (format {}, expected {}). Fix: restart from a file of "
                    "RUN_DIR/checkpoints that Sabo wrote",
                    where, text("format"), kCheckpointFormat));
  }
  if (text("role") != role_) {
    throw FileError(fmt::format("{}: a checkpoint of {}, not of {}. Fix: give the {} its own checkpoint ({}_*.h5)",
                                where, text("role"), role_, role_, role_));
  }
  if (text("scene_digest") != scene_digest_) {
    throw FileError(fmt::format(
        "{}: a checkpoint of another scene (scene digest {}, this scene's {}). Fix: restart with the scene the run "
        "was started with, unchanged (sabo_replay scene --traffic RUN_DIR/traffic.h5 prints it)",
        where, text("scene_digest"), scene_digest_));
  }
  return file;
}

double checkpoint_time(const hdf5::File& file) {
  return file.double_attribute("time");
}
std::uint64_t checkpoint_step(const hdf5::File& file) {
  return static_cast<std::uint64_t>(file.int_attribute("step"));
}

void write_vectors(hdf5::Group& group, const std::string& name, std::span<const Vec3> values) {
  std::vector<double> flat;
  flat.reserve(3 * values.size());
  for (const Vec3& v : values) flat.insert(flat.end(), {v.x(), v.y(), v.z()});
  write_array(group, name, flat);
}

void read_vectors(const hdf5::Group& group, const std::string& name, std::span<Vec3> out) {
  const auto flat = read_array<double>(group, name, 3 * out.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
}

std::vector<Vec3> read_vectors(const hdf5::Group& group, const std::string& name) {
  const auto flat = read_array<double>(group, name);
  if (flat.size() % 3 != 0) {
    throw FileError(
        fmt::format("{}: {}/{} holds {} values, not 3 per vector. Fix: restart from a checkpoint Sabo "
                    "wrote",
                    group.file_name(), group.path(), name, flat.size()));
  }
  std::vector<Vec3> out(flat.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
  return out;
}

void write_series(hdf5::Group& group, const std::string& name, const vtk::TimeSeries& series) {
  std::vector<double> times;
  std::string files;
  for (const auto& entry : series.entries()) {
    times.push_back(entry.time);
    files += entry.file;
    files += '\n';
  }
  write_array(group, name + "_times", times);
  group.set_attribute(name + "_files", files);
}

void read_series(const hdf5::Group& group, const std::string& name, vtk::TimeSeries& series) {
  const auto times = read_array<double>(group, name + "_times");
  const std::string files = group.string_attribute(name + "_files");
  std::vector<vtk::TimeSeries::Entry> entries;
  std::size_t begin = 0;
  for (const double time : times) {
    const std::size_t end = files.find('\n', begin);
    if (end == std::string::npos) {
      throw FileError(
          fmt::format("{}: {}_files names fewer files than {}_times has times. Fix: restart from a "
                      "checkpoint Sabo wrote",
                      group.file_name(), name, name));
    }
    entries.push_back({time, files.substr(begin, end - begin)});
    begin = end + 1;
  }
  series.restore(std::move(entries));
}

void write_file_size(hdf5::Group& group, const std::string& name, const std::filesystem::path& file) {
  std::error_code error;
  const auto size = std::filesystem::file_size(file, error);
  group.set_attribute(name + "_bytes", static_cast<std::int64_t>(error ? 0 : size));
}

bool truncate_to_saved_size(const hdf5::Group& group, const std::string& name, const std::filesystem::path& file) {
  const auto saved = static_cast<std::uintmax_t>(group.int_attribute(name + "_bytes"));
  std::error_code error;
  const auto size = std::filesystem::file_size(file, error);
  if (error) return false;
  if (size < saved) {
    throw FileError(
        fmt::format("{}: {} bytes, shorter than the {} bytes the checkpoint {} had written. Fix: restart "
                    "in the run folder the checkpoint belongs to",
                    file.string(), size, saved, group.file_name()));
  }
  if (size > saved) std::filesystem::resize_file(file, saved);
  return true;
}

}  // namespace sabo::io
