#pragma once
// The scene's [[fronts]] (docs/scene.md): the flow's leading edge along a path, read from the fluid into
//   RUN/fronts.csv          time, front, position, speed, flow_speed, x, y, z
//   RUN/front_stations.csv  time, front, station, at, depth
// one row per front (per station) and sample, and into summary.json (results.sph_solver.fronts) through
// results().
#include <cstdint>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <vector>

#include "libsabo/io/hdf5.hpp"
#include "libsabo/scene/scene.hpp"
#include "sph_solver/gauges.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

// Where the flow's front stands along `front`'s path at t_n, from the active particles of `model`.
struct FrontReading {
  double position = std::numeric_limits<double>::quiet_NaN();  // m, distance along the path; NaN: too few particles
  double flow_speed = 0;      // m/s, mean velocity along the path within 2 h behind the front
  Vec3 point = Vec3::Zero();  // m, the particle at the front
};
[[nodiscard]] FrontReading read_front(const SphModel& model, const scene::Front& front);

class FrontRecorder {
 public:
  // No file is written for a scene without fronts.
  FrontRecorder(const std::filesystem::path& run_dir, const scene::Scene& scene);

  // At t_n (s), with the model between compute_internal_forces() and integrate(), as GaugeRecorder::sample().
  void sample(const SphModel& model, double time);

  [[nodiscard]] bool empty() const { return fronts_.empty(); }
  // summary.json's results.sph_solver.fronts: per front its history, fastest speed and stations.
  [[nodiscard]] nlohmann::json results() const;

  // Everything sample() accumulated and the files' lengths, for checkpoints; load() cuts the files back.
  void save(io::hdf5::Group& group) const;
  void load(const io::hdf5::Group& group);

 private:
  struct Track {
    SampleSchedule schedule;
    std::vector<double> time, position, speed, flow_speed;  // per sample
    std::vector<double> arrival;                            // s per station, NaN until the front passes
    std::vector<double> max_depth, last_depth;              // m per station
  };
  CsvHistory fronts_csv_, stations_csv_;
  std::vector<scene::Front> fronts_;
  std::vector<Track> tracks_;
  double depth_spacing_ = 0;  // m, the sub-sampling of the depth (dx / 4)
};

}  // namespace sabo::sph
