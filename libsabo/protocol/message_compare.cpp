#include "libsabo/protocol/message_compare.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>

namespace sabo::protocol {

namespace {

const char* axis(int component) {
  static const char* names[] = {"x", "y", "z"};
  return component >= 0 && component < 3 ? names[component] : "";
}

std::string entity_text(const Divergence& d) {
  if (d.entity.empty()) return "";
  return d.component >= 0 ? fmt::format("{} ({})", d.entity, axis(d.component)) : d.entity;
}

}  // namespace

const std::vector<std::string>& compared_state_fields() {
  static const std::vector<std::string> fields{"time",           "stable_dt",        "index",         "position",
                                               "velocity",       "angular_velocity", "node_position", "node_velocity",
                                               "boundary_force", "boundary_step",    "energies",      "particle_table",
                                               "topology"};
  return fields;
}

const std::vector<std::string>& compared_forces_fields() {
  static const std::vector<std::string> fields{"dt",
                                               "flags",
                                               "index",
                                               "force",
                                               "torque",
                                               "node_force",
                                               "interest",
                                               "boundary_position",
                                               "boundary_velocity",
                                               "boundary_normal",
                                               "boundary_acceleration",
                                               "boundary_volume",
                                               "boundary_free_slip"};
  return fields;
}

void MessageComparison::count_step(std::uint64_t step) {
  if (steps_ == 0 || step != last_step_) ++steps_;
  last_step_ = step;
}

Tolerance MessageComparison::tolerance(const std::string& field) const {
  const auto it = tolerances_.find(field);
  return it == tolerances_.end() ? Tolerance{} : it->second;
}

void MessageComparison::structural(std::uint64_t step, double time, const std::string& field, const std::string& note) {
  if (skipped(field)) return;
  FieldSummary& summary = fields_[field];
  if (!summary.first_step) summary.first_step = step;
  if (step_marks_[field] != step + 1) {
    step_marks_[field] = step + 1;
    ++summary.steps;
  }
  ++summary.entities;
  if (!first_) {
    Divergence d;
    d.step = step;
    d.time = time;
    d.field = field;
    d.note = note;
    first_ = d;
  }
}

void MessageComparison::scalar(std::uint64_t step, double time, const std::string& field, const std::string& entity,
                               double recorded, double replayed) {
  if (skipped(field)) return;
  FieldSummary& summary = fields_[field];
  ++summary.compared;
  const Tolerance tol = tolerance(field);
  if (replayed == recorded || (std::isnan(recorded) && std::isnan(replayed))) return;  // also infinities
  const double difference = std::abs(replayed - recorded);
  if (difference <= tol.atol + tol.rtol * std::abs(recorded)) return;
  const double relative = recorded != 0 ? difference / std::abs(recorded) : std::numeric_limits<double>::infinity();
  if (!summary.first_step) summary.first_step = step;
  if (step_marks_[field] != step + 1) {
    step_marks_[field] = step + 1;
    ++summary.steps;
  }
  ++summary.entities;
  summary.max_absolute = std::max(summary.max_absolute, difference);
  summary.max_relative = std::max(summary.max_relative, relative);
  if (!first_) {
    Divergence d;
    d.step = step;
    d.time = time;
    d.field = field;
    d.entity = entity;
    d.recorded = recorded;
    d.replayed = replayed;
    d.absolute = difference;
    d.relative = relative;
    d.tolerance = tol;
    first_ = d;
  }
}

template <class Values>
void MessageComparison::compare_values(std::uint64_t step, double time, const std::string& field,
                                       const Values& recorded, const Values& replayed, int per_entity,
                                       const EntityName& entity_name) {
  if (skipped(field)) return;
  if (recorded.size() != replayed.size()) {
    structural(step, time, field, fmt::format("{} values recorded, {} replayed", recorded.size(), replayed.size()));
    return;
  }
  FieldSummary& summary = fields_[field];
  for (int k = 0; k < recorded.size(); ++k) {
    const auto a = static_cast<double>(recorded[k]);
    const auto b = static_cast<double>(replayed[k]);
    if (a == b) {  // the usual case, counted here: the rest of scalar()'s work is for values that differ
      ++summary.compared;
      continue;
    }
    const auto e = static_cast<std::size_t>(k / per_entity);
    const std::size_t before = first_ ? 1 : 0;
    scalar(step, time, field, entity_name(e), a, b);
    if (before == 0 && first_ && first_->field == field && first_->step == step && per_entity == 3) {
      first_->component = k % 3;
    }
  }
}

MessageComparison::EntityName MessageComparison::particle_names(
    const sabo::v1::Register& registration, const google::protobuf::RepeatedField<std::uint32_t>& index) {
  return [&registration, &index](std::size_t e) {
    if (e >= static_cast<std::size_t>(index.size())) return fmt::format("entry {}", e);
    const std::uint32_t i = index[static_cast<int>(e)];
    const auto& table = registration.particles();
    return i < static_cast<std::uint32_t>(table.id_size()) ? fmt::format("particle {}", table.id(static_cast<int>(i)))
                                                           : fmt::format("particle index {}", i);
  };
}

MessageComparison::EntityName MessageComparison::node_names() const {
  return [this](std::size_t e) {
    return e < node_ids_.size() ? fmt::format("node {}", node_ids_[e]) : fmt::format("entry {}", e);
  };
}

MessageComparison::EntityName MessageComparison::numbered(const char* what) {
  return [what](std::size_t e) { return fmt::format("{} {}", what, e); };
}

void MessageComparison::compare_states(const sabo::v1::Register& registration, const sabo::v1::StepState& recorded,
                                       const sabo::v1::StepState& replayed) {
  const std::uint64_t step = recorded.step();
  const double time = recorded.time();
  count_step(step);
  if (!node_ids_set_) {
    node_ids_.assign(registration.surface().node_id().begin(), registration.surface().node_id().end());
    node_ids_set_ = true;
  }
  if (replayed.step() != step) {
    structural(step, time, "step", fmt::format("recorded step {}, replayed step {}", step, replayed.step()));
  }
  if (replayed.held() != recorded.held()) {
    structural(step, time, "step",
               fmt::format("recorded a {} state, replayed a {} one (hold exchanges)",
                           recorded.held() ? "held" : "whole", replayed.held() ? "held" : "whole"));
  }
  scalar(step, time, "time", "", recorded.time(), replayed.time());
  scalar(step, time, "stable_dt", "", recorded.stable_dt(), replayed.stable_dt());
  if (!std::equal(recorded.index().begin(), recorded.index().end(), replayed.index().begin(), replayed.index().end())) {
    structural(step, time, "index",
               fmt::format("{} particles recorded, {} replayed (the interest regions or the active particles differ)",
                           recorded.index_size(), replayed.index_size()));
  } else if (!skipped("index")) {
    fields_["index"].compared += static_cast<std::uint64_t>(recorded.index_size());
  }
  const auto particles = particle_names(registration, recorded.index());
  compare_values(step, time, "position", recorded.position(), replayed.position(), 3, particles);
  compare_values(step, time, "velocity", recorded.velocity(), replayed.velocity(), 3, particles);
  compare_values(step, time, "angular_velocity", recorded.angular_velocity(), replayed.angular_velocity(), 3,
                 particles);
  if (recorded.has_topology() != replayed.has_topology() ||
      (recorded.has_topology() && recorded.topology().SerializeAsString() != replayed.topology().SerializeAsString())) {
    structural(step, time, "topology",
               recorded.has_topology() == replayed.has_topology()
                   ? "the new surface topologies differ"
                   : (recorded.has_topology() ? "recorded a new topology, "
                                                "none replayed"
                                              : "replayed a new topology, "
                                                "none recorded"));
  }
  if (recorded.has_topology())
    node_ids_.assign(recorded.topology().node_id().begin(), recorded.topology().node_id().end());
  const auto nodes = node_names();
  compare_values(step, time, "node_position", recorded.node_position(), replayed.node_position(), 3, nodes);
  compare_values(step, time, "node_velocity", recorded.node_velocity(), replayed.node_velocity(), 3, nodes);
  compare_values(step, time, "boundary_force", recorded.boundary_force(), replayed.boundary_force(), 3,
                 numbered("boundary particle"));
  if (recorded.has_boundary_step() != replayed.has_boundary_step() ||
      recorded.boundary_step() != replayed.boundary_step()) {
    structural(step, time, "boundary_step", "the step whose wall particles the forces answer differs");
  }
  const auto& er = recorded.energies();
  const auto& ep = replayed.energies();
  scalar(step, time, "energies", "kinetic", er.kinetic(), ep.kinetic());
  scalar(step, time, "energies", "potential", er.potential(), ep.potential());
  scalar(step, time, "energies", "elastic", er.elastic(), ep.elastic());
  scalar(step, time, "energies", "dissipated", er.dissipated(), ep.dissipated());
  if (recorded.has_particle_table() != replayed.has_particle_table() ||
      (recorded.has_particle_table() &&
       recorded.particle_table().SerializeAsString() != replayed.particle_table().SerializeAsString())) {
    structural(step, time, "particle_table", "the new particle tables differ");
  }
}

void MessageComparison::compare_forces(const sabo::v1::Register& registration, const sabo::v1::StepForces& recorded,
                                       const sabo::v1::StepForces& replayed) {
  const std::uint64_t step = recorded.step();
  const double time = 0;
  count_step(step);
  if (!node_ids_set_) {
    node_ids_.assign(registration.surface().node_id().begin(), registration.surface().node_id().end());
    node_ids_set_ = true;
  }
  scalar(step, time, "dt", "", recorded.dt(), replayed.dt());
  const auto flags = [](const sabo::v1::StepForces& f) {
    return (f.checkpoint() ? 1 : 0) | (f.output() ? 2 : 0) | (f.stop() ? 4 : 0) | (f.interest_all() ? 8 : 0) |
           (f.hold() ? 16 : 0);
  };
  scalar(step, time, "flags", "", flags(recorded), flags(replayed));
  scalar(step, time, "flags", "holds", recorded.holds(), replayed.holds());
  if (!std::equal(recorded.index().begin(), recorded.index().end(), replayed.index().begin(), replayed.index().end())) {
    structural(step, time, "index",
               fmt::format("{} particles recorded, {} replayed", recorded.index_size(), replayed.index_size()));
  }
  const auto particles = particle_names(registration, recorded.index());
  compare_values(step, time, "force", recorded.force(), replayed.force(), 3, particles);
  compare_values(step, time, "torque", recorded.torque(), replayed.torque(), 3, particles);
  compare_values(step, time, "node_force", recorded.node_force(), replayed.node_force(), 3, node_names());
  std::vector<double> boxes_recorded, boxes_replayed;
  for (const auto* list : {&recorded, &replayed}) {
    auto& out = list == &recorded ? boxes_recorded : boxes_replayed;
    for (const auto& b : list->interest())
      out.insert(out.end(), {b.min_x(), b.min_y(), b.min_z(), b.max_x(), b.max_y(), b.max_z()});
  }
  google::protobuf::RepeatedField<double> rb(boxes_recorded.begin(), boxes_recorded.end()),
      pb(boxes_replayed.begin(), boxes_replayed.end());
  compare_values(step, time, "interest", rb, pb, 6, numbered("box"));
  const EntityName boundary = numbered("boundary particle");
  compare_values(step, time, "boundary_position", recorded.boundary_position(), replayed.boundary_position(), 3,
                 boundary);
  compare_values(step, time, "boundary_velocity", recorded.boundary_velocity(), replayed.boundary_velocity(), 3,
                 boundary);
  compare_values(step, time, "boundary_normal", recorded.boundary_normal(), replayed.boundary_normal(), 3, boundary);
  compare_values(step, time, "boundary_acceleration", recorded.boundary_acceleration(),
                 replayed.boundary_acceleration(), 3, boundary);
  compare_values(step, time, "boundary_volume", recorded.boundary_volume(), replayed.boundary_volume(), 1, boundary);
  compare_values(step, time, "boundary_free_slip", recorded.boundary_free_slip(), replayed.boundary_free_slip(), 1,
                 boundary);
}

std::string MessageComparison::report() const {
  std::string out;
  if (!first_) {
    out += fmt::format("every field matches over {} steps\n", steps_);
  } else {
    const Divergence& d = *first_;
    out += fmt::format("first divergence: step {}, t = {:.9g} s, field {}", d.step, d.time, d.field);
    if (!d.note.empty()) {
      out += fmt::format(": {}\n", d.note);
    } else {
      out += fmt::format(
          "{}{}: recorded {:.17g}, replayed {:.17g}, |difference| {:.3g}, relative {:.3g} (tolerance "
          "rtol {:g}, atol {:g})\n",
          d.entity.empty() ? "" : ", ", entity_text(d), d.recorded, d.replayed, d.absolute, d.relative,
          d.tolerance.rtol, d.tolerance.atol);
    }
  }
  out += fmt::format("{:<22} {:>12} {:>8} {:>10} {:>12} {:>12}\n", "field", "first step", "steps", "values",
                     "max |diff|", "max rel");
  for (const auto& [field, s] : fields_) {
    out += fmt::format("{:<22} {:>12} {:>8} {:>10} {:>12.3g} {:>12.3g}\n", field,
                       s.first_step ? std::to_string(*s.first_step) : std::string("-"), s.steps, s.entities,
                       s.max_absolute, s.max_relative);
  }
  if (!skipped_.empty()) out += fmt::format("not compared (not recorded): {}\n", fmt::join(skipped_, ", "));
  if (!taken_.empty()) {
    out += fmt::format("taken from the recording at every step (the solver's own values replaced): {}\n",
                       fmt::join(taken_, ", "));
  }
  return out;
}

nlohmann::json MessageComparison::json() const {
  using nlohmann::json;
  json fields = json::object();
  for (const auto& [field, s] : fields_) {
    fields[field] = {{"first_step", s.first_step ? json(*s.first_step) : json(nullptr)},
                     {"steps", s.steps},
                     {"values", s.entities},
                     {"compared", s.compared},
                     {"max_absolute", s.max_absolute},
                     {"max_relative", std::isfinite(s.max_relative) ? json(s.max_relative) : json("inf")}};
  }
  json first = nullptr;
  if (first_) {
    const Divergence& d = *first_;
    first = {{"step", d.step},
             {"time", d.time},
             {"field", d.field},
             {"entity", d.entity},
             {"component", d.component >= 0 ? json(axis(d.component)) : json(nullptr)},
             {"recorded", d.recorded},
             {"replayed", d.replayed},
             {"absolute", d.absolute},
             {"relative", std::isfinite(d.relative) ? json(d.relative) : json("inf")},
             {"rtol", d.tolerance.rtol},
             {"atol", d.tolerance.atol},
             {"note", d.note}};
  }
  return {
      {"matches", matches()}, {"steps", steps_},          {"first_divergence", first},
      {"fields", fields},     {"not_compared", skipped_}, {"taken", taken_},
  };
}

}  // namespace sabo::protocol
