#pragma once
// A few boxes that together cover many small ones: the interest regions of
// docs/design.md, "Only the interface travels". One bounding box of a sloping floor or of dams far apart holds
// far more of the scene than the surfaces themselves; a handful of tiles hugs
// them, so the particles sent grow with the interface, not the scene's volume.
#include <cstddef>
#include <span>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::geometry {

// Boxes per interest region of one contact pair: a solver tests an entity
// against up to this many before it is left out of the step's state.
inline constexpr std::size_t kMaxInterestBoxes = 16;

// Every non-empty piece lies inside at least one returned box; at most
// max_boxes (>= 1) boxes. The pieces are binned by their centres into cubic
// tiles of the finest of 16, 8, 4, 2 or 1 divisions of the longest side that
// yields at most max_boxes occupied tiles; each box is the union of its tile's
// pieces (so it may reach past the tile). Boxes come in tile order (z, y, x):
// the same pieces give the same boxes. Empty when no piece is non-empty.
[[nodiscard]] std::vector<Aabb> covering_boxes(std::span<const Aabb> pieces, std::size_t max_boxes);
// The same for points (pieces of zero size).
[[nodiscard]] std::vector<Aabb> covering_boxes(std::span<const Vec3> points, std::size_t max_boxes);

// Sum of the boxes' volumes, m^3 (overlaps counted twice): what a cover costs.
[[nodiscard]] double total_volume(std::span<const Aabb> boxes);

}  // namespace sabo::geometry
