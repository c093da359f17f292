#pragma once
// What the supervisor needs to start a run of a loaded scene.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "libsabo/scene/scene.hpp"

namespace sabo::scene {

// The launch plan:
// {"scene": absolute path, "end_time", "output_interval", "hang_timeout",
//  "max_dt" (only when set), "endpoint": "ipc" | "tcp://HOST:PORT",
//  "processes": [{"role": "coupler", "command": [BIN/coupler]},
//                {"role": "dem_solver", "command": [...], "beta": 0.8}, ...],
//  "bodies": {"fluids", "particle_sets", "spheres", "structures", "materials"}}.
// The coupler comes first, then the solvers the scene needs in the order
// sph, dem, fem. A role without its own command runs bin_dir/<role name>
// (bin_dir made absolute). The supervisor appends --scene, --coupler, --out.
[[nodiscard]] nlohmann::json launch_plan(const Scene& scene, const std::filesystem::path& bin_dir);

}  // namespace sabo::scene
