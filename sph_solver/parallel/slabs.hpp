#pragma once
// Slabs of the neighbour grid's layers along one axis, one slab per rank, in rank order,
// balanced by the particles each layer holds (docs/architecture.md, "The slurry on several
// processes"). Pure arithmetic: the same counts give every rank the same slabs.
#include <cstdint>
#include <span>
#include <vector>

namespace sabo::sph::parallel {

class Slabs {
 public:
  Slabs() = default;
  // counts[l]: particles in layer l (summed over the ranks). Rank r gets layers
  // [first(r), first(r + 1)), at least one each, with about r/R of the particles before it.
  // Throws Error when there are fewer layers than ranks.
  Slabs(std::span<const std::int64_t> counts, int ranks);

  [[nodiscard]] int ranks() const { return static_cast<int>(first_.size()) - 1; }
  [[nodiscard]] std::int64_t layers() const { return first_.back(); }
  [[nodiscard]] std::int64_t first(int rank) const { return first_[static_cast<std::size_t>(rank)]; }
  [[nodiscard]] int owner(std::int64_t layer) const;
  // Whether `layer` is in rank's window: its slab and one layer either side (its halo).
  [[nodiscard]] bool in_window(int rank, std::int64_t layer) const {
    return layer >= first(rank) - 1 && layer <= first(rank + 1);
  }
  // The ranks whose window holds `layer`, ascending (one to three).
  [[nodiscard]] std::vector<int> windows_holding(std::int64_t layer) const;

 private:
  std::vector<std::int64_t> first_{0, 0};  // per rank, then the layer count
};

}  // namespace sabo::sph::parallel
