#pragma once
// The neighbour search of SphModel on the grid of the last build_grid() (passes/grid.cpp):
// rows of 3 cells around a point, their x windows, and the blocks of kLanes slots the
// pair loops run over. Private to sph_solver/ (the passes and sph_sample.cpp).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// Slots per block of the inner loops (one AVX-512 register of floats); the
// cell-ordered arrays carry this many padding entries.
constexpr std::uint32_t kLanes = 16;

}  // namespace

// inline: as when defined in the class (the same inlining outside the pair loops).
template <class Visit>
inline void SphModel::for_neighbour_rows(double x, double y, double z, const std::vector<std::uint32_t>& start,
                                         Visit&& visit) const {
  const double inverse_cell = inverse_cell_;
  const auto cx = static_cast<std::int64_t>((x - grid_origin_.x()) * inverse_cell);
  const auto cy = static_cast<std::int64_t>((y - grid_origin_.y()) * inverse_cell);
  const auto cz = static_cast<std::int64_t>((z - grid_origin_.z()) * inverse_cell);
  const std::int64_t x0 = std::max<std::int64_t>(cx - 1, 0), x1 = std::min(cx + 1, nx_ - 1);
  for (std::int64_t kz = std::max<std::int64_t>(cz - 1, 0); kz <= std::min(cz + 1, nz_ - 1); ++kz) {
    for (std::int64_t ky = std::max<std::int64_t>(cy - 1, 0); ky <= std::min(cy + 1, ny_ - 1); ++ky) {
      const std::int64_t row = (kz * ny_ + ky) * nx_;
      const std::uint32_t begin = start[static_cast<std::size_t>(row + x0)];
      const std::uint32_t end = start[static_cast<std::size_t>(row + x1 + 1)];
      if (begin < end) {
        if constexpr (std::is_invocable_v<Visit, std::uint32_t, std::uint32_t, std::int64_t, std::int64_t>) {
          visit(begin, end, ky, kz);
        } else {
          visit(begin, end);
        }
      }
    }
  }
}

inline int SphModel::neighbour_rows(double x, double y, double z, const std::vector<std::uint32_t>& start,
                                    NeighbourRow (&rows)[9]) const {
  const double cell = kernel_.support(), support2 = cell * cell;
  const double px = x - grid_origin_.x(), py = y - grid_origin_.y(), pz = z - grid_origin_.z();
  const auto cy = static_cast<std::int64_t>(py * inverse_cell_);
  const auto cz = static_cast<std::int64_t>(pz * inverse_cell_);
  // Distance from p to the band [k cell, (k + 1) cell] of offset k - c: 0 inside, else to its nearer side.
  const auto band_distance = [&](double p, std::int64_t k, std::int64_t c) {
    if (k < c) return p - static_cast<double>(k + 1) * cell;
    if (k > c) return static_cast<double>(k) * cell - p;
    return 0.0;
  };
  int count = 0;
  for_neighbour_rows(x, y, z, start, [&](std::uint32_t begin, std::uint32_t end, std::int64_t ky, std::int64_t kz) {
    const double dy = std::max(0.0, band_distance(py, ky, cy)), dz = std::max(0.0, band_distance(pz, kz, cz));
    const double w2 = support2 - dy * dy - dz * dz;
    if (w2 <= 0) return;
    // The margin covers the float positions and the cell index rounding.
    const double w = std::sqrt(w2) + 1e-4 * cell;
    rows[count++] = {begin, end, static_cast<float>(px - w), static_cast<float>(px + w)};
  });
  return count;
}

// The inner loops index slots in 64 bits and test lanes in 32 bits: contiguous vector loads.
template <class Block>
void SphModel::for_neighbour_blocks(const Vec3& position, const std::vector<std::uint32_t>& start,
                                    const float* sorted_x, Block&& block) const {
  NeighbourRow rows[9];
  const int row_count = neighbour_rows(position.x(), position.y(), position.z(), start, rows);
  for (int r = 0; r < row_count; ++r) {
    const std::uint32_t end = rows[r].end;
    // Blocks wholly outside the x window hold no neighbour: skipped.
    std::uint32_t j0 = rows[r].begin;
    while (j0 < end && sorted_x[std::min(j0 + kLanes, end) - 1] < rows[r].x_min) j0 += kLanes;
    std::uint32_t stop = j0;
    while (stop < end && sorted_x[stop] <= rows[r].x_max) stop += kLanes;
    for (; j0 < stop; j0 += kLanes) block(j0, static_cast<std::int32_t>(std::min(end - j0, kLanes)));
  }
}

template <class Visit>
inline void SphModel::for_neighbours(double x, double y, double z, const std::vector<std::uint32_t>& start,
                                     Visit&& visit) const {
  for_neighbour_rows(x, y, z, start, [&](std::uint32_t begin, std::uint32_t end) {
    for (std::uint32_t j = begin; j < end; ++j) visit(j);
  });
}

}  // namespace sabo::sph
