#pragma once
// The 8-node hexahedron's geometry shared by the mesh reader (io/gmsh.hpp) and
// the FEM element (fem_solver/elements/hex8.hpp). Node order, in natural
// coordinates (xi, eta, zeta):
//   0 (-,-,-) 1 (+,-,-) 2 (+,+,-) 3 (-,+,-) 4 (-,-,+) 5 (+,-,+) 6 (+,+,+) 7 (-,+,+)
#include <array>

#include "libsabo/core/types.hpp"

namespace sabo::geometry {

// Volume at the element centre, 8 det J, m^3 (exact for parallelepipeds): positive for an element in
// this node order, zero for a flat one and negative for an inverted one.
[[nodiscard]] double hexahedron_volume(const std::array<Vec3, 8>& x);

}  // namespace sabo::geometry
