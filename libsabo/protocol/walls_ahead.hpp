#pragma once
// Walls ahead (docs/protocol.md, "Walls ahead"): the boundary particles of a step go to the sph_solver in a
// StepForces of their own (walls_ahead set) before the step's StepForces, which then carries none. The
// recording and a restart's catch-up keep the one StepForces a solver without walls ahead gets: these
// helpers split and join the two.
#include "sabo/v1/sabo.pb.h"

namespace sabo::protocol {

// Whether any boundary_* field of `forces` holds values.
[[nodiscard]] bool has_boundary_particles(const sabo::v1::StepForces& forces);

// Moves the boundary_* fields of `from` into `into`, which must have none (asserted): `from` is left without
// them. Swaps the arrays; nothing is copied.
void move_boundary_particles(sabo::v1::StepForces& from, sabo::v1::StepForces& into);

}  // namespace sabo::protocol
