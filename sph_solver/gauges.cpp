#include "sph_solver/gauges.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"

namespace sabo::sph {
namespace {

constexpr const char* kGaugesFile = "gauges.csv";
// A sample time k * interval counts as reached this fraction of an interval early (the steps' sum rounds).
constexpr double kTimeTolerance = 1e-9;
// At most this many sub-samples along a line for its depth.
constexpr double kMaxDepthSamples = 1e5;

}  // namespace

bool SampleSchedule::due(double time) {
  if (time < (static_cast<double>(next_) - kTimeTolerance) * interval_) return false;
  next_ = static_cast<std::uint64_t>(std::floor(time / interval_ + kTimeTolerance)) + 1;
  return true;
}

void CsvHistory::append(const std::string& rows) {
  std::ofstream out(file_, started_ ? std::ios::app : std::ios::trunc);
  if (!started_) {
    out << header_ << "\n";
    started_ = true;
  }
  out << rows;
  out.flush();
  if (!out) throw FileError(fmt::format("{}: cannot write {}", file_.string(), what_));
}

void CsvHistory::save(io::hdf5::Group& group, const std::string& started, const std::string& length) const {
  group.set_attribute(started, started_ ? 1 : 0);
  if (started_) io::write_file_size(group, length, file_);
}

void CsvHistory::load(const io::hdf5::Group& group, const std::string& started, const std::string& length) {
  started_ = group.int_attribute(started) != 0 && io::truncate_to_saved_size(group, length, file_);
}

double surface_distance(const SphModel& model, const Vec3& start, const Vec3& end, double spacing) {
  const double length = (end - start).norm();
  const auto intervals = static_cast<std::size_t>(std::clamp(std::ceil(length / spacing), 1.0, kMaxDepthSamples));
  double previous = model.kernel_sum(start);
  double distance = 0;
  for (std::size_t k = 1; k <= intervals; ++k) {
    const double s = length * static_cast<double>(k) / static_cast<double>(intervals);
    const double sum = model.kernel_sum(start + (end - start) * (s / length));
    if (previous >= kSurfaceKernelSum && sum < kSurfaceKernelSum) {
      const double s_previous = length * static_cast<double>(k - 1) / static_cast<double>(intervals);
      distance = s_previous + (s - s_previous) * (previous - kSurfaceKernelSum) / (previous - sum);
    }
    previous = sum;
  }
  return previous >= kSurfaceKernelSum ? length : distance;
}

GaugeRecorder::GaugeRecorder(const std::filesystem::path& run_dir, const scene::Scene& scene)
    : csv_(run_dir / kGaugesFile, "time,gauge,point,x,y,z,kernel_sum,pressure,velocity_x,velocity_y,velocity_z,depth",
           "the gauges' readings"),
      gauges_(scene.gauges),
      depth_spacing_(0.25 * scene.sph.particle_spacing) {
  for (const scene::Gauge& gauge : gauges_)
    schedule_.emplace_back(gauge.interval > 0 ? gauge.interval : scene.run.output_interval);
}

void GaugeRecorder::sample(const SphModel& model, double time) {
  std::string rows;
  for (std::size_t g = 0; g < gauges_.size(); ++g) {
    if (!schedule_[g].due(time)) continue;
    const scene::Gauge& gauge = gauges_[g];
    const std::string depth =
        gauge.line() ? fmt::format("{:.9g}", surface_distance(model, gauge.start, gauge.end, depth_spacing_)) : "";
    for (std::size_t k = 0; k < gauge.points; ++k) {
      const Vec3 x = gauge.point(k);
      const FluidSample s = model.sample(x);
      rows += fmt::format("{:.9g},{},{},{:.9g},{:.9g},{:.9g},{:.6g},{:.9g},{:.9g},{:.9g},{:.9g},{}\n", time, gauge.name,
                          k, x.x(), x.y(), x.z(), s.kernel_sum, s.pressure, s.velocity.x(), s.velocity.y(),
                          s.velocity.z(), depth);
    }
  }
  if (!rows.empty()) csv_.append(rows);
}

void GaugeRecorder::save(io::hdf5::Group& group) const {
  if (gauges_.empty()) return;
  io::hdf5::Group out = group.create_group("gauges");
  std::vector<std::uint64_t> next;
  for (const SampleSchedule& schedule : schedule_) next.push_back(schedule.next());
  io::write_array<std::uint64_t>(out, "next_sample", next);
  csv_.save(out, "started", "gauges_csv");
}

void GaugeRecorder::load(const io::hdf5::Group& group) {
  if (gauges_.empty()) return;
  if (!group.exists("gauges")) {
    throw FileError(
        fmt::format("{}: no state of the gauges, while the scene has {}. Fix: restart from a checkpoint of "
                    "this scene, unchanged",
                    group.file_name(), gauges_.size()));
  }
  const io::hdf5::Group in = group.group("gauges");
  const auto next = io::read_array<std::uint64_t>(in, "next_sample");
  if (next.size() != gauges_.size()) {
    throw FileError(
        fmt::format("{}: the checkpoint holds {} gauges, the scene {}. Fix: restart from a checkpoint of "
                    "this scene, unchanged",
                    group.file_name(), next.size(), gauges_.size()));
  }
  for (std::size_t g = 0; g < next.size(); ++g) schedule_[g].set_next(next[g]);
  csv_.load(in, "started", "gauges_csv");
}

}  // namespace sabo::sph
