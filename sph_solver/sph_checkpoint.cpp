// SphModel's state in and out of a checkpoint (docs/restart.md): the per-particle state by id and what the last
// compute leaves for the next step (the stable step, the wall forces sent in the next state, each particle's
// support count, the walls' held work), so that a model built from the same scene continues with the same bits.
// The cell-sorted working copies are rebuilt by every compute and are not saved.
#include <fmt/format.h>

#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

void SphModel::save_state(io::hdf5::Group& group) const {
  assert(!forces_ready_ && "checkpoints are written after integrate()");
  group.set_attribute("particles", static_cast<std::int64_t>(size()));
  io::write_vectors(group, "position", position_);
  io::write_vectors(group, "velocity", velocity_);
  io::write_vectors(group, "acceleration", acceleration_);
  io::write_vectors(group, "external_force", external_force_);
  io::write_array(group, "density", density_);
  io::write_array(group, "pressure", pressure_);
  io::write_array(group, "stress", stress_);
  io::write_array(group, "stress_rate", stress_rate_);
  // On ranks (rank 0, after collect_state()): every particle's flag, not this rank's share.
  io::write_array(group, "active", std::vector<std::uint8_t>(active().begin(), active().end()));
  io::write_array(group, "settle_factor", settle_factor_);
  io::write_vectors(group, "wrap_offset", wrap_offset_);
  io::write_vectors(group, "boundary_force", boundary_force_);
  io::write_array(group, "boundary_stress", boundary_stress_);
  // Counts and single-precision credits as doubles: exact, and the files keep to the element types of libsabo/io.
  io::write_array(group, "support_neighbours",
                  std::vector<double>(support_neighbours_.begin(), support_neighbours_.end()));
  io::write_array(group, "wall_work_held", std::vector<double>(wall_work_held_.begin(), wall_work_held_.end()));
  group.set_attribute("lost", static_cast<std::int64_t>(lost_));
  group.set_attribute("time", time_);
  group.set_attribute("max_mu", max_mu_);
  group.set_attribute("max_acceleration", max_acceleration_);
  group.set_attribute("min_viscous_dt", min_viscous_dt_);
  group.set_attribute("stable_dt", stable_dt_);
  group.set_attribute("mean_neighbours", mean_neighbours_);
  io::write_array(group, "energies",
                  std::vector<double>{energies_.kinetic, energies_.potential, energies_.elastic, energies_.wall_held,
                                      energies_.inflow});
  io::write_array(group, "inflows", inflow_values());  // kInflowValues an inflow
  group.set_attribute("inflow_pending", inflow_pending_);
}

void SphModel::load_state(const io::hdf5::Group& group) {
  const auto particles = static_cast<std::size_t>(group.int_attribute("particles"));
  if (particles != size()) {
    throw FileError(
        fmt::format("{}: a checkpoint of {} SPH particles, this scene has {}. Fix: restart from a "
                    "checkpoint of this scene, unchanged",
                    group.file_name(), particles, size()));
  }
  io::read_vectors(group, "position", position_);
  io::read_vectors(group, "velocity", velocity_);
  io::read_vectors(group, "acceleration", acceleration_);
  external_force_ = io::read_vectors(group, "external_force");
  density_ = io::read_array<double>(group, "density", size());
  pressure_ = io::read_array<double>(group, "pressure", size());
  stress_ = io::read_array<double>(group, "stress", has_stress_ ? 6 * size() : 0);
  stress_rate_ = io::read_array<double>(group, "stress_rate");
  active_ = io::read_array<std::uint8_t>(group, "active", size());
  if (decomposed()) collected_active_ = active_;  // and share_loaded_state() cuts active_ to this rank's share
  settle_factor_ = io::read_array<double>(group, "settle_factor");
  wrap_offset_ = io::read_vectors(group, "wrap_offset");
  boundary_force_ = io::read_vectors(group, "boundary_force");
  boundary_stress_ = io::read_array<double>(group, "boundary_stress");
  const auto support = io::read_array<double>(group, "support_neighbours");
  support_neighbours_.assign(support.begin(), support.end());
  const auto held = io::read_array<double>(group, "wall_work_held");
  wall_work_held_.assign(held.begin(), held.end());
  lost_ = static_cast<std::size_t>(group.int_attribute("lost"));
  time_ = group.double_attribute("time");
  max_mu_ = group.double_attribute("max_mu");
  max_acceleration_ = group.double_attribute("max_acceleration");
  min_viscous_dt_ = group.double_attribute("min_viscous_dt");
  stable_dt_ = group.double_attribute("stable_dt");
  mean_neighbours_ = group.double_attribute("mean_neighbours");
  const auto energies = io::read_array<double>(group, "energies", 5);
  energies_ = {energies[0], energies[1], energies[2], energies[3], energies[4]};
  set_inflow_values(io::read_array<double>(group, "inflows", kInflowValues * inflows_.size()));
  inflow_pending_ = group.double_attribute("inflow_pending");
  forces_ready_ = false;
}

}  // namespace sabo::sph
