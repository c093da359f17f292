// DemModel's state in and out of a checkpoint (docs/restart.md): what integrate() leaves for the next step,
// so that a model built from the same scene and loaded continues with the same bits.
#include <fmt/format.h>

#include "dem_solver/dem_model.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/io/checkpoint.hpp"

namespace sabo::dem {

void DemModel::save_state(io::hdf5::Group& group) const {
  assert(!forces_ready_ && "checkpoints are written after integrate()");
  group.set_attribute("spheres", static_cast<std::int64_t>(size()));
  group.set_attribute("walls", static_cast<std::int64_t>(walls_.size()));
  io::write_vectors(group, "position", position_);
  io::write_vectors(group, "velocity", velocity_);
  io::write_vectors(group, "spin", spin_);
  io::write_array(group, "fixed", fixed_);
  io::write_array(group, "energies",
                  std::vector<double>{energies_.kinetic, energies_.potential, energies_.elastic, energies_.dissipated});
  // The Verlet list is rebuilt on load from the positions of its last build: the same pairs in the same slots.
  io::write_vectors(group, "build_position", build_position_);
  group.set_attribute("rebuild", rebuild_ || start_.empty() ? 1 : 0);
  group.set_attribute("largest_displacement_squared", largest_displacement_squared_);
  group.set_attribute("displacement_known", displacement_known_ ? 1 : 0);
  group.set_attribute("neighbour_builds", static_cast<std::int64_t>(neighbour_builds_));
  const auto contacts = contact_histories();
  std::vector<std::uint32_t> pairs;
  std::vector<Vec3> tangential, rolling;
  std::vector<double> energy;
  for (const auto& contact : contacts) {
    pairs.insert(pairs.end(), {contact.a, contact.b});
    tangential.push_back(contact.tangential_displacement);
    rolling.push_back(contact.rolling_torque);
    energy.push_back(contact.spring_energy);
  }
  io::write_array(group, "contact_pairs", pairs);
  io::write_vectors(group, "contact_tangential", tangential);
  io::write_vectors(group, "contact_rolling", rolling);
  io::write_array(group, "contact_spring_energy", energy);
  io::write_vectors(group, "wall_tangential", wall_tangential_);
  io::write_vectors(group, "wall_rolling", wall_rolling_);
  io::write_array(group, "wall_in_contact", wall_in_contact_);
  io::write_array(group, "wall_spring_energy", wall_spring_energy_);
}

void DemModel::load_state(const io::hdf5::Group& group) {
  const std::string where = group.file_name();
  const auto spheres = static_cast<std::size_t>(group.int_attribute("spheres"));
  const auto walls = static_cast<std::size_t>(group.int_attribute("walls"));
  if (spheres != size() || walls != walls_.size()) {
    throw FileError(
        fmt::format("{}: a checkpoint of {} spheres and {} walls, this scene has {} and {}. Fix: restart "
                    "from a checkpoint of this scene, unchanged",
                    where, spheres, walls, size(), walls_.size()));
  }
  io::read_vectors(group, "position", position_);
  io::read_vectors(group, "velocity", velocity_);
  io::read_vectors(group, "spin", spin_);
  fixed_ = io::read_array<std::uint8_t>(group, "fixed", size());
  for (std::uint32_t i = 0; i < size(); ++i) update_inverse_mass(i);
  stable_dt_.reset();
  const auto energies = io::read_array<double>(group, "energies", 4);

  const auto pairs = io::read_array<std::uint32_t>(group, "contact_pairs");
  const std::size_t contacts = pairs.size() / 2;
  std::vector<Vec3> tangential(contacts), rolling(contacts);
  io::read_vectors(group, "contact_tangential", tangential);
  io::read_vectors(group, "contact_rolling", rolling);
  const auto energy = io::read_array<double>(group, "contact_spring_energy", contacts);
  std::vector<ContactRecord> records(contacts);
  for (std::size_t c = 0; c < contacts; ++c)
    records[c] = {pairs[2 * c], pairs[2 * c + 1], tangential[c], rolling[c], energy[c]};
  restore(records, energies[3]);

  const auto built = io::read_array<double>(group, "build_position");
  if (!built.empty()) {
    // The list of the original run's last build, with the histories in its slots.
    std::vector<Vec3> now = position_;
    if (built.size() != 3 * size()) {
      throw FileError(
          fmt::format("{}: build_position holds {} values for {} spheres. Fix: restart from a checkpoint "
                      "Sabo wrote for this scene",
                      where, built.size(), size()));
    }
    for (std::size_t i = 0; i < size(); ++i) position_[i] = Vec3(built[3 * i], built[3 * i + 1], built[3 * i + 2]);
    build_neighbours();
    position_ = std::move(now);
    if (dropped_released_ != 0) {
      throw FileError(
          fmt::format("{}: a contact of the checkpoint is not in the neighbour list its build positions "
                      "give. Fix: restart from a checkpoint Sabo wrote for this scene",
                      where));
    }
  }
  rebuild_ = group.int_attribute("rebuild") != 0;
  largest_displacement_squared_ = group.double_attribute("largest_displacement_squared");
  displacement_known_ = group.int_attribute("displacement_known") != 0;
  neighbour_builds_ = static_cast<std::size_t>(group.int_attribute("neighbour_builds"));

  const std::size_t wall_slots = size() * walls_.size();
  wall_tangential_.resize(wall_slots);
  wall_rolling_.resize(wall_slots);
  io::read_vectors(group, "wall_tangential", wall_tangential_);
  io::read_vectors(group, "wall_rolling", wall_rolling_);
  wall_in_contact_ = io::read_array<std::uint8_t>(group, "wall_in_contact", wall_slots);
  wall_spring_energy_ = io::read_array<double>(group, "wall_spring_energy", wall_slots);
  energies_ = {energies[0], energies[1], energies[2], energies[3]};
  forces_ready_ = false;
}

}  // namespace sabo::dem
