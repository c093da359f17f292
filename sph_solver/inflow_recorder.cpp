#include "sph_solver/inflow_recorder.hpp"

#include <fmt/format.h>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"

namespace sabo::sph {

InflowRecorder::InflowRecorder(const std::filesystem::path& run_dir, const scene::Scene& scene, const SphModel& model)
    : csv_(run_dir / "inflows.csv", "time,body,discharge,hydrograph_volume,released_volume,buffer_speed",
           "the inflows' history"),
      inflows_(model.inflows().size()),
      schedule_(scene.run.output_interval) {}

void InflowRecorder::sample(const SphModel& model, double time) {
  if (inflows_ == 0 || !schedule_.due(time)) return;
  std::string rows;
  for (const InflowState& inflow : model.inflows()) {
    rows += fmt::format("{:.9g},{},{:.9g},{:.9g},{:.9g},{:.9g}\n", time, inflow.name, inflow.section.discharge(time),
                        inflow.section.volume(0.0, time), inflow.released_volume(), inflow.speed);
  }
  csv_.append(rows);
}

void InflowRecorder::save(io::hdf5::Group& group) const {
  if (inflows_ == 0) return;
  io::hdf5::Group out = group.create_group("inflow_history");
  out.set_attribute("next_sample", static_cast<std::int64_t>(schedule_.next()));
  csv_.save(out, "started", "inflows_csv");
}

void InflowRecorder::load(const io::hdf5::Group& group) {
  if (inflows_ == 0) return;
  if (!group.exists("inflow_history")) {
    throw FileError(
        fmt::format("{}: no history of the inflows, while the scene has {}. Fix: restart from a checkpoint of "
                    "this scene, unchanged",
                    group.file_name(), inflows_));
  }
  const io::hdf5::Group in = group.group("inflow_history");
  schedule_.set_next(static_cast<std::uint64_t>(in.int_attribute("next_sample")));
  csv_.load(in, "started", "inflows_csv");
}

}  // namespace sabo::sph
