#pragma once
#include <cstdint>

#include "libsabo/core/types.hpp"

namespace sabo::coupler {

// One load a contact pair put on a structure this step, where it acts on the surface (sensors.csv).
struct PointLoad {
  std::uint32_t part = 0;     // the part's index in the FEM surface (SurfaceMesh::part_name)
  Vec3 point = Vec3::Zero();  // m, on the surface
  Vec3 force = Vec3::Zero();  // N, on the structure
};

}  // namespace sabo::coupler
