#include "coupler/accounting.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"

namespace sabo::coupler {

double pairs_on_critical_path(const std::vector<SolverCycle>& cycles, const PairSeconds& pairs) {
  const SolverCycle* slowest = nullptr;
  for (const SolverCycle& c : cycles) {
    if (slowest == nullptr || c.compute > slowest->compute) slowest = &c;
  }
  if (slowest == nullptr) return 0.0;
  if (!slowest->waited_for_forces) return std::min(pairs.all, slowest->waited);
  const double for_forces = std::clamp(*slowest->waited_for_forces, 0.0, slowest->waited);
  return std::min(pairs.walls_ahead, slowest->waited - for_forces) +
         std::min(std::max(0.0, pairs.all - pairs.walls_ahead), for_forces);
}

std::FILE* open_for_writing(const std::filesystem::path& file) {
  std::FILE* handle = std::fopen(file.c_str(), "w");
  if (handle == nullptr) throw FileError(fmt::format("cannot create '{}': {}", file.string(), std::strerror(errno)));
  return handle;
}

std::FILE* open_for_appending(const std::filesystem::path& file) {
  std::FILE* handle = std::fopen(file.c_str(), "a");
  if (handle == nullptr) throw FileError(fmt::format("cannot append to '{}': {}", file.string(), std::strerror(errno)));
  return handle;
}

namespace {

// Names joined by '\n': how a list of names is kept in one attribute.
std::string joined(const std::vector<std::string>& names) {
  std::string text;
  for (const auto& name : names) text += name + "\n";
  return text;
}

void check_names(const io::hdf5::Group& group, const char* attribute, const std::vector<std::string>& names,
                 const char* what) {
  if (group.string_attribute(attribute) != joined(names)) {
    throw FileError(
        fmt::format("{}: the checkpoint's {} are not this scene's. Fix: resume with the scene the run "
                    "was started with, unchanged",
                    group.path(), what));
  }
}

}  // namespace

ForceHistory::ForceHistory(const std::filesystem::path& file, std::vector<std::string> part_names,
                           std::vector<std::string> sources)
    : ForceHistory(open_for_writing(file), std::move(part_names), std::move(sources)) {}

ForceHistory::ForceHistory(std::FILE* file, std::vector<std::string> part_names, std::vector<std::string> sources,
                           bool header)
    : file_(file),
      part_names_(std::move(part_names)),
      sources_(std::move(sources)),
      accumulators_(part_names_.size(), std::vector<Accumulator>(sources_.size())),
      run_peak_(part_names_.size(), std::vector<double>(sources_.size(), 0.0)) {
  if (header) std::fputs("time,part,source,Fx,Fy,Fz,F,F_peak\n", file_);
}

ForceHistory::ForceHistory(std::FILE* file, std::vector<std::string> sensor_names, std::vector<SensorRow> sensors,
                           std::vector<std::string> sources, bool header)
    : ForceHistory(file, std::move(sensor_names), std::move(sources), false) {
  sensors_ = std::move(sensors);
  if (header) std::fputs("time,sensor,part,source,Fx,Fy,Fz,F,F_peak,area,pressure\n", file_);
}

void ForceHistory::save(io::hdf5::Group& group) const {
  group.set_attribute("parts", joined(part_names_));
  group.set_attribute("sources", joined(sources_));
  std::vector<double> impulse, last, duration, peak, run_peak;
  for (std::size_t part = 0; part < part_names_.size(); ++part) {
    for (std::size_t source = 0; source < sources_.size(); ++source) {
      const Accumulator& acc = accumulators_[part][source];
      impulse.insert(impulse.end(), {acc.impulse.x(), acc.impulse.y(), acc.impulse.z()});
      last.insert(last.end(), {acc.last.x(), acc.last.y(), acc.last.z()});
      duration.push_back(acc.duration);
      peak.push_back(acc.peak);
      run_peak.push_back(run_peak_[part][source]);
    }
  }
  io::write_array<double>(group, "impulse", impulse);
  io::write_array<double>(group, "last", last);
  io::write_array<double>(group, "duration", duration);
  io::write_array<double>(group, "peak", peak);
  io::write_array<double>(group, "run_peak", run_peak);
}

void ForceHistory::restore(const io::hdf5::Group& group) {
  check_names(group, "parts", part_names_, "structure parts");
  check_names(group, "sources", sources_, "force sources");
  const std::size_t n = part_names_.size() * sources_.size();
  const auto impulse = io::read_array<double>(group, "impulse", 3 * n);
  const auto last = io::read_array<double>(group, "last", 3 * n);
  const auto duration = io::read_array<double>(group, "duration", n);
  const auto peak = io::read_array<double>(group, "peak", n);
  const auto run_peak = io::read_array<double>(group, "run_peak", n);
  std::size_t k = 0;
  for (std::size_t part = 0; part < part_names_.size(); ++part) {
    for (std::size_t source = 0; source < sources_.size(); ++source, ++k) {
      Accumulator& acc = accumulators_[part][source];
      acc.impulse = Vec3(impulse[3 * k], impulse[3 * k + 1], impulse[3 * k + 2]);
      acc.last = Vec3(last[3 * k], last[3 * k + 1], last[3 * k + 2]);
      acc.duration = duration[k];
      acc.peak = peak[k];
      run_peak_[part][source] = run_peak[k];
    }
  }
}

ForceHistory::~ForceHistory() {
  close();
}

void ForceHistory::add(std::size_t part, std::size_t source, const Vec3& force, double dt) {
  auto& acc = accumulators_[part][source];
  acc.impulse += force * dt;
  acc.duration += dt;
  acc.last = force;
  const double magnitude = force.norm();
  acc.peak = std::max(acc.peak, magnitude);
  run_peak_[part][source] = std::max(run_peak_[part][source], magnitude);
}

void ForceHistory::write(double time) {
  if (file_ == nullptr) return;
  for (std::size_t part = 0; part < part_names_.size(); ++part) {
    for (std::size_t source = 0; source < sources_.size(); ++source) {
      auto& acc = accumulators_[part][source];
      const Vec3 mean = acc.duration > 0 ? Vec3(acc.impulse / acc.duration) : acc.last;
      if (sensors_.empty()) {
        fmt::print(file_, "{:.9g},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n", time, part_names_[part],
                   sources_[source], mean.x(), mean.y(), mean.z(), mean.norm(), acc.peak);
      } else {
        const SensorRow& sensor = sensors_[part];
        const double pressure = -mean.dot(sensor.normal) / sensor.area;
        fmt::print(file_, "{:.9g},{},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n", time, part_names_[part],
                   sensor.part, sources_[source], mean.x(), mean.y(), mean.z(), mean.norm(), acc.peak, sensor.area,
                   pressure);
      }
      acc = Accumulator{};
    }
  }
  std::fflush(file_);
}

void ForceHistory::close() {
  if (file_ != nullptr) std::fclose(file_);
  file_ = nullptr;
}

EnergyHistory::EnergyHistory(const std::filesystem::path& file) : EnergyHistory(open_for_writing(file)) {}

EnergyHistory::EnergyHistory(std::FILE* file, bool header) : file_(file) {
  if (header) std::fputs("time,kinetic,potential,solver_elastic,contact_elastic,total,dissipated,inflow\n", file_);
}

namespace {
std::vector<double> sample_values(const EnergySample& e) {
  return {e.time, e.kinetic, e.potential, e.solver_elastic, e.contact_elastic, e.dissipated, e.inflow};
}
EnergySample sample_from(const std::vector<double>& v) {
  return {.time = v[0],
          .kinetic = v[1],
          .potential = v[2],
          .solver_elastic = v[3],
          .contact_elastic = v[4],
          .dissipated = v[5],
          .inflow = v[6]};
}
}  // namespace

void EnergyHistory::save(io::hdf5::Group& group) const {
  group.set_attribute("observed", first_ ? 0 : 1);
  group.set_attribute("max_total", max_total_);
  io::write_array<double>(group, "initial", sample_values(initial_));
  io::write_array<double>(group, "last", sample_values(last_));
}

void EnergyHistory::restore(const io::hdf5::Group& group) {
  first_ = group.int_attribute("observed") == 0;
  max_total_ = group.double_attribute("max_total");
  initial_ = sample_from(io::read_array<double>(group, "initial", 7));
  last_ = sample_from(io::read_array<double>(group, "last", 7));
}

EnergyHistory::~EnergyHistory() {
  close();
}

void EnergyHistory::observe(const EnergySample& sample, bool write) {
  if (first_) {
    initial_ = sample;
    max_total_ = sample.own();
    first_ = false;
  }
  last_ = sample;
  max_total_ = std::max(max_total_, sample.own());
  if (write && file_ != nullptr) {
    fmt::print(file_, "{:.9g},{:.12g},{:.12g},{:.12g},{:.12g},{:.12g},{:.12g},{:.12g}\n", sample.time, sample.kinetic,
               sample.potential, sample.solver_elastic, sample.contact_elastic, sample.total(), sample.dissipated,
               sample.inflow);
    std::fflush(file_);
  }
}

void EnergyHistory::close() {
  if (file_ != nullptr) std::fclose(file_);
  file_ = nullptr;
}

void PartEnergyHistory::observe(const PartEnergySample& sample, const std::string& part, bool keep) {
  Series& series = parts_[part];
  series.last = sample;
  series.last_kept = keep;
  if (keep) series.kept.push_back(sample);
}

std::map<std::string, std::vector<PartEnergySample>> PartEnergyHistory::history() const {
  std::map<std::string, std::vector<PartEnergySample>> out;
  for (const auto& [part, series] : parts_) {
    auto& samples = out[part];
    samples = series.kept;
    if (!series.last_kept) samples.push_back(series.last);
  }
  return out;
}

}  // namespace sabo::coupler

namespace sabo::coupler {

namespace {
constexpr std::size_t kPartSampleValues = 8;
void append_sample(std::vector<double>& out, const PartEnergySample& e) {
  out.insert(out.end(), {e.time, e.kinetic, e.internal, e.plastic_work, e.hourglass, e.eroded, e.external_work,
                         static_cast<double>(e.eroded_elements)});
}
PartEnergySample part_sample_at(const std::vector<double>& v, std::size_t k) {
  const double* e = v.data() + kPartSampleValues * k;
  return {e[0], e[1], e[2], e[3], e[4], e[5], e[6], static_cast<std::uint64_t>(e[7])};
}
}  // namespace

void PartEnergyHistory::save(io::hdf5::Group& group) const {
  std::vector<std::string> names;
  for (const auto& [part, series] : parts_) {
    names.push_back(part);
    io::hdf5::Group part_group = group.create_group(fmt::format("part_{}", names.size() - 1));
    part_group.set_attribute("part", part);
    part_group.set_attribute("last_kept", series.last_kept ? 1 : 0);
    std::vector<double> kept, last;
    for (const auto& sample : series.kept) append_sample(kept, sample);
    append_sample(last, series.last);
    io::write_array<double>(part_group, "kept", kept);
    io::write_array<double>(part_group, "last", last);
  }
  group.set_attribute("parts", static_cast<std::int64_t>(names.size()));
}

void PartEnergyHistory::restore(const io::hdf5::Group& group) {
  parts_.clear();
  const auto count = static_cast<std::size_t>(group.int_attribute("parts"));
  for (std::size_t k = 0; k < count; ++k) {
    const io::hdf5::Group part_group = group.group(fmt::format("part_{}", k));
    Series& series = parts_[part_group.string_attribute("part")];
    series.last_kept = part_group.int_attribute("last_kept") != 0;
    const auto kept = io::read_array<double>(part_group, "kept");
    if (kept.size() % kPartSampleValues != 0) {
      throw FileError(fmt::format("{}/kept: {} values, not a multiple of {}. Fix: the checkpoint is damaged",
                                  part_group.path(), kept.size(), kPartSampleValues));
    }
    for (std::size_t i = 0; i < kept.size() / kPartSampleValues; ++i) series.kept.push_back(part_sample_at(kept, i));
    series.last = part_sample_at(io::read_array<double>(part_group, "last", kPartSampleValues), 0);
  }
}

}  // namespace sabo::coupler
