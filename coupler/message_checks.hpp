#pragma once
// What the coupler checks of a solver's messages before anything is computed
// from them (issue-18 hardening: a solver that sends NaN, out-of-range indices
// or duplicate ids is refused naming the solver, the field, the entity and the
// value, instead of failing later inside a contact pair).
#include <optional>
#include <string>

#include "libsabo/scene/estimate.hpp"
#include "libsabo/scene/scene.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::coupler {

// The first problem of a particle table (registration or a state's new table) of a solver of `role`:
// array lengths, unique ids, finite radius > 0 and mass > 0, material and body indices in range.
[[nodiscard]] std::optional<std::string> particle_table_problem(const sabo::v1::ParticleTable& table,
                                                                const scene::Scene& scene, Role role);

// The first problem of a surface topology (registration or a state's new topology): array lengths,
// unique node ids, finite node positions, triangle corners and parts in range, finite thickness >= 0, bulk
// modulus > 0, element volume >= 0 and node mass >= 0.
[[nodiscard]] std::optional<std::string> surface_problem(const sabo::v1::SurfaceTopology& surface,
                                                         const scene::Scene& scene);

// A stable step the run cannot be made of, s: not a number, <= 0, or so small that end_time would take more
// than scene::kMaxSteps steps (a model blown up, or an input such as a Young's modulus of 1e300; the scene
// check refuses what it can foresee with the same bound, scene/estimate.hpp).
using scene::kMaxSteps;
[[nodiscard]] std::optional<std::string> stable_dt_problem(double stable_dt, double end_time);

}  // namespace sabo::coupler
