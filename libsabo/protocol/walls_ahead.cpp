#include "libsabo/protocol/walls_ahead.hpp"

#include <cassert>

namespace sabo::protocol {

bool has_boundary_particles(const sabo::v1::StepForces& forces) {
  return forces.boundary_position_size() > 0 || forces.boundary_velocity_size() > 0 ||
         forces.boundary_normal_size() > 0 || forces.boundary_acceleration_size() > 0 ||
         forces.boundary_volume_size() > 0 || forces.boundary_free_slip_size() > 0;
}

void move_boundary_particles(sabo::v1::StepForces& from, sabo::v1::StepForces& into) {
  assert(!has_boundary_particles(into) && "the step's own StepForces carries no boundary particles");
  into.mutable_boundary_position()->Swap(from.mutable_boundary_position());
  into.mutable_boundary_velocity()->Swap(from.mutable_boundary_velocity());
  into.mutable_boundary_normal()->Swap(from.mutable_boundary_normal());
  into.mutable_boundary_acceleration()->Swap(from.mutable_boundary_acceleration());
  into.mutable_boundary_volume()->Swap(from.mutable_boundary_volume());
  into.mutable_boundary_free_slip()->Swap(from.mutable_boundary_free_slip());
}

}  // namespace sabo::protocol
