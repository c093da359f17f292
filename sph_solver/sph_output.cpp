#include "sph_solver/sph_output.hpp"

#include <fmt/format.h>

namespace sabo::sph {

SphOutput::SphOutput(const std::filesystem::path& run_dir, const SphModel& model)
    : model_(model), folder_(run_dir / "sph"), series_(run_dir / "sph.pvd") {
  std::filesystem::create_directories(folder_);
  id_.resize(model.size());
  for (std::size_t i = 0; i < id_.size(); ++i) id_[i] = i;
}

void SphOutput::write(std::uint64_t step, double time) {
  using io::vtk::Array;
  std::vector<Array> arrays = {
      Array::of<std::uint64_t>("id", id_),
      Array::of<std::uint32_t>("body", model_.body_index()),
      Array::vectors("velocity", model_.velocities()),
      Array::scalars("density", model_.densities()),
      Array::scalars("pressure", model_.pressures()),
      Array::of<std::uint8_t>("active", model_.active()),
  };
  if (model_.has_stress()) arrays.push_back(Array::of<double>("deviatoric_stress", model_.deviatoric_stress(), 6));
  if (!model_.wall_work_held().empty()) arrays.push_back(Array::of<float>("wall_work_held", model_.wall_work_held()));
  const auto file = folder_ / fmt::format("sph_{:07d}.vtp", step);
  io::vtk::write_points(file, model_.positions(), arrays);
  series_.add(time, file);
}

}  // namespace sabo::sph
