#pragma once
// ParaView output of dem_solver: dem/dem_<step>.vtp per output time and the
// dem.pvd series in the run folder.
#include <filesystem>

#include "dem_solver/dem_model.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "libsabo/io/vtk.hpp"

namespace sabo::dem {

class DemOutput {
 public:
  DemOutput(const std::filesystem::path& run_dir, const DemModel& model);
  // Spheres at x_n with their half-step velocities and the forces of step n.
  void write(std::uint64_t step, double time);
  void close() {}  // the series is complete on disk after every write
  void save(io::hdf5::Group& group) const { io::write_series(group, "dem_pvd", series_); }
  void load(const io::hdf5::Group& group) { io::read_series(group, "dem_pvd", series_); }

 private:
  const DemModel& model_;
  std::filesystem::path folder_;
  io::vtk::TimeSeries series_;
  std::vector<std::uint64_t> id_;
};

}  // namespace sabo::dem
