// summary.json at the end of a run (its fields: README.md, "The run folder"): the status, steps and times,
// each process's compute and wait seconds, the coupling overhead, the effects and their pairs' seconds, the
// restarts and the energies.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>

#include "coupler/coupler.hpp"
#include "coupler/coupler_peer.hpp"
#include "coupler/effects.hpp"

namespace sabo::coupler {

// Each solver's steps and exchanges, and the steps lock-step (paper eq. 7) would have taken over the same
// simulated time: every solver at the smallest stable step of all.
nlohmann::json Coupler::multirate_summary() const {
  nlohmann::json solvers = nlohmann::json::object();
  const double lock_steps = std::round(lock_step_equivalent_);
  double saved = 0;
  for (const auto& peer : peers_) {
    const double steps = static_cast<double>(peer->solver_steps);
    solvers[peer->name()] = {{"steps", peer->solver_steps},
                             {"exchanges", steps_ > 0 ? steps_ - 1 : 0},
                             {"hold_exchanges", peer->holds},
                             {"lock_step_steps", lock_steps},
                             {"steps_saved", lock_steps - steps}};
    saved += lock_steps - steps;
  }
  nlohmann::json out = {{"enabled", scene_.run.multirate}, {"solvers", solvers}, {"steps_saved", saved}};
  if (held_forces_lost_ > 0) out["held_forces_lost"] = held_forces_lost_;
  return out;
}

void Coupler::write_summary(const std::string& status) {
  using nlohmann::json;
  const double wall = wall_before_ + seconds_since(start_wall_);
  json processes = json::object();
  processes["coupler"] = {{"contact_seconds", contact_seconds_},
                          {"contact_seconds_on_critical_path", critical_contact_seconds_},
                          {"checkpoint_seconds", checkpoint_seconds_},
                          {"messaging_seconds", receive_seconds_ + send_seconds_},
                          {"wait_seconds", wait_seconds_ - receive_seconds_}};
  // Exchanges whose boundary particles went to the sph_solver before its state was in (docs/protocol.md).
  if (walls_ahead_) processes["coupler"]["walls_before_the_fluid_state"] = walls_before_the_fluid_;
  for (const auto& peer : peers_) {
    const bool have_goodbye = peer->said_goodbye && peer->goodbye.steps() > 0;
    processes[peer->name()] = {
        {"pid", peer->registration.pid()},
        {"name", peer->registration.name()},
        {"compute_seconds", have_goodbye ? peer->goodbye.compute_seconds() : peer->compute_seconds},
        {"checkpoint_seconds", have_goodbye ? peer->goodbye.checkpoint_seconds() : 0.0},
        {"wait_seconds", have_goodbye ? peer->goodbye.wait_seconds() : peer->reported_wait},
        {"steps", have_goodbye ? peer->goodbye.steps() : steps_},
        {"solver_steps", peer->solver_steps},
        {"exit", peer->said_goodbye ? peer->goodbye.reason() : std::string("no goodbye")}};
  }
  const double per_step = steps_ > 0 ? 1.0 / static_cast<double>(steps_) : 0.0;
  const std::uint64_t bytes_received = bytes_received_before_ + socket_.bytes_received();  // a resumed run: all of it
  const std::uint64_t bytes_sent = bytes_sent_before_ + socket_.bytes_sent();
  const double overhead = std::max(0.0, wall - critical_compute_seconds_ - critical_contact_seconds_);
  json energies = json::object();
  if (energy_csv_) {
    auto sample_json = [](const EnergySample& e) {
      return json{{"time", e.time},
                  {"kinetic", e.kinetic},
                  {"potential", e.potential},
                  {"solver_elastic", e.solver_elastic},
                  {"contact_elastic", e.contact_elastic},
                  {"dissipated", e.dissipated},
                  {"inflow", e.inflow},
                  {"total", e.total()}};
    };
    energies = {{"initial", sample_json(energy_csv_->initial())},
                {"final", sample_json(energy_csv_->last())},
                {"max_total", energy_csv_->max_total()},
                {"max_rise_over_initial", energy_csv_->max_total() - energy_csv_->initial().own()}};
  }
  // Deformable FEM parts: the history of internal, kinetic, plastic work,
  // hourglass and eroded energy at the output times (columns), and the largest
  // hourglass share of the internal energy among the samples holding at least
  // a tenth of the part's largest internal energy.
  json structures = json::object();
  for (const auto& [part, samples] : part_energies_.history()) {
    json columns = {{"time", json::array()},          {"kinetic", json::array()},        {"internal", json::array()},
                    {"plastic_work", json::array()},  {"hourglass", json::array()},      {"eroded", json::array()},
                    {"external_work", json::array()}, {"eroded_elements", json::array()}};
    double peak_internal = 0;
    for (const auto& e : samples) {
      columns["time"].push_back(e.time);
      columns["kinetic"].push_back(e.kinetic);
      columns["internal"].push_back(e.internal);
      columns["plastic_work"].push_back(e.plastic_work);
      columns["hourglass"].push_back(e.hourglass);
      columns["eroded"].push_back(e.eroded);
      columns["external_work"].push_back(e.external_work);
      columns["eroded_elements"].push_back(e.eroded_elements);
      peak_internal = std::max(peak_internal, e.internal);
    }
    double worst_hourglass = 0;
    for (const auto& e : samples) {
      if (e.internal > 0 && e.internal >= 0.1 * peak_internal) {
        worst_hourglass = std::max(worst_hourglass, e.hourglass / e.internal);
      }
    }
    structures[part] = {{"history", columns}, {"max_hourglass_over_internal", worst_hourglass}};
  }
  if (!structures.empty()) energies["structures"] = structures;
  json peak_forces = json::object();
  if (forces_csv_) {
    for (std::size_t part = 0; part < forces_csv_->part_names().size(); ++part) {
      for (std::size_t source = 0; source < forces_csv_->sources().size(); ++source) {
        peak_forces[forces_csv_->part_names()[part]][forces_csv_->sources()[source]] =
            forces_csv_->peak()[part][source];
      }
    }
  }
  // Each solver's own results (Goodbye results_json): a JSON object, or the reason it is not one.
  json results = json::object();
  for (const auto& peer : peers_) {
    const std::string& text = peer->goodbye.results_json();
    if (!peer->said_goodbye || text.empty()) continue;
    json parsed = json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (parsed.is_discarded() || !parsed.is_object()) {
      spdlog::warn("{}: its results are not a JSON object ({} bytes); summary.json says so", peer->name(), text.size());
      parsed = {{"error", fmt::format("the solver's results are not a JSON object ({} bytes)", text.size())}};
    }
    results[peer->name()] = std::move(parsed);
  }
  json effects = solver_effects(scene_, processes);
  json pair_residuals = json::object();
  for (const auto& slot : pairs_) {
    json effect = slot.pair->effect();
    effect["seconds"] = slot.seconds;
    pair_residuals[effect["effect"].get<std::string>()] = slot.max_residual;
    effects.push_back(std::move(effect));
  }
  if (recorder_) effects.push_back({{"effect", "traffic_recording"}, {"process", "coupler"}});

  json summary = {
      {"status", status},
      {"failure", failure_},
      {"scene", scene_.file.string()},
      {"steps", steps_},
      {"simulated_time", time_},
      {"end_time", scene_.run.end_time},
      {"wall_seconds", wall},
      {"steps_per_second", wall > 0 ? static_cast<double>(steps_) / wall : 0.0},
      {"dt", {{"min", std::isfinite(dt_min_) ? dt_min_ : 0.0}, {"max", dt_max_}}},
      {"multirate", multirate_summary()},
      {"checkpoints",
       {{"interval", scene_.run.checkpoint_period()},
        {"written", checkpoints_},
        {"coupler_failed", checkpoint_failures_}}},
      {"restarts", restarts_},
      {"resumes", resumes_},
      {"processes", processes},
      {"coupling_overhead",
       {{"seconds", overhead},
        {"microseconds_per_step", 1e6 * overhead * per_step},
        {"fraction_of_wall", wall > 0 ? overhead / wall : 0.0}}},
      {"bytes_exchanged",
       {{"received", bytes_received},
        {"sent", bytes_sent},
        {"per_step", static_cast<double>(bytes_received + bytes_sent) * per_step}}},
      {"traffic", {{"file", "traffic.h5"}, {"bytes", recorder_ ? recorder_->bytes_written() : 0}}},
      {"energies", energies},
      {"newton_third_law",
       {{"max_relative_residual", newton_max_residual_},
        {"violations", newton_violations_},
        {"max_relative_residual_per_pair", pair_residuals}}},
      {"contacts", {{"max_simultaneous", max_contacts_}}},
      {"connections",
       {{"max_message_bytes", max_message_bytes_},
        {"accepted", guard_->stats().accepted},
        {"closed_unregistered", guard_->stats().dropped_unregistered},
        {"closed_over_limit", guard_->stats().dropped_over_limit},
        {"most_unregistered_at_once", guard_->stats().most_unregistered}}},
      {"security", security_summary()},
      {"peak_force", peak_forces},
      {"results", results},
      {"active_effects", effects},
  };
  const auto file = options_.out_dir / "summary.json";
  const auto temporary = options_.out_dir / "summary.json.tmp";
  {
    std::ofstream out = std::move(summary_out_);
    if (!out.is_open()) out.open(temporary);
    if (!out) {
      // The descriptor the connection guard kept in reserve, should connections have taken every other one.
      guard_->release_reserve();
      out.open(temporary);
    }
    out << summary.dump(2) << "\n";
    if (!out) throw FileError(fmt::format("cannot write '{}'", temporary.string()));
  }
  std::filesystem::rename(temporary, file);
}

nlohmann::json Coupler::security_summary() const {
  nlohmann::json refused = nlohmann::json::array();
  for (const auto& connection : guard_->refused()) {
    refused.push_back({{"address", connection.address}, {"reason", connection.reason}, {"count", connection.count}});
  }
  nlohmann::json security = {
      {"transport", protocol::transport_of(options_.endpoint) == protocol::Transport::tcp ? "tcp" : "ipc"},
      {"mechanism", protocol::mechanism_name(mechanism_)},
      {"heartbeat_timeout", scene_.run.heartbeat_timeout},
      {"refused_handshakes", guard_->stats().refused_handshakes},
      {"refused", refused}};
  if (!security_warning_.empty()) security["warning"] = security_warning_;
  return security;
}

}  // namespace sabo::coupler
