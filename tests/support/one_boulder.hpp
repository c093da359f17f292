#pragma once
// One DEM boulder for the coupler alone, with the test scripting the dem_solver (tests/coupler, the fuzz
// targets and bench/fuzz_campaign.cpp): the scene's body, the solver's registration and its state.
#include <unistd.h>

#include <cstdint>
#include <string>

#include "libsabo/protocol/wire.hpp"
#include "libsabo/scene/scene.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::testing {

// Adds the boulder to `scene`: material "rock" (3000 kg/m^3), set "boulders" with one sphere of 0.5 m at
// z = 1 m, at rest, and the dem_solver's settings (beta 1).
void add_one_boulder(scene::Scene& scene);

// The scripted dem_solver's registration of that boulder.
sabo::v1::Register boulder_registration(const std::string& name);

// Its state at `step`: the boulder where it started, at rest.
sabo::v1::StepState boulder_state(std::uint64_t step, double time, double stable_dt);

}  // namespace sabo::testing
