#pragma once
// The inflows' history (docs/scene.md [[inflows]]) in RUN/inflows.csv, one row per inflow and output time:
//   time, body, discharge, hydrograph_volume, released_volume, buffer_speed (body: the inflow's name)
// discharge: the hydrograph's Q at t_n (m^3/s); hydrograph_volume: its integral from 0 to t_n (m^3);
// released_volume: the layers released through the section so far (m^3, InflowState::released_volume);
// buffer_speed: the buffer's speed over the last step (m/s). No file for a scene without inflows.
#include <filesystem>
#include <string>
#include <vector>

#include "libsabo/io/hdf5.hpp"
#include "libsabo/scene/scene.hpp"
#include "sph_solver/gauges.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

class InflowRecorder {
 public:
  InflowRecorder(const std::filesystem::path& run_dir, const scene::Scene& scene, const SphModel& model);

  // At t_n (s): a row per inflow when the output time has come.
  void sample(const SphModel& model, double time);

  // The next sample and the file's length, for checkpoints; load() cuts the file back to it.
  void save(io::hdf5::Group& group) const;
  void load(const io::hdf5::Group& group);

 private:
  CsvHistory csv_;
  std::size_t inflows_;  // SphModel::inflows().size()
  SampleSchedule schedule_;
};

}  // namespace sabo::sph
