#include "libsabo/physics/cell_list.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>

namespace sabo::physics {
namespace {

constexpr std::int32_t kFree = std::numeric_limits<std::int32_t>::min();
// At most this many cells along an axis, so that coordinates fit in 32 bits.
constexpr std::int64_t kMaxCellsPerAxis = std::int64_t{1} << 30;

// splitmix64 finaliser over the three coordinates: spreads neighbouring cells over the table.
std::uint64_t hash(std::int32_t x, std::int32_t y, std::int32_t z) {
  std::uint64_t key = (static_cast<std::uint64_t>(static_cast<std::uint32_t>(x)) << 32) ^
                      (static_cast<std::uint64_t>(static_cast<std::uint32_t>(y)) << 16) ^
                      (static_cast<std::uint64_t>(static_cast<std::uint32_t>(z)) * 0x9e3779b97f4a7c15ULL);
  key = (key ^ (key >> 30)) * 0xbf58476d1ce4e5b9ULL;
  key = (key ^ (key >> 27)) * 0x94d049bb133111ebULL;
  return key ^ (key >> 31);
}

bool finite(const Aabb& box) {
  return !box.empty() && box.min.allFinite() && box.max.allFinite();
}

}  // namespace

void CellList::prepare(const Aabb& extent, double cell_size) {
  assert(cell_size > 0 && std::isfinite(cell_size));
  cell_size_ = cell_size;
  origin_ = extent.empty() ? Vec3::Zero() : extent.min;
  if (!extent.empty()) {
    const double largest_extent = (extent.max - extent.min).maxCoeff();
    // Keep every coordinate below kMaxCellsPerAxis (rare: items spread over millions of cells).
    if (largest_extent / cell_size_ >= static_cast<double>(kMaxCellsPerAxis - 2)) {
      cell_size_ = largest_extent / static_cast<double>(kMaxCellsPerAxis - 2);
    }
    for (int axis = 0; axis < 3; ++axis) {
      dims_[axis] = static_cast<std::int64_t>(std::floor((extent.max[axis] - origin_[axis]) / cell_size_)) + 1;
    }
  } else {
    dims_[0] = dims_[1] = dims_[2] = 0;
  }
  entry_cell_.clear();
  entry_item_.clear();
  item_count_ = 0;
}

CellList::CellKey CellList::cell_of(const Vec3& p) const {
  std::int32_t index[3];
  for (int axis = 0; axis < 3; ++axis) {
    index[axis] = static_cast<std::int32_t>(
        std::clamp(static_cast<std::int64_t>(std::floor((p[axis] - origin_[axis]) / cell_size_)), std::int64_t{0},
                   dims_[axis] - 1));
  }
  return CellKey{index[0], index[1], index[2]};
}

CellList::CellRange CellList::range_of(const Aabb& box) const {
  CellRange range{{0, 0, 0}, {-1, -1, -1}};
  if (box.empty() || box.min.hasNaN() || box.max.hasNaN()) return range;
  for (int axis = 0; axis < 3; ++axis) {
    const double last = static_cast<double>(dims_[axis] - 1);
    // Same formula as cell_of, so that an item inside the box is in a visited cell.
    const double lo = std::floor((box.min[axis] - origin_[axis]) / cell_size_);
    const double hi = std::floor((box.max[axis] - origin_[axis]) / cell_size_);
    if (hi < 0 || lo > last) return CellRange{{0, 0, 0}, {-1, -1, -1}};
    range.lo[axis] = static_cast<std::int64_t>(std::max(lo, 0.0));
    range.hi[axis] = static_cast<std::int64_t>(std::min(hi, last));
  }
  return range;
}

std::uint32_t CellList::insert_cell(const CellKey& key) {
  if (dense_) return static_cast<std::uint32_t>((std::int64_t{key.z} * dims_[1] + key.y) * dims_[0] + key.x);
  const std::size_t mask = table_keys_.size() - 1;
  std::size_t slot = hash(key.x, key.y, key.z) & mask;
  while (table_keys_[slot].x != kFree && table_keys_[slot] != key) slot = (slot + 1) & mask;
  if (table_keys_[slot].x == kFree) {
    table_keys_[slot] = key;
    table_cells_[slot] = static_cast<std::uint32_t>(cell_start_.size());
    cell_start_.push_back(0);  // one slot per cell; counts are filled in finish()
  }
  return table_cells_[slot];
}

std::span<const std::uint32_t> CellList::items_in(std::int64_t ix, std::int64_t iy, std::int64_t iz) const {
  assert(!dense_);  // the dense grid is read by rows in for_each_in
  const CellKey key{static_cast<std::int32_t>(ix), static_cast<std::int32_t>(iy), static_cast<std::int32_t>(iz)};
  const std::size_t mask = table_keys_.size() - 1;
  std::size_t slot = hash(key.x, key.y, key.z) & mask;
  while (table_keys_[slot] != key) {
    if (table_keys_[slot].x == kFree) return {};
    slot = (slot + 1) & mask;
  }
  const std::uint32_t cell = table_cells_[slot];
  return std::span<const std::uint32_t>(cell_items_)
      .subspan(cell_start_[cell], cell_start_[cell + 1] - cell_start_[cell]);
}

void CellList::finish(std::size_t item_count) {
  item_count_ = item_count;
  const std::size_t cells = cell_start_.size();
  // Counting sort of the entries by cell, stable in item order.
  cell_start_.push_back(0);
  std::fill(cell_start_.begin(), cell_start_.end(), 0U);
  for (std::uint32_t cell : entry_cell_) ++cell_start_[cell + 1];
  for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  cell_items_.resize(entry_item_.size());
  cursor_.assign(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t e = 0; e < entry_item_.size(); ++e) cell_items_[cursor_[entry_cell_[e]]++] = entry_item_[e];
}

std::size_t CellList::occupied_cell_count() const {
  std::size_t occupied = 0;
  for (std::size_t c = 0; c + 1 < cell_start_.size(); ++c) occupied += cell_start_[c + 1] > cell_start_[c] ? 1 : 0;
  return occupied;
}

void CellList::reset_table(std::size_t entries) {
  const double cells = static_cast<double>(dims_[0]) * static_cast<double>(dims_[1]) * static_cast<double>(dims_[2]);
  dense_ = cells <= static_cast<double>(std::max<std::size_t>(4 * entries, 4096));
  if (dense_) {
    cell_start_.assign(static_cast<std::size_t>(cells), 0);  // every cell, filled in finish()
    return;
  }
  const std::size_t size = std::bit_ceil(std::max<std::size_t>(2 * entries, 16));
  table_keys_.assign(size, CellKey{kFree, 0, 0});
  table_cells_.resize(size);
  cell_start_.clear();
}

void CellList::build_points(std::span<const Vec3> points, double cell_size) {
  assert(points.size() < std::numeric_limits<std::uint32_t>::max());
  Aabb extent;
  std::size_t count = 0;
  for (const Vec3& p : points) {
    if (p.allFinite()) {
      extent.extend(p);
      ++count;
    }
  }
  prepare(extent, cell_size);
  reset_table(count);
  entry_cell_.reserve(count);
  entry_item_.reserve(count);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    entry_cell_.push_back(insert_cell(cell_of(points[i])));
    entry_item_.push_back(static_cast<std::uint32_t>(i));
  }
  finish(count);
}

void CellList::build_boxes(std::span<const Aabb> boxes, double cell_size) {
  Aabb extent;
  std::size_t count = 0;
  for (const Aabb& box : boxes) {
    if (finite(box)) {
      extent.extend(box);
      ++count;
    }
  }
  prepare(extent, cell_size);
  std::size_t entries = 0;
  for (const Aabb& box : boxes) {
    if (!finite(box)) continue;
    const CellRange range = range_of(box);
    entries += static_cast<std::size_t>((range.hi[0] - range.lo[0] + 1) * (range.hi[1] - range.lo[1] + 1) *
                                        (range.hi[2] - range.lo[2] + 1));
  }
  reset_table(entries);
  entry_cell_.reserve(entries);
  entry_item_.reserve(entries);
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    if (!finite(boxes[i])) continue;
    const CellRange range = range_of(boxes[i]);
    for (std::int64_t iz = range.lo[2]; iz <= range.hi[2]; ++iz) {
      for (std::int64_t iy = range.lo[1]; iy <= range.hi[1]; ++iy) {
        for (std::int64_t ix = range.lo[0]; ix <= range.hi[0]; ++ix) {
          entry_cell_.push_back(insert_cell(
              CellKey{static_cast<std::int32_t>(ix), static_cast<std::int32_t>(iy), static_cast<std::int32_t>(iz)}));
          entry_item_.push_back(static_cast<std::uint32_t>(i));
        }
      }
    }
  }
  finish(count);
}

void CellList::candidates(const Aabb& box, std::vector<std::uint32_t>& out) const {
  out.clear();
  for_each_in(box, [&out](std::uint32_t item) { out.push_back(item); });
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

}  // namespace sabo::physics
