#pragma once
// ParaView output of the sph_solver: one .vtp per frame in RUN/sph/ and the
// series RUN/sph.pvd (position, velocity, density, pressure; deviatoric
// stress for elastic-plastic fluids).
#include <cstdint>
#include <filesystem>
#include <vector>

#include "libsabo/io/checkpoint.hpp"
#include "libsabo/io/vtk.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

class SphOutput {
 public:
  SphOutput(const std::filesystem::path& run_dir, const SphModel& model);
  void write(std::uint64_t step, double time);
  void save(io::hdf5::Group& group) const { io::write_series(group, "sph_pvd", series_); }
  void load(const io::hdf5::Group& group) { io::read_series(group, "sph_pvd", series_); }

 private:
  const SphModel& model_;
  std::filesystem::path folder_;
  io::vtk::TimeSeries series_;
  std::vector<std::uint64_t> id_;
};

}  // namespace sabo::sph
