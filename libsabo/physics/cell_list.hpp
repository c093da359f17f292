#pragma once
// Uniform-grid neighbour search. Items (points, or boxes such as triangle
// bounds) are binned into cubic cells. When the grid over the items' extent
// has few cells for the items (at most 4 per binning), every cell is stored in
// a dense array (z, then y, then x), and the cells of a query along x are one
// contiguous run of items; otherwise only occupied cells are stored, in a hash
// table keyed by exact cell coordinates, so far outliers cost nothing. Either
// way the build is linear in the number of items. Buffers are kept between builds.
//
// Determinism: cells are visited in a fixed order (z, then y, then x
// ascending) and the items of a cell in ascending item index.
//
// Typical uses:
//   points, interaction distance <= cell size: for_each_near(p) visits every
//     item within cell_size of p (and more: filter by the real distance);
//   points against a box (e.g. a triangle's bounds inflated by the contact
//     range): for_each_in(box);
//   boxes against a point: for_each_in(Aabb{p, p}) visits every box whose
//     cells contain p. A box binned into several cells is visited once per
//     cell by a box query; candidates() returns a sorted, duplicate-free list.
#include <cstdint>
#include <span>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::physics {

class CellList {
 public:
  // Bins points; cell edge cell_size, m (> 0). Non-finite points are left out.
  void build_points(std::span<const Vec3> points, double cell_size);
  // Bins each box into every cell it overlaps. Empty or non-finite boxes are left out.
  void build_boxes(std::span<const Aabb> boxes, double cell_size);

  // Visits visit(item) for every item binned in the 3x3x3 cells around the cell of p.
  template <class Visit>
  void for_each_near(const Vec3& p, Visit&& visit) const;
  // Visits visit(item) for every item binned in a cell that overlaps box.
  template <class Visit>
  void for_each_in(const Aabb& box, Visit&& visit) const;
  // Whether test(item) holds for an item binned in a cell that overlaps box; stops at the first.
  template <class Test>
  [[nodiscard]] bool any_in(const Aabb& box, Test&& test) const;
  // Items binned in cells overlapping box, sorted and unique; replaces out's content.
  void candidates(const Aabb& box, std::vector<std::uint32_t>& out) const;

  // Cell edge actually used, m: the requested one, grown only when the items'
  // extent would need more than 2^30 cells along an axis.
  [[nodiscard]] double cell_size() const { return cell_size_; }
  [[nodiscard]] std::size_t item_count() const { return item_count_; }
  [[nodiscard]] std::size_t occupied_cell_count() const;  // counted on demand (diagnostics)

 private:
  struct CellKey {
    std::int32_t x, y, z;  // cell coordinates; x == INT32_MIN marks a free table slot
    bool operator==(const CellKey&) const = default;
  };
  struct CellRange {
    std::int64_t lo[3];
    std::int64_t hi[3];
    [[nodiscard]] bool empty() const { return lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]; }
  };
  void prepare(const Aabb& extent, double cell_size);
  [[nodiscard]] CellKey cell_of(const Vec3& p) const;       // p inside the extent
  [[nodiscard]] CellRange range_of(const Aabb& box) const;  // clipped to occupied cells
  // Chooses the dense grid or the hash table for `entries` binnings, and clears the cells.
  void reset_table(std::size_t entries);
  std::uint32_t insert_cell(const CellKey& key);
  [[nodiscard]] std::span<const std::uint32_t> items_in(std::int64_t ix, std::int64_t iy, std::int64_t iz) const;
  void finish(std::size_t item_count);  // counting sort of the entries by cell

  double cell_size_ = 0;
  Vec3 origin_ = Vec3::Zero();
  std::int64_t dims_[3] = {0, 0, 0};
  std::size_t item_count_ = 0;
  bool dense_ = false;  // cell id = (z * dims_[1] + y) * dims_[0] + x, no table
  // (cell id, item) per binning, in item order; then counting-sorted into cell_items_.
  std::vector<std::uint32_t> entry_cell_;  // cell id of each entry
  std::vector<std::uint32_t> entry_item_;
  std::vector<std::uint32_t> cell_start_;  // cell id -> first entry in cell_items_ (size cells + 1)
  std::vector<std::uint32_t> cell_items_;
  std::vector<CellKey> table_keys_;  // open addressing
  std::vector<std::uint32_t> table_cells_;
  std::vector<std::uint32_t> cursor_;
};

template <class Visit>
void CellList::for_each_near(const Vec3& p, Visit&& visit) const {
  if (item_count_ == 0 || !p.allFinite()) return;
  const Vec3 h = Vec3::Constant(cell_size_);
  for_each_in(Aabb{p - h, p + h}, visit);
}

template <class Visit>
void CellList::for_each_in(const Aabb& box, Visit&& visit) const {
  (void)any_in(box, [&](std::uint32_t item) {
    visit(item);
    return false;
  });
}

template <class Test>
bool CellList::any_in(const Aabb& box, Test&& test) const {
  if (item_count_ == 0) return false;
  const CellRange range = range_of(box);
  if (range.empty()) return false;
  for (std::int64_t iz = range.lo[2]; iz <= range.hi[2]; ++iz) {
    for (std::int64_t iy = range.lo[1]; iy <= range.hi[1]; ++iy) {
      if (dense_) {
        const auto row = static_cast<std::size_t>((iz * dims_[1] + iy) * dims_[0]);
        const std::uint32_t first = cell_start_[row + static_cast<std::size_t>(range.lo[0])];
        const std::uint32_t last = cell_start_[row + static_cast<std::size_t>(range.hi[0]) + 1];
        for (std::uint32_t e = first; e < last; ++e) {
          if (test(cell_items_[e])) return true;
        }
        continue;
      }
      for (std::int64_t ix = range.lo[0]; ix <= range.hi[0]; ++ix) {
        for (std::uint32_t item : items_in(ix, iy, iz)) {
          if (test(item)) return true;
        }
      }
    }
  }
  return false;
}

}  // namespace sabo::physics
