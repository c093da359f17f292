// traffic.h5's reader (TrafficReader, docs/traffic.md): the recorded messages of a run, by role and step.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <map>
#include <optional>
#include <span>

#include "libsabo/core/error.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/io/traffic.hpp"
#include "libsabo/io/traffic_format.hpp"

namespace sabo::io {

using namespace traffic_format;

namespace {

// The messages of one stream (state or forces) of one role.
class StreamReader {
 public:
  StreamReader(hdf5::Group group, std::string what) : group_(std::move(group)), what_(std::move(what)) {
    // `step` is written last at every flush: its length is the number of
    // complete messages, whatever else a crash left behind.
    steps_ = group_.dataset("step").read_all<std::uint64_t>();
    sorted_ = std::is_sorted(steps_.begin(), steps_.end());
  }

  [[nodiscard]] const std::vector<std::uint64_t>& steps() const { return steps_; }

  // Entry of `step`; the last one if a step was recorded twice.
  [[nodiscard]] std::uint64_t entry(std::uint64_t step) const {
    if (sorted_) {
      auto it = std::upper_bound(steps_.begin(), steps_.end(), step);
      if (it != steps_.begin() && *(it - 1) == step) return static_cast<std::uint64_t>(it - steps_.begin() - 1);
    } else {
      for (std::size_t i = steps_.size(); i-- > 0;) {
        if (steps_[i] == step) return i;
      }
    }
    throw FileError(
        fmt::format("{}: step {} was not recorded ({} steps recorded{}). Fix: ask for a recorded step, "
                    "or record it (scene [recording] every, first_step, last_step)",
                    what_, step, steps_.size(),
                    steps_.empty() ? std::string() : fmt::format(", from {} to {}", steps_.front(), steps_.back())));
  }

  // A per-message value (a scalar, an offset, a count), through the same read-ahead window as the field values:
  // a replay reads every message in turn, and one HDF5 read per value cost more than the replayed process's step.
  template <hdf5::Element T>
  T scalar(const std::string& name, std::uint64_t entry, std::uint64_t per_entry = 1, std::uint64_t at = 0) const {
    T value{};
    read_values<T>(name, entry * per_entry + at, std::span<T>(&value, 1));
    return value;
  }

  [[nodiscard]] bool has(const std::string& name) const {
    auto found = present_.find(name);
    if (found == present_.end()) found = present_.emplace(name, group_.exists(name)).first;
    return found->second;
  }

  // Reads the slice of array field `name` for `entry` into `out`; leaves it
  // empty when the field was not recorded.
  template <hdf5::Element T, class Out>
  void array(const std::string& name, std::uint64_t entry, Out* out) const {
    if (!has(name)) return;
    const auto offset = scalar<std::uint64_t>(name + "_offset", entry);
    const auto count = scalar<std::uint64_t>(name + "_count", entry);
    out->Resize(static_cast<int>(count), T{});
    read_values<T>(name, offset, std::span<T>(out->mutable_data(), count));
  }

  [[nodiscard]] std::string bytes(const std::string& name, std::uint64_t entry) const {
    const auto offset = scalar<std::uint64_t>(name + "_offset", entry);
    const auto count = scalar<std::uint64_t>(name + "_count", entry);
    std::string text(count, '\0');
    read_values<std::uint8_t>(name, offset,
                              std::span<std::uint8_t>(reinterpret_cast<std::uint8_t*>(text.data()), count));
    return text;
  }

  [[nodiscard]] const std::string& what() const { return what_; }

 private:
  const hdf5::Dataset& dataset(const std::string& name) const {
    auto found = datasets_.find(name);
    if (found == datasets_.end()) found = datasets_.emplace(name, group_.dataset(name)).first;
    return found->second;
  }

  // Values [offset, offset + out.size()) of a dataset, through a window read ahead: messages are read in turn,
  // so one HDF5 read serves many of them.
  template <hdf5::Element T>
  void read_values(const std::string& name, std::uint64_t offset, std::span<T> out) const {
    if (out.empty()) return;
    constexpr std::uint64_t kReadAhead = std::uint64_t{1} << 16;  // values
    auto& window = windows_of<T>()[name];
    const std::uint64_t end = offset + out.size();
    if (offset < window.start || end > window.start + window.values.size()) {
      const hdf5::Dataset& data = dataset(name);
      const std::uint64_t size = data.size();
      if (end > size) {
        throw FileError(
            fmt::format("{}: {} holds {} values, a message needs values {} to {}. Fix: the file is "
                        "damaged",
                        what_, name, size, offset, end));
      }
      window.start = offset;
      window.values.resize(std::min(size, offset + std::max<std::uint64_t>(out.size(), kReadAhead)) - offset);
      data.read<T>(offset, std::span<T>(window.values));
    }
    std::copy_n(window.values.begin() + static_cast<std::ptrdiff_t>(offset - window.start), out.size(), out.begin());
  }

  template <hdf5::Element T>
  struct Window {
    std::uint64_t start = 0;
    std::vector<T> values;
  };
  template <hdf5::Element T>
  std::map<std::string, Window<T>, std::less<>>& windows_of() const {
    if constexpr (std::same_as<T, double>) return double_windows_;
    if constexpr (std::same_as<T, std::uint64_t>) return count_windows_;
    if constexpr (std::same_as<T, std::uint32_t>) return index_windows_;
    if constexpr (std::same_as<T, std::uint8_t>) return byte_windows_;
  }

  hdf5::Group group_;
  std::string what_;
  std::vector<std::uint64_t> steps_;
  bool sorted_ = true;
  mutable std::map<std::string, hdf5::Dataset, std::less<>> datasets_;
  mutable std::map<std::string, bool, std::less<>> present_;  // which fields were recorded
  mutable std::map<std::string, Window<double>, std::less<>> double_windows_;
  mutable std::map<std::string, Window<std::uint64_t>, std::less<>> count_windows_;
  mutable std::map<std::string, Window<std::uint32_t>, std::less<>> index_windows_;
  mutable std::map<std::string, Window<std::uint8_t>, std::less<>> byte_windows_;
};

struct RoleReader {
  RoleReader(hdf5::Group group, const std::string& file, const std::string& role)
      : registration_count(group.dataset("registration_count").size()),
        registration_group(group),
        state(group.group("state"), fmt::format("{}: {} states", file, role)),
        forces(group.group("forces"), fmt::format("{}: {} forces", file, role)) {}
  std::uint64_t registration_count;
  hdf5::Group registration_group;
  StreamReader state;
  StreamReader forces;
};

template <class Message>
void parse(Message& message, const std::string& bytes, const std::string& what) {
  if (!message.ParseFromString(bytes)) {
    throw FileError(fmt::format("{}: the recorded {} does not parse. Fix: the file is damaged", what,
                                Message::descriptor()->name()));
  }
}

}  // namespace

struct TrafficReader::Impl {
  explicit Impl(const std::filesystem::path& file_in) : path(file_in) {
    file = hdf5::File::open(path, hdf5::Access::swmr_read);
    if (!file.has_attribute("format") || file.string_attribute("format") != kFormatName) {
      throw FileError(
          fmt::format("{}: not a sabo traffic recording (no attribute format = '{}'). Fix: open the "
                      "traffic.h5 of a run folder",
                      path.string(), kFormatName));
    }
    version = file.int_attribute("format_version");
    if (version < kOldestReadVersion || version > kFormatVersion) {
      throw FileError(
          fmt::format("{}: traffic format version {} but this program reads versions {} to {}. Fix: read it "
                      "with the sabo version that wrote it",
                      path.string(), version, kOldestReadVersion, kFormatVersion));
    }
    for (const auto& name : file.children()) {
      if (name == "scene") continue;
      roles.emplace(name, std::make_unique<RoleReader>(file.group(name), path.string(), name));
    }
  }

  const RoleReader& role(const std::string& name) const {
    auto found = roles.find(name);
    if (found == roles.end()) {
      std::vector<std::string> names;
      for (const auto& [recorded, unused] : roles) names.push_back(recorded);
      throw FileError(fmt::format("{}: no role '{}' in the recording (it has {})", path.string(), name,
                                  fmt::format("{}", fmt::join(names, ", "))));
    }
    return *found->second;
  }

  std::filesystem::path path;
  std::int64_t version = kFormatVersion;
  hdf5::File file;
  std::map<std::string, std::unique_ptr<RoleReader>, std::less<>> roles;
};

TrafficReader::TrafficReader(const std::filesystem::path& file) : impl_(std::make_unique<Impl>(file)) {}

TrafficReader::~TrafficReader() = default;

std::string TrafficReader::scene_text() const {
  const auto bytes = impl_->file.dataset("scene").read_all<std::uint8_t>();
  return {bytes.begin(), bytes.end()};
}

std::vector<std::string> TrafficReader::recorded_fields() const {
  const std::string fields = impl_->file.string_attribute("fields");
  if (fields == "all") return traffic_field_names();
  std::vector<std::string> names;
  std::size_t start = 0;
  while (start <= fields.size()) {
    const std::size_t comma = std::min(fields.find(',', start), fields.size());
    std::string name = fields.substr(start, comma - start);
    name.erase(0, name.find_first_not_of(' '));
    if (!name.empty()) names.push_back(name);
    start = comma + 1;
  }
  return names;
}

std::uint64_t TrafficReader::every() const {
  return static_cast<std::uint64_t>(impl_->file.int_attribute("every"));
}

std::vector<std::string> TrafficReader::roles() const {
  std::vector<std::string> names;
  for (const auto& [name, reader] : impl_->roles) {
    if (reader->registration_count > 0 || !reader->state.steps().empty() || !reader->forces.steps().empty()) {
      names.push_back(name);
    }
  }
  return names;
}

std::vector<std::uint64_t> TrafficReader::steps(const std::string& role) const {
  return impl_->role(role).state.steps();
}

std::vector<std::uint64_t> TrafficReader::force_steps(const std::string& role) const {
  return impl_->role(role).forces.steps();
}

sabo::v1::StepState TrafficReader::state(const std::string& role, std::uint64_t step) const {
  const StreamReader& stream = impl_->role(role).state;
  const std::uint64_t entry = stream.entry(step);
  sabo::v1::StepState message;
  message.set_step(step);
  message.set_time(stream.scalar<double>("time", entry));
  message.set_stable_dt(stream.scalar<double>("stable_dt", entry));
  message.set_compute_seconds(stream.scalar<double>("timing", entry, 2, 0));
  message.set_wait_seconds(stream.scalar<double>("timing", entry, 2, 1));
  if (impl_->version >= kHoldColumnsVersion && stream.scalar<std::uint8_t>("held", entry) != 0) message.set_held(true);
  if (stream.has("energies")) {
    auto* energies = message.mutable_energies();
    energies->set_kinetic(stream.scalar<double>("energies", entry, 4, 0));
    energies->set_potential(stream.scalar<double>("energies", entry, 4, 1));
    energies->set_elastic(stream.scalar<double>("energies", entry, 4, 2));
    energies->set_dissipated(stream.scalar<double>("energies", entry, 4, 3));
  }
  stream.array<std::uint32_t>("index", entry, message.mutable_index());
  stream.array<double>("position", entry, message.mutable_position());
  stream.array<double>("velocity", entry, message.mutable_velocity());
  stream.array<double>("angular_velocity", entry, message.mutable_angular_velocity());
  stream.array<double>("node_position", entry, message.mutable_node_position());
  stream.array<double>("node_velocity", entry, message.mutable_node_velocity());
  stream.array<double>("boundary_force", entry, message.mutable_boundary_force());
  google::protobuf::RepeatedField<std::uint64_t> boundary_step;
  stream.array<std::uint64_t>("boundary_step", entry, &boundary_step);
  if (!boundary_step.empty()) message.set_boundary_step(boundary_step[0]);
  const std::string table = stream.bytes("particle_table", entry);
  if (!table.empty()) parse(*message.mutable_particle_table(), table, stream.what());
  const std::string topology = stream.bytes("topology", entry);
  if (!topology.empty()) parse(*message.mutable_topology(), topology, stream.what());
  return message;
}

sabo::v1::StepForces TrafficReader::forces(const std::string& role, std::uint64_t step) const {
  const StreamReader& stream = impl_->role(role).forces;
  const std::uint64_t entry = stream.entry(step);
  sabo::v1::StepForces message;
  message.set_step(step);
  message.set_dt(stream.scalar<double>("dt", entry));
  const auto bits = stream.scalar<std::uint8_t>("flags", entry);
  message.set_checkpoint((bits & kFlagCheckpoint) != 0);
  message.set_output((bits & kFlagOutput) != 0);
  message.set_stop((bits & kFlagStop) != 0);
  message.set_interest_all((bits & kFlagInterestAll) != 0);
  const std::uint32_t substeps = impl_->version >= kSubstepsColumnVersion
                                     ? stream.scalar<std::uint8_t>("substeps", entry)
                                     : 1u << (bits >> kVersion1SubstepsShift);
  if (substeps > 1) message.set_substeps(substeps);
  if (impl_->version >= kHoldColumnsVersion) {
    message.set_hold((bits & kFlagHold) != 0);
    const std::uint32_t holds = stream.scalar<std::uint8_t>("holds", entry);
    if (holds > 0) message.set_holds(holds);
  }
  stream.array<std::uint32_t>("index", entry, message.mutable_index());
  stream.array<double>("force", entry, message.mutable_force());
  stream.array<double>("torque", entry, message.mutable_torque());
  stream.array<double>("node_force", entry, message.mutable_node_force());
  stream.array<double>("boundary_position", entry, message.mutable_boundary_position());
  stream.array<double>("boundary_velocity", entry, message.mutable_boundary_velocity());
  stream.array<double>("boundary_normal", entry, message.mutable_boundary_normal());
  stream.array<double>("boundary_acceleration", entry, message.mutable_boundary_acceleration());
  stream.array<double>("boundary_volume", entry, message.mutable_boundary_volume());
  stream.array<std::uint32_t>("boundary_free_slip", entry, message.mutable_boundary_free_slip());
  google::protobuf::RepeatedField<double> boxes;
  stream.array<double>("interest", entry, &boxes);
  for (int i = 0; i + 6 <= boxes.size(); i += 6) {
    auto* box = message.add_interest();
    box->set_min_x(boxes[i]);
    box->set_min_y(boxes[i + 1]);
    box->set_min_z(boxes[i + 2]);
    box->set_max_x(boxes[i + 3]);
    box->set_max_y(boxes[i + 4]);
    box->set_max_z(boxes[i + 5]);
  }
  return message;
}

sabo::v1::Register TrafficReader::registration(const std::string& role) const {
  const RoleReader& reader = impl_->role(role);
  const std::string what = fmt::format("{}: {} registration", impl_->path.string(), role);
  if (reader.registration_count == 0) {
    throw FileError(fmt::format("{}: none was recorded (the solver never registered, or the run died before)", what));
  }
  const std::uint64_t entry = reader.registration_count - 1;
  const auto& group = reader.registration_group;
  std::uint64_t offset = 0;
  std::uint64_t count = 0;
  group.dataset("registration_offset").read<std::uint64_t>(entry, std::span<std::uint64_t>(&offset, 1));
  group.dataset("registration_count").read<std::uint64_t>(entry, std::span<std::uint64_t>(&count, 1));
  std::string bytes(count, '\0');
  group.dataset("registration")
      .read<std::uint8_t>(offset, std::span<std::uint8_t>(reinterpret_cast<std::uint8_t*>(bytes.data()), count));
  sabo::v1::Register message;
  parse(message, bytes, what);
  return message;
}

}  // namespace sabo::io
