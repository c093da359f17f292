#include "coupler/restart_journal.hpp"

#include <fmt/format.h>
#include <google/protobuf/field_mask.pb.h>
#include <google/protobuf/util/field_mask_util.h>
#include <xxhash.h>

#include <cassert>
#include <set>

#include "libsabo/core/error.hpp"

namespace sabo::coupler {

RestartJournal::RestartJournal(std::filesystem::path file, std::uint64_t limit)
    : path_(std::move(file)), limit_(limit) {
  begin(0);
}

void RestartJournal::begin(std::uint64_t step) {
  // An open journal is written again from its start, not truncated: freeing and allocating again the
  // hundreds of MB a checkpoint interval of a large scene holds stalled the exchange (bytes past size_ are
  // never read).
  if (!file_.is_open()) {
    std::error_code error;
    std::filesystem::create_directories(path_.parent_path(), error);
    file_.open(path_, std::ios::binary | std::ios::in | std::ios::out | std::ios::trunc);
    if (!file_) {
      throw FileError(
          fmt::format("{}: cannot write the restart journal (is the run folder writable?)", path_.string()));
    }
  }
  size_ = 0;
  first_ = step;
  dropped_ = false;
  states_.clear();
  forces_.clear();
}

void RestartJournal::remove() {
  if (file_.is_open()) file_.close();
  std::error_code error;
  std::filesystem::remove(path_, error);
  states_.clear();
  forces_.clear();
}

RestartJournal::Span RestartJournal::append(std::span<const char> bytes) {
  file_.seekp(static_cast<std::streamoff>(size_));
  file_.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!file_) throw FileError(fmt::format("{}: cannot append to the restart journal (disk full?)", path_.string()));
  const Span span{size_, bytes.size()};
  size_ += bytes.size();
  return span;
}

std::string RestartJournal::read(const Span& span) {
  file_.flush();
  std::string bytes(span.size, '\0');
  file_.seekg(static_cast<std::streamoff>(span.offset));
  file_.read(bytes.data(), static_cast<std::streamsize>(span.size));
  if (!file_) throw FileError(fmt::format("{}: cannot read the restart journal back", path_.string()));
  return bytes;
}

namespace {

// XXH3: the states of a large scene are hundreds of kB an exchange (a byte-wise FNV-1a took 270 us
// for 300 kB, a third of the coupling overhead of debris_flow_dam). The digests live in memory only.
std::uint64_t digest_of_bytes(const void* data, std::size_t size) {
  return XXH3_64bits(data, size);
}

template <class T>
std::uint64_t digest_of(const google::protobuf::RepeatedField<T>& values) {
  return digest_of_bytes(values.data(), static_cast<std::size_t>(values.size()) * sizeof(T));
}

std::uint64_t digest_of(const google::protobuf::MessageLite& message) {
  const std::string bytes = message.SerializeAsString();
  return digest_of_bytes(bytes.data(), bytes.size());
}

}  // namespace

const std::vector<std::string>& RestartJournal::field_names() {
  static const std::vector<std::string> names = {
      "step",          "time",          "stable_dt",      "index",    "position", "velocity",        "angular_velocity",
      "node_position", "node_velocity", "boundary_force", "energies", "topology", "the other fields"};
  return names;
}

std::vector<std::uint64_t> RestartJournal::digests(const sabo::v1::StepState& state) {
  const std::uint64_t step = state.step();
  const double time = state.time(), stable_dt = state.stable_dt();
  // The other fields, copied without the large ones (a copy of the whole state cost as much as its digests).
  static const google::protobuf::FieldMask other_fields = [] {
    using S = sabo::v1::StepState;
    const std::set<int> apart = {S::kStepFieldNumber,
                                 S::kTimeFieldNumber,
                                 S::kStableDtFieldNumber,
                                 S::kIndexFieldNumber,
                                 S::kPositionFieldNumber,
                                 S::kVelocityFieldNumber,
                                 S::kAngularVelocityFieldNumber,
                                 S::kNodePositionFieldNumber,
                                 S::kNodeVelocityFieldNumber,
                                 S::kBoundaryForceFieldNumber,
                                 S::kEnergiesFieldNumber,
                                 S::kTopologyFieldNumber,
                                 S::kComputeSecondsFieldNumber,
                                 S::kWaitSecondsFieldNumber,
                                 S::kForcesWaitSecondsFieldNumber};
    google::protobuf::FieldMask mask;
    const auto* descriptor = S::descriptor();
    for (int k = 0; k < descriptor->field_count(); ++k) {
      if (!apart.contains(descriptor->field(k)->number())) mask.add_paths(descriptor->field(k)->name());
    }
    return mask;
  }();
  sabo::v1::StepState rest;
  google::protobuf::util::FieldMaskUtil::MergeMessageTo(state, other_fields, {}, &rest);
  return {digest_of_bytes(&step, sizeof step),
          digest_of_bytes(&time, sizeof time),
          digest_of_bytes(&stable_dt, sizeof stable_dt),
          digest_of(state.index()),
          digest_of(state.position()),
          digest_of(state.velocity()),
          digest_of(state.angular_velocity()),
          digest_of(state.node_position()),
          digest_of(state.node_velocity()),
          digest_of(state.boundary_force()),
          digest_of(state.energies()),
          digest_of(state.topology()),
          digest_of(rest)};
}

void RestartJournal::add_state(const sabo::v1::StepState& state) {
  if (dropped_) return;
  assert(state.step() == first_ + states_.size() && states_.size() == forces_.size());
  states_.push_back(digests(state));
}

void RestartJournal::add_forces(const sabo::v1::StepForces& forces, std::span<const std::uint8_t> serialized) {
  if (dropped_) return;
  assert(forces.step() == first_ + forces_.size() && states_.size() == forces_.size() + 1);
  std::span<const char> bytes(reinterpret_cast<const char*>(serialized.data()), serialized.size());
  if (serialized.empty()) {
    // Into a buffer kept between steps: a fresh string of hundreds of kB a step is fresh pages to fault in.
    if (!forces.SerializeToString(&scratch_)) {
      throw FileError(fmt::format("{}: the forces of step {} do not serialize", path_.string(), forces.step()));
    }
    bytes = scratch_;
  }
  if (size_ + bytes.size() > limit_) {
    // Dropped until the next checkpoint: the file emptied (its space given back), nothing kept.
    dropped_ = true;
    states_.clear();
    forces_.clear();
    size_ = 0;
    file_.close();
    std::error_code error;
    std::filesystem::resize_file(path_, 0, error);
    return;
  }
  forces_.push_back(append(bytes));
}

std::string RestartJournal::first_difference(const sabo::v1::StepState& state) const {
  assert(state.step() >= first_ && state.step() - first_ < states_.size());
  const auto now = digests(state);
  const auto& before = states_[state.step() - first_];
  for (std::size_t k = 0; k < now.size(); ++k) {
    if (now[k] != before[k]) return field_names()[k];
  }
  return {};
}

sabo::v1::StepForces RestartJournal::forces(std::uint64_t step) {
  assert(covers(step));
  sabo::v1::StepForces forces;
  if (!forces.ParseFromString(read(forces_[step - first_]))) {
    throw FileError(fmt::format("{}: the forces of step {} do not parse", path_.string(), step));
  }
  return forces;
}

}  // namespace sabo::coupler
