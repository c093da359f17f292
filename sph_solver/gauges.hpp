#pragma once
// The scene's [[gauges]] (docs/scene.md), read from the fluid into RUN/gauges.csv:
//   time, gauge, point, x, y, z, kernel_sum, pressure, velocity_x, velocity_y, velocity_z, depth
// one row per gauge point and sample; depth (line gauges) is the distance from the line's start to the
// free surface along it, empty for point gauges.
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "libsabo/io/hdf5.hpp"
#include "libsabo/scene/scene.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

// The free surface along the line from `start` to `end` (m): the distance from `start` to the last
// point where the kernel sum falls through kSurfaceKernelSum, on a sub-sampling of at most `spacing`
// (m); 0 when the line is dry, its length when it ends in the fluid.
[[nodiscard]] double surface_distance(const SphModel& model, const Vec3& start, const Vec3& end, double spacing);

// When an instrument samples: at the first step whose t_n reaches k * interval, k = 0, 1, ...
class SampleSchedule {
 public:
  explicit SampleSchedule(double interval) : interval_(interval) {}
  // Whether `time` (s) reached the next sample time; when it did, the one after it becomes the next.
  [[nodiscard]] bool due(double time);
  // The index k of the next sample time, for checkpoints.
  [[nodiscard]] std::uint64_t next() const { return next_; }
  void set_next(std::uint64_t next) { next_ = next; }

 private:
  double interval_;  // s
  std::uint64_t next_ = 0;
};

// A CSV file an instrument appends to (gauges.csv, fronts.csv, front_stations.csv, inflows.csv): the header
// before the first rows; its length goes into a checkpoint, and a run resumed from one cuts the file back to
// it (a restart into another folder, a replay, starts the file afresh).
class CsvHistory {
 public:
  CsvHistory(std::filesystem::path file, std::string header, std::string what)
      : file_(std::move(file)), header_(std::move(header)), what_(std::move(what)) {}
  // Appends `rows` (each ending in a newline); throws FileError naming the file and `what` when it cannot.
  void append(const std::string& rows);
  // In `group`: the attribute `started` (1 once the header is written) and the file's length as `length`.
  void save(io::hdf5::Group& group, const std::string& started, const std::string& length) const;
  void load(const io::hdf5::Group& group, const std::string& started, const std::string& length);

 private:
  std::filesystem::path file_;
  std::string header_, what_;
  bool started_ = false;  // the header is written
};

class GaugeRecorder {
 public:
  // No file is written for a scene without gauges.
  GaugeRecorder(const std::filesystem::path& run_dir, const scene::Scene& scene);

  // At t_n (s), with the model between compute_internal_forces() and integrate(): samples every gauge
  // whose sample time has come and appends its rows.
  void sample(const SphModel& model, double time);

  // Each gauge's next sample and the file's length, for checkpoints; load() cuts the file back to it.
  void save(io::hdf5::Group& group) const;
  void load(const io::hdf5::Group& group);

 private:
  CsvHistory csv_;
  std::vector<scene::Gauge> gauges_;
  std::vector<SampleSchedule> schedule_;  // per gauge
  double depth_spacing_ = 0;              // m, the sub-sampling of the depth (dx / 4)
};

}  // namespace sabo::sph
