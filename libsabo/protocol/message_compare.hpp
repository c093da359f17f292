#pragma once
// Field-by-field comparison of recorded and replayed messages (replay, and the
// catch-up of a restarted process): which field diverges first, at which step,
// for which entity, by how much, and a summary per field.
//
// A value matches when |replayed - recorded| <= atol + rtol |recorded| for its
// field's tolerance: exact (0, 0) by default. Entities are named by their ids:
// a particle by its particle-table id, a surface node by its node id, a
// boundary particle by its place in the list, an energy by its name.
#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "sabo/v1/sabo.pb.h"

namespace sabo::protocol {

struct Tolerance {
  double rtol = 0, atol = 0;
};

// The fields a comparison knows: StepState's and StepForces' (docs/traffic.md).
[[nodiscard]] const std::vector<std::string>& compared_state_fields();
[[nodiscard]] const std::vector<std::string>& compared_forces_fields();

struct Divergence {
  std::uint64_t step = 0;
  double time = 0;  // s, of the recorded message
  std::string field;
  std::string entity;  // "particle 12", "node 40", "boundary particle 3", "kinetic", "" (the field as a whole)
  int component = -1;  // 0, 1, 2 for x, y, z; -1 for a scalar
  double recorded = 0, replayed = 0;
  double absolute = 0, relative = 0;
  Tolerance tolerance;
  std::string note;  // for structural differences: what differs (lengths, ids)
};

struct FieldSummary {
  std::optional<std::uint64_t> first_step;
  std::uint64_t steps = 0;     // steps with a divergence in this field
  std::uint64_t entities = 0;  // divergent values, summed over the steps
  double max_absolute = 0, max_relative = 0;
  std::uint64_t compared = 0;  // values compared
};

class MessageComparison {
 public:
  // tolerances per field name; a field not named is exact.
  explicit MessageComparison(std::map<std::string, Tolerance> tolerances = {}) : tolerances_(std::move(tolerances)) {}

  // Fields left out of the comparison (a recording that did not keep them); the report lists them.
  void skip(std::set<std::string> fields) { skipped_ = std::move(fields); }
  // Fields fed to the solver from the recording (replay --take): still compared, they match from step 1 on
  // by construction; the report names them.
  void set_taken(std::set<std::string> fields) { taken_ = std::move(fields); }

  // `registration`: of the solver the messages are about (it names the particles; surface nodes come from
  // its surface, or from the last topology seen).
  void compare_states(const sabo::v1::Register& registration, const sabo::v1::StepState& recorded,
                      const sabo::v1::StepState& replayed);
  void compare_forces(const sabo::v1::Register& registration, const sabo::v1::StepForces& recorded,
                      const sabo::v1::StepForces& replayed);

  [[nodiscard]] bool matches() const { return !first_.has_value(); }
  [[nodiscard]] const std::optional<Divergence>& first() const { return first_; }
  [[nodiscard]] const std::map<std::string, FieldSummary>& fields() const { return fields_; }
  [[nodiscard]] std::uint64_t steps_compared() const { return steps_; }

  // A text report: the first divergence, then one line per field.
  [[nodiscard]] std::string report() const;
  [[nodiscard]] nlohmann::json json() const;

 private:
  // The name of entity e of a field ("particle 12", "node 40"), made only for a value that differs.
  using EntityName = std::function<std::string(std::size_t)>;
  template <class Values>
  void compare_values(std::uint64_t step, double time, const std::string& field, const Values& recorded,
                      const Values& replayed, int per_entity, const EntityName& entity_name);
  void structural(std::uint64_t step, double time, const std::string& field, const std::string& note);
  void scalar(std::uint64_t step, double time, const std::string& field, const std::string& entity, double recorded,
              double replayed);
  [[nodiscard]] Tolerance tolerance(const std::string& field) const;
  void count_step(std::uint64_t step);
  // Both refer to `registration` and `index`, which must outlive them.
  [[nodiscard]] static EntityName particle_names(const sabo::v1::Register& registration,
                                                 const google::protobuf::RepeatedField<std::uint32_t>& index);
  [[nodiscard]] EntityName node_names() const;
  [[nodiscard]] static EntityName numbered(const char* what);

  [[nodiscard]] bool skipped(const std::string& field) const { return skipped_.count(field) != 0; }

  std::map<std::string, Tolerance> tolerances_;
  std::set<std::string> skipped_, taken_;
  std::optional<Divergence> first_;
  std::map<std::string, FieldSummary> fields_;
  std::uint64_t steps_ = 0, last_step_ = 0;
  std::vector<std::uint64_t> node_ids_;  // of the surface now (registration, then topologies)
  bool node_ids_set_ = false;
  std::map<std::string, std::uint64_t> step_marks_;  // field -> the last step counted in its summary
};

}  // namespace sabo::protocol
