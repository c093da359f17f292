// traffic.h5's recorder (TrafficRecorder, docs/traffic.md): every message of a run, one HDF5 dataset per
// field and role, written in chunks and flushed on an interval; the reader is traffic_reader.cpp.
#include "libsabo/io/traffic.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <map>
#include <optional>
#include <span>

#include "libsabo/core/error.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/io/traffic_format.hpp"

namespace sabo::io {
namespace {

using namespace traffic_format;

// Entries per chunk of the per-message datasets (step, time, offsets, ...).
constexpr std::uint64_t kEntryChunk = 512;
// Values per chunk of the field datasets. A flush rewrites the partly filled
// last chunk of every dataset it touches, so this bounds the cost of a flush.
constexpr std::uint64_t kValueChunk = 8192;
// Flush regardless of the interval when this much is buffered.
constexpr std::size_t kMaxPendingBytes = std::size_t{64} << 20;

const std::vector<std::string> kFieldNames = {"position", "velocity",           "angular_velocity", "force",
                                              "torque",   "node_position",      "node_velocity",    "node_force",
                                              "energies", "boundary_particles", "boundary_force"};

template <class T>
std::span<const T> span_of(const google::protobuf::RepeatedField<T>& field) {
  return {field.data(), static_cast<std::size_t>(field.size())};
}

std::span<const std::uint8_t> bytes_of(const std::string& text) {
  return {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()};
}

// Which optional fields are recorded.
struct Selection {
  bool position = false, velocity = false, angular_velocity = false, force = false, torque = false;
  bool node_position = false, node_velocity = false, node_force = false, energies = false;
  // SPH walls: the boundary particles sent (StepForces boundary_*) and the
  // fluid's forces on them with their boundary_step (StepState).
  bool boundary_particles = false, boundary_force = false;

  explicit Selection(const std::vector<std::string>& fields) {
    const bool all = fields.empty();
    auto wants = [&](const char* name) { return all || std::find(fields.begin(), fields.end(), name) != fields.end(); };
    for (const auto& field : fields) {
      if (std::find(kFieldNames.begin(), kFieldNames.end(), field) == kFieldNames.end()) {
        throw SceneError(fmt::format("recording.fields: unknown field '{}'. Fix: use some of {}", field,
                                     fmt::join(kFieldNames, ", ")));
      }
    }
    position = wants("position");
    velocity = wants("velocity");
    angular_velocity = wants("angular_velocity");
    force = wants("force");
    torque = wants("torque");
    node_position = wants("node_position");
    node_velocity = wants("node_velocity");
    node_force = wants("node_force");
    energies = wants("energies");
    boundary_particles = wants("boundary_particles");
    boundary_force = wants("boundary_force");
  }
};

// Flush order: a later stage is written only after every earlier one is on disk.
enum Stage : std::size_t { kValues = 0, kIndex = 1, kScalars = 2, kCommit = 3, kStageCount = 4 };

class ColumnBase {
 public:
  virtual ~ColumnBase() = default;
  virtual std::uint64_t flush() = 0;  // payload bytes written
  [[nodiscard]] virtual std::size_t pending_bytes() const = 0;
};

using Stages = std::array<std::vector<ColumnBase*>, kStageCount>;

// One dataset and the values recorded for it since the last flush. The
// buffer keeps its capacity, so steady recording does not allocate.
template <hdf5::Element T>
class Column final : public ColumnBase {
 public:
  Column(hdf5::Group& group, const std::string& name, std::uint64_t chunk, Stages& stages, Stage stage)
      : name_(name), dataset_(group.create_dataset<T>(name, chunk)) {
    stages[stage].push_back(this);
  }
  Column(const Column&) = delete;
  Column& operator=(const Column&) = delete;

  void push(T value) {
    pending_.push_back(value);
    ++total_;
  }
  void push(std::span<const T> values) {
    pending_.insert(pending_.end(), values.begin(), values.end());
    total_ += values.size();
  }
  [[nodiscard]] std::uint64_t total() const { return total_; }

  std::uint64_t flush() override {
    if (pending_.empty()) return 0;
    dataset_.append<T>(pending_);
    dataset_.flush();
    const std::uint64_t bytes = pending_.size() * sizeof(T);
    pending_.clear();
    return bytes;
  }
  [[nodiscard]] std::size_t pending_bytes() const override { return pending_.size() * sizeof(T); }

  // Takes the first `n` values of the dataset of the same name in `old` (a recording being continued);
  // returns the payload bytes written.
  std::uint64_t carry(const hdf5::Group& old, std::uint64_t n) {
    if (n == 0) return 0;
    const hdf5::Dataset source = old.dataset(name_);
    if (source.size() < n) {
      throw FileError(
          fmt::format("{}: {} values where the recording's index needs {}. Fix: the file is damaged; "
                      "start the run again",
                      source.path(), source.size(), n));
    }
    constexpr std::uint64_t kBlock = std::uint64_t{1} << 20;
    std::vector<T> block;
    for (std::uint64_t at = 0; at < n; at += kBlock) {
      block.resize(std::min(kBlock, n - at));
      source.read<T>(at, std::span<T>(block));
      dataset_.append<T>(block);
    }
    dataset_.flush();
    total_ += n;
    return n * sizeof(T);
  }

 private:
  std::string name_;
  hdf5::Dataset dataset_;
  std::vector<T> pending_;
  std::uint64_t total_ = 0;  // values recorded, flushed or not
};

// A field with a variable number of values per message.
template <hdf5::Element T>
struct ArrayColumn {
  ArrayColumn(hdf5::Group& group, const std::string& name_in, Stages& stages, Stage count_stage = kIndex)
      : name(name_in),
        values(group, name_in, kValueChunk, stages, kValues),
        offset(group, name_in + "_offset", kEntryChunk, stages, kIndex),
        count(group, name_in + "_count", kEntryChunk, stages, count_stage) {}
  void push(std::span<const T> data) {
    offset.push(values.total());
    count.push(data.size());
    values.push(data);
  }
  // The first `entries` messages' slices of this field in `old`.
  std::uint64_t carry(const hdf5::Group& old, std::uint64_t entries) {
    std::uint64_t end = 0;
    if (entries > 0) {
      std::array<std::uint64_t, 2> last{};
      old.dataset(offset_name()).template read<std::uint64_t>(entries - 1, std::span<std::uint64_t>(&last[0], 1));
      old.dataset(count_name()).template read<std::uint64_t>(entries - 1, std::span<std::uint64_t>(&last[1], 1));
      end = last[0] + last[1];
    }
    return offset.carry(old, entries) + count.carry(old, entries) + values.carry(old, end);
  }
  [[nodiscard]] std::string offset_name() const { return name + "_offset"; }
  [[nodiscard]] std::string count_name() const { return name + "_count"; }
  std::string name;
  Column<T> values;
  Column<std::uint64_t> offset;
  Column<std::uint64_t> count;
};

template <hdf5::Element T>
using OptionalArray = std::optional<ArrayColumn<T>>;

template <hdf5::Element T>
void emplace_if(bool wanted, OptionalArray<T>& column, hdf5::Group& group, const char* name, Stages& stages) {
  if (wanted) column.emplace(group, name, stages);
}

template <hdf5::Element T>
std::uint64_t carry_if(OptionalArray<T>& column, const hdf5::Group& old, std::uint64_t entries) {
  return column ? column->carry(old, entries) : 0;
}

// The messages of a stream in `old` of steps before `step` (the `step` dataset is written last at every
// flush, so its length counts the complete messages).
std::uint64_t entries_before(const hdf5::Group& old, std::uint64_t step) {
  const auto steps = old.dataset("step").read_all<std::uint64_t>();
  return static_cast<std::uint64_t>(
      std::find_if(steps.begin(), steps.end(), [&](std::uint64_t s) { return s >= step; }) - steps.begin());
}

struct StateStream {
  StateStream(hdf5::Group group_in, const Selection& selection, Stages& stages)
      : group(std::move(group_in)),
        step(group, "step", kEntryChunk, stages, kCommit),
        time(group, "time", kEntryChunk, stages, kScalars),
        stable_dt(group, "stable_dt", kEntryChunk, stages, kScalars),
        timing(group, "timing", kEntryChunk * 2, stages, kScalars),
        held(group, "held", kEntryChunk, stages, kScalars),
        particle_table(group, "particle_table", stages),
        topology(group, "topology", stages) {
    if (selection.energies) energies.emplace(group, "energies", kEntryChunk * 4, stages, kScalars);
    emplace_if(selection.position || selection.velocity || selection.angular_velocity, index, group, "index", stages);
    emplace_if(selection.position, position, group, "position", stages);
    emplace_if(selection.velocity, velocity, group, "velocity", stages);
    emplace_if(selection.angular_velocity, angular_velocity, group, "angular_velocity", stages);
    emplace_if(selection.node_position, node_position, group, "node_position", stages);
    emplace_if(selection.node_velocity, node_velocity, group, "node_velocity", stages);
    emplace_if(selection.boundary_force, boundary_force, group, "boundary_force", stages);
    emplace_if(selection.boundary_force, boundary_step, group, "boundary_step", stages);
  }

  void record(const sabo::v1::StepState& message, std::string& scratch) {
    step.push(message.step());
    time.push(message.time());
    stable_dt.push(message.stable_dt());
    timing.push(message.compute_seconds());
    timing.push(message.wait_seconds());
    held.push(static_cast<std::uint8_t>(message.held() ? 1 : 0));
    if (energies) {
      const auto& e = message.energies();
      const std::array<double, 4> values{e.kinetic(), e.potential(), e.elastic(), e.dissipated()};
      energies->push(std::span<const double>(values));
    }
    if (index) index->push(span_of(message.index()));
    if (position) position->push(span_of(message.position()));
    if (velocity) velocity->push(span_of(message.velocity()));
    if (angular_velocity) angular_velocity->push(span_of(message.angular_velocity()));
    if (node_position) node_position->push(span_of(message.node_position()));
    if (node_velocity) node_velocity->push(span_of(message.node_velocity()));
    if (boundary_force) boundary_force->push(span_of(message.boundary_force()));
    if (boundary_step) {
      // Optional on the wire: 1 value when present, 0 when absent.
      const std::uint64_t value = message.boundary_step();
      boundary_step->push(message.has_boundary_step() ? std::span<const std::uint64_t>(&value, 1)
                                                      : std::span<const std::uint64_t>());
    }
    scratch.clear();
    if (message.has_particle_table()) message.particle_table().SerializeToString(&scratch);
    particle_table.push(bytes_of(scratch));
    scratch.clear();
    if (message.has_topology()) message.topology().SerializeToString(&scratch);
    topology.push(bytes_of(scratch));
  }

  // The states of steps before `before` in `old`, this stream's group of a recording being continued.
  std::uint64_t carry(const hdf5::Group& old, std::uint64_t before) {
    const std::uint64_t n = entries_before(old, before);
    std::uint64_t bytes = time.carry(old, n) + stable_dt.carry(old, n) + timing.carry(old, 2 * n) + held.carry(old, n);
    if (energies) bytes += energies->carry(old, 4 * n);
    bytes += carry_if(index, old, n);
    for (auto* column : {&position, &velocity, &angular_velocity, &node_position, &node_velocity, &boundary_force}) {
      bytes += carry_if(*column, old, n);
    }
    bytes += carry_if(boundary_step, old, n);
    bytes += particle_table.carry(old, n) + topology.carry(old, n);
    return bytes + step.carry(old, n);
  }

  hdf5::Group group;
  Column<std::uint64_t> step;
  Column<double> time, stable_dt, timing;
  Column<std::uint8_t> held;
  std::optional<Column<double>> energies;
  OptionalArray<std::uint32_t> index;
  OptionalArray<double> position, velocity, angular_velocity, node_position, node_velocity, boundary_force;
  OptionalArray<std::uint64_t> boundary_step;
  ArrayColumn<std::uint8_t> particle_table, topology;
};

struct ForcesStream {
  ForcesStream(hdf5::Group group_in, const Selection& selection, Stages& stages)
      : group(std::move(group_in)),
        step(group, "step", kEntryChunk, stages, kCommit),
        dt(group, "dt", kEntryChunk, stages, kScalars),
        flags(group, "flags", kEntryChunk, stages, kScalars),
        substeps(group, "substeps", kEntryChunk, stages, kScalars),
        holds(group, "holds", kEntryChunk, stages, kScalars),
        interest(group, "interest", stages) {
    emplace_if(selection.force || selection.torque, index, group, "index", stages);
    emplace_if(selection.force, force, group, "force", stages);
    emplace_if(selection.torque, torque, group, "torque", stages);
    emplace_if(selection.node_force, node_force, group, "node_force", stages);
    const bool walls = selection.boundary_particles;
    emplace_if(walls, boundary_position, group, "boundary_position", stages);
    emplace_if(walls, boundary_velocity, group, "boundary_velocity", stages);
    emplace_if(walls, boundary_normal, group, "boundary_normal", stages);
    emplace_if(walls, boundary_acceleration, group, "boundary_acceleration", stages);
    emplace_if(walls, boundary_volume, group, "boundary_volume", stages);
    emplace_if(walls, boundary_free_slip, group, "boundary_free_slip", stages);
  }

  void record(const sabo::v1::StepForces& message, std::vector<double>& scratch) {
    step.push(message.step());
    dt.push(message.dt());
    std::uint8_t bits = 0;
    if (message.checkpoint()) bits |= kFlagCheckpoint;
    if (message.output()) bits |= kFlagOutput;
    if (message.stop()) bits |= kFlagStop;
    if (message.interest_all()) bits |= kFlagInterestAll;
    if (message.hold()) bits |= kFlagHold;
    flags.push(bits);
    const std::uint32_t steps = std::max<std::uint32_t>(message.substeps(), 1);
    assert(steps <= kMaxRecordedSubsteps && "at most solver::kMaxSubsteps");
    substeps.push(static_cast<std::uint8_t>(steps));
    assert(message.holds() <= kMaxRecordedHolds && "at most coupler::kMaxHeldExchanges - 1");
    holds.push(static_cast<std::uint8_t>(message.holds()));
    if (index) index->push(span_of(message.index()));
    if (force) force->push(span_of(message.force()));
    if (torque) torque->push(span_of(message.torque()));
    if (node_force) node_force->push(span_of(message.node_force()));
    if (boundary_position) {
      boundary_position->push(span_of(message.boundary_position()));
      boundary_velocity->push(span_of(message.boundary_velocity()));
      boundary_normal->push(span_of(message.boundary_normal()));
      boundary_acceleration->push(span_of(message.boundary_acceleration()));
      boundary_volume->push(span_of(message.boundary_volume()));
      boundary_free_slip->push(span_of(message.boundary_free_slip()));
    }
    scratch.clear();
    for (const auto& box : message.interest()) {
      scratch.insert(scratch.end(), {box.min_x(), box.min_y(), box.min_z(), box.max_x(), box.max_y(), box.max_z()});
    }
    interest.push(scratch);
  }

  std::uint64_t carry(const hdf5::Group& old, std::uint64_t before) {
    const std::uint64_t n = entries_before(old, before);
    std::uint64_t bytes =
        dt.carry(old, n) + flags.carry(old, n) + substeps.carry(old, n) + holds.carry(old, n) + carry_if(index, old, n);
    for (auto* column : {&force, &torque, &node_force, &boundary_position, &boundary_velocity, &boundary_normal,
                         &boundary_acceleration, &boundary_volume}) {
      bytes += carry_if(*column, old, n);
    }
    bytes += carry_if(boundary_free_slip, old, n);
    bytes += interest.carry(old, n);
    return bytes + step.carry(old, n);
  }

  hdf5::Group group;
  Column<std::uint64_t> step;
  Column<double> dt;
  Column<std::uint8_t> flags, substeps, holds;
  OptionalArray<std::uint32_t> index;
  OptionalArray<double> force, torque, node_force;
  OptionalArray<double> boundary_position, boundary_velocity, boundary_normal, boundary_acceleration, boundary_volume;
  OptionalArray<std::uint32_t> boundary_free_slip;
  ArrayColumn<double> interest;
};

struct RoleRecord {
  RoleRecord(hdf5::Group group_in, const Selection& selection, Stages& stages)
      : group(std::move(group_in)),
        registration(group, "registration", stages, kCommit),
        state(group.create_group("state"), selection, stages),
        forces(group.create_group("forces"), selection, stages) {}
  // Every registration of `old` (this role's group of a recording being continued), and its messages of
  // steps before `before`.
  std::uint64_t carry(const hdf5::Group& old, std::uint64_t before) {
    return registration.carry(old, old.dataset(registration.count_name()).size()) +
           state.carry(old.group("state"), before) + forces.carry(old.group("forces"), before);
  }

  hdf5::Group group;
  ArrayColumn<std::uint8_t> registration;
  StateStream state;
  ForcesStream forces;
};

std::string join(const std::vector<std::string>& names) {
  return fmt::format("{}", fmt::join(names, ", "));
}

std::vector<std::string> all_roles() {
  std::vector<std::string> names;
  for (const Role role : kRoles) names.emplace_back(role_name(role));
  return names;
}

}  // namespace

const std::vector<std::string>& traffic_field_names() {
  return kFieldNames;
}

struct TrafficRecorder::Impl {
  Impl(const std::filesystem::path& file, const scene::Recording& settings_in, const std::string& scene_text,
       const std::vector<std::string>& roles, std::optional<std::uint64_t> continue_at = {})
      : path(file), settings(settings_in), selection(settings_in.fields) {
    if (settings.every == 0) {
      throw SceneError("recording.every = 0: must be at least 1. Fix: record every N-th step with N >= 1");
    }
    hdf5::File old;
    if (continue_at) old = open_to_continue(file, scene_text);
    // Built under a temporary name and renamed once in SWMR mode: a file
    // named `file` is always a consistent recording.
    std::filesystem::path partial = file;
    partial += ".partial";
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    hdf5_file = hdf5::File::create(partial, /*swmr=*/true);
    hdf5_file.set_attribute("format", kFormatName);
    hdf5_file.set_attribute("format_version", kFormatVersion);
    hdf5_file.set_attribute("fields", settings.fields.empty() ? std::string("all") : join(settings.fields));
    hdf5_file.set_attribute("every", static_cast<std::int64_t>(settings.every));
    hdf5_file.set_attribute("first_step", static_cast<std::int64_t>(settings.first_step));
    hdf5_file.set_attribute("last_step", settings.last_step >= static_cast<std::uint64_t>(INT64_MAX)
                                             ? std::int64_t{-1}
                                             : static_cast<std::int64_t>(settings.last_step));
    auto scene_dataset = hdf5_file.create_dataset<std::uint8_t>(
        "scene", std::clamp<std::uint64_t>(scene_text.size(), 1, std::uint64_t{1} << 16));
    scene_dataset.append(bytes_of(scene_text));
    for (const auto& role : roles) {
      records.emplace(role, std::make_unique<RoleRecord>(hdf5_file.create_group(role), selection, stages));
    }
    if (continue_at) {
      for (const auto& [role, record] : records) {
        if (old.exists(role)) bytes += record->carry(old.group(role), *continue_at);
      }
      old.close();
    }
    hdf5_file.start_swmr_write();
    std::error_code error;
    std::filesystem::rename(partial, file, error);
    if (error) {
      throw FileError(fmt::format("{}: cannot rename the new recording to {}: {}", partial.string(), file.string(),
                                  error.message()));
    }
    last_flush = std::chrono::steady_clock::now();
  }

  // The recording a continued run started, checked to be of this scene and format.
  static hdf5::File open_to_continue(const std::filesystem::path& file, const std::string& scene_text) {
    hdf5::File old;
    try {
      old = hdf5::File::open(file, hdf5::Access::swmr_read);
    } catch (const LibraryError& error) {
      throw FileError(
          fmt::format("{}: the recording to continue does not open ({}). Fix: restore it from a copy, or "
                      "start the run again in a new folder",
                      file.string(), error.what()));
    }
    if (!old.has_attribute("format") || old.string_attribute("format") != kFormatName ||
        old.int_attribute("format_version") != kFormatVersion) {
      throw FileError(
          fmt::format("{}: not a sabo traffic recording of format version {}: it cannot be continued. "
                      "Fix: start the run again in a new folder",
                      file.string(), kFormatVersion));
    }
    const auto recorded_scene = old.dataset("scene").read_all<std::uint8_t>();
    if (std::string(recorded_scene.begin(), recorded_scene.end()) != scene_text) {
      throw FileError(
          fmt::format("{}: recorded with another scene text than the run's scene: it cannot be "
                      "continued. Fix: resume with the scene the run was started with, unchanged",
                      file.string()));
    }
    return old;
  }

  RoleRecord& record(const std::string& role) {
    if (closed) throw Error(fmt::format("traffic recorder '{}': recording after close()", path.string()));
    auto found = records.find(role);
    if (found == records.end()) {
      std::vector<std::string> names;
      for (const auto& [name, unused] : records) names.push_back(name);
      throw Error(
          fmt::format("traffic recorder '{}': unknown role '{}' (the file has {})", path.string(), role, join(names)));
    }
    return *found->second;
  }

  void flush() {
    for (const auto& stage : stages) {
      for (ColumnBase* column : stage) bytes += column->flush();
    }
    last_flush = std::chrono::steady_clock::now();
  }

  [[nodiscard]] std::size_t pending_bytes() const {
    std::size_t total = 0;
    for (const auto& stage : stages) {
      for (const ColumnBase* column : stage) total += column->pending_bytes();
    }
    return total;
  }

  [[nodiscard]] bool recorded(std::uint64_t step) const {
    return step >= settings.first_step && step <= settings.last_step &&
           (step - settings.first_step) % settings.every == 0;
  }

  void close() {
    if (closed) return;
    closed = true;  // even if the flush throws: do not try twice
    flush();
    stages = {};
    records.clear();
    hdf5_file.close();
  }

  std::filesystem::path path;
  scene::Recording settings;
  Selection selection;
  hdf5::File hdf5_file;
  Stages stages;
  std::map<std::string, std::unique_ptr<RoleRecord>, std::less<>> records;
  std::string message_scratch;
  std::vector<double> box_scratch;
  std::uint64_t bytes = 0;
  std::chrono::steady_clock::time_point last_flush;
  bool closed = false;
};

TrafficRecorder::TrafficRecorder(const std::filesystem::path& file, const scene::Recording& settings,
                                 const std::string& scene_text)
    : TrafficRecorder(file, settings, scene_text, all_roles()) {}

TrafficRecorder::TrafficRecorder(const std::filesystem::path& file, const scene::Recording& settings,
                                 const std::string& scene_text, const std::vector<std::string>& roles)
    : impl_(std::make_unique<Impl>(file, settings, scene_text, roles)) {}

TrafficRecorder::TrafficRecorder(const std::filesystem::path& file, const scene::Recording& settings,
                                 const std::string& scene_text, ContinueAt continue_at)
    : impl_(std::make_unique<Impl>(file, settings, scene_text, all_roles(), continue_at.step)) {}

TrafficRecorder::~TrafficRecorder() {
  try {
    close();
  } catch (...) {
    // A destructor must not throw; call close() to see the error.
  }
}

void TrafficRecorder::record_registration(const std::string& role, const sabo::v1::Register& message) {
  auto& column = impl_->record(role).registration;
  message.SerializeToString(&impl_->message_scratch);
  column.push(bytes_of(impl_->message_scratch));
  // Rare and needed for everything after it: on disk at once, count last.
  impl_->bytes += column.values.flush();
  impl_->bytes += column.offset.flush();
  impl_->bytes += column.count.flush();
}

void TrafficRecorder::record_state(const std::string& role, const sabo::v1::StepState& message) {
  if (!impl_->recorded(message.step())) return;
  impl_->record(role).state.record(message, impl_->message_scratch);
}

void TrafficRecorder::record_forces(const std::string& role, const sabo::v1::StepForces& message) {
  if (!impl_->recorded(message.step())) return;
  impl_->record(role).forces.record(message, impl_->box_scratch);
}

void TrafficRecorder::end_step(std::uint64_t /*step*/) {
  if (impl_->closed) return;
  const double interval = impl_->settings.flush_interval;
  const auto elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - impl_->last_flush).count();
  if (interval <= 0 || elapsed >= interval || impl_->pending_bytes() >= kMaxPendingBytes) impl_->flush();
}

void TrafficRecorder::flush() {
  if (!impl_->closed) impl_->flush();
}

void TrafficRecorder::close() {
  impl_->close();
}

bool TrafficRecorder::recorded(std::uint64_t step) const {
  return impl_->recorded(step);
}

std::uint64_t TrafficRecorder::bytes_written() const {
  return impl_->bytes;
}

const std::filesystem::path& TrafficRecorder::path() const {
  return impl_->path;
}

}  // namespace sabo::io
