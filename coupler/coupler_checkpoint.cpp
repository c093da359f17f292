// The coupler's checkpoints and the resume of a run from them (docs/restart.md, "Resuming a run").
//
// A checkpoint of step k is written after the forces of step k - 1 went out with StepForces.checkpoint, when
// every solver writes its own of the same step. It holds what the loop carries into step k: the clock and
// the output and checkpoint times, the pairs' histories, the boundary particles' lists of the last steps,
// the open intervals of forces.csv and the energy accounts, the run statistics, the lengths of forces.csv and
// energy.csv, and the FEM surface's newest topology. traffic.h5 is flushed before, so that it holds every
// step before k.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "coupler/coupler.hpp"
#include "coupler/coupler_peer.hpp"
#include "libsabo/core/error.hpp"

namespace sabo::coupler {

namespace {

constexpr const char* kForcesFile = "forces.csv";
constexpr const char* kEnergyFile = "energy.csv";
constexpr const char* kSensorsFile = "sensors.csv";

std::string pair_group_name(std::size_t index, const std::string& name) {
  return fmt::format("{:02}_{}", index, name);
}

}  // namespace

void Coupler::write_checkpoint(std::uint64_t step) {
  const auto start = std::chrono::steady_clock::now();
  if (recorder_) recorder_->flush();
  // A checkpoint is a safety net, not part of the answer: one that cannot be written (no descriptor left, a
  // full disk) is reported and the run goes on; a resume then starts from an older one.
  try {
    write_checkpoint_file(step);
  } catch (const std::exception& error) {
    ++checkpoint_failures_;
    spdlog::warn(
        "could not write the coupler's checkpoint of step {} (the run goes on; a resume would start from "
        "an earlier checkpoint): {}",
        step, error.what());
  }
  checkpoint_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void Coupler::write_checkpoint_file(std::uint64_t step) {
  const auto path = checkpoint_store_->write(step, expected_time_, [&](io::hdf5::File& file) {
    file.set_attribute("dt_previous", dt_previous_);
    io::hdf5::Group group = file.create_group("coupler");
    group.set_attribute("next_output_time", next_output_time_);
    group.set_attribute("next_checkpoint_time", next_checkpoint_time_);
    group.set_attribute("checkpoints_written", static_cast<std::int64_t>(checkpoints_));
    group.set_attribute("previous_time", previous_time_);
    group.set_attribute("previous_output", previous_output_ ? 1 : 0);
    group.set_attribute("previous_block_start", previous_block_start_ ? 1 : 0);
    group.set_attribute("previous_contact_elastic", previous_contact_elastic_);
    group.set_attribute("contact_dissipated", contact_dissipated_);
    group.set_attribute("surface_nodes", static_cast<std::int64_t>(surface_nodes_));
    group.set_attribute("surface_revision", static_cast<std::int64_t>(surface_revision_));
    io::write_array<std::uint8_t>(
        group, "surface_topology",
        std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(surface_topology_.data()),
                                      surface_topology_.size()));
    io::write_file_size(group, kForcesFile, options_.out_dir / kForcesFile);
    io::write_file_size(group, kEnergyFile, options_.out_dir / kEnergyFile);
    if (sensors_) io::write_file_size(group, kSensorsFile, options_.out_dir / kSensorsFile);

    // Statistics for summary.json: a resumed run reports the whole run.
    io::hdf5::Group stats = group.create_group("statistics");
    stats.set_attribute("dt_min", dt_min_);
    stats.set_attribute("dt_max", dt_max_);
    stats.set_attribute("lock_step_equivalent", lock_step_equivalent_);
    stats.set_attribute("newton_max_residual", newton_max_residual_);
    stats.set_attribute("newton_violations", static_cast<std::int64_t>(newton_violations_));
    stats.set_attribute("max_contacts", static_cast<std::int64_t>(max_contacts_));
    stats.set_attribute("contact_seconds", contact_seconds_);
    stats.set_attribute("receive_seconds", receive_seconds_);
    stats.set_attribute("send_seconds", send_seconds_);
    stats.set_attribute("wait_seconds", wait_seconds_);
    stats.set_attribute("critical_compute_seconds", critical_compute_seconds_);
    stats.set_attribute("critical_contact_seconds", critical_contact_seconds_);
    stats.set_attribute("walls_before_the_fluid_state", static_cast<std::int64_t>(walls_before_the_fluid_));
    stats.set_attribute("checkpoint_seconds", checkpoint_seconds_);
    stats.set_attribute(
        "wall_seconds",
        wall_before_ + std::chrono::duration<double>(std::chrono::steady_clock::now() - start_wall_).count());
    stats.set_attribute("bytes_received", static_cast<std::int64_t>(bytes_received_before_ + socket_.bytes_received()));
    stats.set_attribute("bytes_sent", static_cast<std::int64_t>(bytes_sent_before_ + socket_.bytes_sent()));
    stats.set_attribute("restarts", restarts_.dump());
    stats.set_attribute("resumes", resumes_.dump());
    for (const auto& peer : peers_) {
      stats.set_attribute(std::string(peer->name()) + "_compute_seconds", peer->compute_seconds);
      stats.set_attribute(std::string(peer->name()) + "_solver_steps", static_cast<std::int64_t>(peer->solver_steps));
      stats.set_attribute(std::string(peer->name()) + "_hold_exchanges", static_cast<std::int64_t>(peer->holds));
    }

    if (forces_csv_) {
      io::hdf5::Group forces = group.create_group("forces");
      forces_csv_->save(forces);
    }
    if (energy_csv_) {
      io::hdf5::Group energy = group.create_group("energy");
      energy_csv_->save(energy);
    }
    if (sensors_) {
      io::hdf5::Group sensors = group.create_group("sensors");
      sensors_->save(sensors);
    }
    io::hdf5::Group parts = group.create_group("part_energies");
    part_energies_.save(parts);
    io::hdf5::Group channel = group.create_group("boundary_channel");
    replies_.boundary().save(channel);
    io::hdf5::Group pairs = group.create_group("pairs");
    pairs.set_attribute("count", static_cast<std::int64_t>(pairs_.size()));
    for (std::size_t i = 0; i < pairs_.size(); ++i) {
      const PairSlot& slot = pairs_[i];
      io::hdf5::Group pair = pairs.create_group(pair_group_name(i, slot.pair->name()));
      slot.pair->save_history(pair);
      pair.set_attribute("coupler_seconds", slot.seconds);
      pair.set_attribute("coupler_max_residual", slot.max_residual);
      pair.set_attribute("coupler_dt_previous", slot.dt_previous);
    }
  });
  spdlog::debug("wrote {}", path.string());
}

void Coupler::open_resume() {
  resume_file_ = checkpoint_store_->open_file(options_.resume);
  resume_step_ = io::checkpoint_step(resume_file_);
  if (!resume_file_.exists("coupler")) {
    throw FileError(
        fmt::format("{}: holds no coupler state. Fix: resume from a file the coupler wrote "
                    "(RUN_DIR/checkpoints/coupler_<step>.h5)",
                    options_.resume.string()));
  }
  expected_time_ = io::checkpoint_time(resume_file_);
  dt_previous_ = resume_file_.double_attribute("dt_previous");
  spdlog::info("resuming the run at step {}, t = {:.9g} s, from {}", *resume_step_, expected_time_,
               options_.resume.string());
}

void Coupler::cut_histories() {
  const io::hdf5::Group group = resume_file_.group("coupler");
  std::vector<const char*> histories{kForcesFile, kEnergyFile};
  if (!scene_.sensors.empty()) histories.push_back(kSensorsFile);
  for (const char* name : histories) {
    const auto file = options_.out_dir / name;
    if (!io::truncate_to_saved_size(group, name, file)) {
      throw FileError(
          fmt::format("{}: missing, while the checkpoint {} continues it. Fix: resume in the run folder "
                      "the checkpoint belongs to",
                      file.string(), options_.resume.string()));
    }
  }
}

void Coupler::restore_surface() {
  const io::hdf5::Group group = resume_file_.group("coupler");
  const auto topology = io::read_array<std::uint8_t>(group, "surface_topology");
  surface_nodes_ = static_cast<std::size_t>(group.int_attribute("surface_nodes"));
  surface_revision_ = static_cast<std::uint64_t>(group.int_attribute("surface_revision"));
  surface_topology_.assign(topology.begin(), topology.end());
  surface_ids_stale_ = true;
  if (surface_topology_.empty()) return;  // the registered surface is the current one
  auto fem =
      std::find_if(peers_.begin(), peers_.end(), [](const auto& p) { return p->registration.exposes_surface(); });
  if (fem == peers_.end()) {
    throw FileError(
        fmt::format("{}: holds a surface topology, but no solver of this run exposes a surface. Fix: "
                    "resume with the scene the run was started with, unchanged",
                    options_.resume.string()));
  }
  // The pairs start from the surface as it was last set (its node positions then define eq. 6's stiffness).
  if (!(*fem)->registration.mutable_surface()->ParseFromString(surface_topology_)) {
    throw FileError(
        fmt::format("{}: coupler/surface_topology does not parse. Fix: the checkpoint is damaged; "
                    "resume from the other one kept",
                    options_.resume.string()));
  }
}

void Coupler::restore_state() {
  const io::hdf5::Group group = resume_file_.group("coupler");
  const auto fail_file = [&](const std::string& what) {
    throw FileError(fmt::format("{}: {}. Fix: resume with the scene the run was started with, unchanged",
                                options_.resume.string(), what));
  };
  next_output_time_ = group.double_attribute("next_output_time");
  next_checkpoint_time_ = group.double_attribute("next_checkpoint_time");
  checkpoints_ = static_cast<std::uint64_t>(group.int_attribute("checkpoints_written"));
  previous_time_ = group.double_attribute("previous_time");
  previous_output_ = group.int_attribute("previous_output") != 0;
  // Checkpoints written before hold exchanges: every exchange started a block.
  previous_block_start_ =
      !group.has_attribute("previous_block_start") || group.int_attribute("previous_block_start") != 0;
  previous_contact_elastic_ = group.double_attribute("previous_contact_elastic");
  contact_dissipated_ = group.double_attribute("contact_dissipated");

  const io::hdf5::Group stats = group.group("statistics");
  dt_min_ = stats.double_attribute("dt_min");
  dt_max_ = stats.double_attribute("dt_max");
  lock_step_equivalent_ =
      stats.has_attribute("lock_step_equivalent") ? stats.double_attribute("lock_step_equivalent") : 0;
  newton_max_residual_ = stats.double_attribute("newton_max_residual");
  newton_violations_ = static_cast<std::uint64_t>(stats.int_attribute("newton_violations"));
  max_contacts_ = static_cast<std::size_t>(stats.int_attribute("max_contacts"));
  contact_seconds_ = stats.double_attribute("contact_seconds");
  receive_seconds_ = stats.double_attribute("receive_seconds");
  send_seconds_ = stats.double_attribute("send_seconds");
  wait_seconds_ = stats.double_attribute("wait_seconds");
  critical_compute_seconds_ = stats.double_attribute("critical_compute_seconds");
  // Checkpoints from before the pairs' share of the critical path was measured: all of their time, as then.
  critical_contact_seconds_ = stats.has_attribute("critical_contact_seconds")
                                  ? stats.double_attribute("critical_contact_seconds")
                                  : contact_seconds_;
  walls_before_the_fluid_ = stats.has_attribute("walls_before_the_fluid_state")
                                ? static_cast<std::uint64_t>(stats.int_attribute("walls_before_the_fluid_state"))
                                : 0;
  checkpoint_seconds_ = stats.double_attribute("checkpoint_seconds");
  wall_before_ = stats.double_attribute("wall_seconds");
  bytes_received_before_ = static_cast<std::uint64_t>(stats.int_attribute("bytes_received"));
  bytes_sent_before_ = static_cast<std::uint64_t>(stats.int_attribute("bytes_sent"));
  restarts_ = nlohmann::json::parse(stats.string_attribute("restarts"));
  resumes_ = nlohmann::json::parse(stats.string_attribute("resumes"));
  for (auto& peer : peers_) {
    const std::string key = std::string(peer->name()) + "_compute_seconds";
    if (stats.has_attribute(key)) peer->compute_seconds = stats.double_attribute(key);
    const std::string steps_key = std::string(peer->name()) + "_solver_steps";
    if (stats.has_attribute(steps_key)) peer->solver_steps = static_cast<std::uint64_t>(stats.int_attribute(steps_key));
    const std::string holds_key = std::string(peer->name()) + "_hold_exchanges";
    if (stats.has_attribute(holds_key)) peer->holds = static_cast<std::uint64_t>(stats.int_attribute(holds_key));
  }
  steps_ = *resume_step_;

  if (forces_csv_) forces_csv_->restore(group.group("forces"));
  if (energy_csv_) energy_csv_->restore(group.group("energy"));
  if (sensors_) {
    if (!group.exists("sensors")) fail_file("it holds no state of the sensors, while the scene has some");
    sensors_->restore(group.group("sensors"));
  }
  part_energies_.restore(group.group("part_energies"));
  replies_.boundary().restore(group.group("boundary_channel"));
  const io::hdf5::Group pairs = group.group("pairs");
  if (static_cast<std::size_t>(pairs.int_attribute("count")) != pairs_.size()) {
    fail_file(fmt::format("it holds {} contact pairs, this scene has {}", pairs.int_attribute("count"), pairs_.size()));
  }
  for (std::size_t i = 0; i < pairs_.size(); ++i) {
    PairSlot& slot = pairs_[i];
    const std::string name = pair_group_name(i, slot.pair->name());
    if (!pairs.exists(name)) fail_file(fmt::format("it holds no history of the contact pair {}", name));
    const io::hdf5::Group pair = pairs.group(name);
    slot.pair->restore_history(pair);
    slot.seconds = pair.double_attribute("coupler_seconds");
    slot.max_residual = pair.double_attribute("coupler_max_residual");
    // dt_{n-1} as the pair sees it: its last interval (the coupler's before hold exchanges).
    slot.dt_previous =
        pair.has_attribute("coupler_dt_previous") ? pair.double_attribute("coupler_dt_previous") : dt_previous_;
  }
  resumes_.push_back({{"from_step", *resume_step_},
                      {"time", expected_time_},
                      {"wall_seconds_before", wall_before_},
                      {"reason", options_.resume_reason}});
  events_.emit({{"event", "resumed"}, {"from_step", *resume_step_}, {"time", expected_time_}});
  resume_file_.close();
}

}  // namespace sabo::coupler
