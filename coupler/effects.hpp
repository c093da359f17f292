#pragma once
// What the run summary lists as the active effects of the solvers (the
// contact pairs describe their own): the scene decides what is simulated (docs/design.md), and the
// summary says what each effect cost.
#include <nlohmann/json.hpp>

#include "libsabo/scene/scene.hpp"

namespace sabo::coupler {

// processes: summary.json's "processes" object (compute_seconds per solver name).
[[nodiscard]] nlohmann::json solver_effects(const scene::Scene& scene, const nlohmann::json& processes);

}  // namespace sabo::coupler
