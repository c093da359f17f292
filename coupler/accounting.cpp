#include "coupler/accounting.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "libsabo/core/error.hpp"

namespace sabo::coupler {

std::FILE* open_for_writing(const std::filesystem::path& file) {
  std::FILE* handle = std::fopen(file.c_str(), "w");
  if (handle == nullptr) throw FileError(fmt::format("cannot create '{}': {}", file.string(), std::strerror(errno)));
  return handle;
}

ForceHistory::ForceHistory(const std::filesystem::path& file, std::vector<std::string> part_names,
                           std::vector<std::string> sources)
    : ForceHistory(open_for_writing(file), std::move(part_names), std::move(sources)) {}

ForceHistory::ForceHistory(std::FILE* file, std::vector<std::string> part_names, std::vector<std::string> sources)
    : file_(file),
      part_names_(std::move(part_names)),
      sources_(std::move(sources)),
      accumulators_(part_names_.size(), std::vector<Accumulator>(sources_.size())),
      run_peak_(part_names_.size(), std::vector<double>(sources_.size(), 0.0)) {
  std::fputs("time,part,source,Fx,Fy,Fz,F,F_peak\n", file_);
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
      fmt::print(file_, "{:.9g},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n", time, part_names_[part], sources_[source],
                 mean.x(), mean.y(), mean.z(), mean.norm(), acc.peak);
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

EnergyHistory::EnergyHistory(std::FILE* file) : file_(file) {
  std::fputs("time,kinetic,potential,solver_elastic,contact_elastic,total,dissipated\n", file_);
}

EnergyHistory::~EnergyHistory() {
  close();
}

void EnergyHistory::observe(const EnergySample& sample, bool write) {
  if (first_) {
    initial_ = sample;
    max_total_ = sample.total();
    first_ = false;
  }
  last_ = sample;
  max_total_ = std::max(max_total_, sample.total());
  if (write && file_ != nullptr) {
    fmt::print(file_, "{:.9g},{:.12g},{:.12g},{:.12g},{:.12g},{:.12g},{:.12g}\n", sample.time, sample.kinetic,
               sample.potential, sample.solver_elastic, sample.contact_elastic, sample.total(), sample.dissipated);
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
