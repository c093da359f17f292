#include "dem_solver/dem_output.hpp"

#include <fmt/format.h>

namespace sabo::dem {

DemOutput::DemOutput(const std::filesystem::path& run_dir, const DemModel& model)
    : model_(model), folder_(run_dir / "dem"), series_(run_dir / "dem.pvd") {
  std::filesystem::create_directories(folder_);
  id_.resize(model.size());
  for (std::size_t i = 0; i < id_.size(); ++i) id_[i] = i;
}

void DemOutput::write(std::uint64_t step, double time) {
  using io::vtk::Array;
  const std::array<Array, 7> arrays = {
      Array::of<std::uint64_t>("id", id_),
      Array::scalars("radius", model_.radii()),
      Array::of<std::uint32_t>("set", model_.body_index()),
      Array::vectors("velocity", model_.velocities()),
      Array::vectors("angular_velocity", model_.angular_velocities()),
      Array::vectors("force", model_.forces()),
      Array::vectors("torque", model_.torques()),
  };
  const auto file = folder_ / fmt::format("dem_{:07d}.vtp", step);
  io::vtk::write_points(file, model_.positions(), arrays);
  series_.add(time, file);
}

}  // namespace sabo::dem
