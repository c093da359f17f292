#pragma once
// SurfaceMesh <-> SurfaceTopology message (docs/protocol.md).
#include "libsabo/geometry/surface_mesh.hpp"
#include "sabo/v1/sabo.pb.h"

namespace sabo::protocol {

void surface_to_message(const geometry::SurfaceMesh& mesh, std::uint64_t revision, sabo::v1::SurfaceTopology& out);
// Whether the message's arrays agree in length: 3 coordinates per node id, 3
// corners and one part per triangle.
[[nodiscard]] bool arrays_consistent(const sabo::v1::SurfaceTopology& topology);
// Throws sabo::Error (naming `sender`) when the message is inconsistent.
geometry::SurfaceMesh surface_from_message(const sabo::v1::SurfaceTopology& topology, const std::string& sender);

}  // namespace sabo::protocol
