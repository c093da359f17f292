#include "sph_solver/parallel/slabs.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>

#include "libsabo/core/error.hpp"

namespace sabo::sph::parallel {

Slabs::Slabs(std::span<const std::int64_t> counts, int ranks) {
  assert(ranks >= 1);
  const auto layers = static_cast<std::int64_t>(counts.size());
  if (layers < ranks) {
    throw Error(fmt::format(
        "sph_solver: the particles span {} layers of cells (2h thick) along the slab axis, fewer than the {} ranks; "
        "each rank needs at least one. Fix: run with at most {} ranks (mpirun -n {})",
        layers, ranks, layers, std::max<std::int64_t>(layers, 1)));
  }
  std::int64_t total = 0;
  for (std::int64_t c : counts) total += c;
  first_.assign(static_cast<std::size_t>(ranks) + 1, 0);
  first_.back() = layers;
  // Rank r starts at the first layer whose particles before it reach r * total / R (integer
  // arithmetic: the same on every rank), kept at least one layer after rank r - 1 and early
  // enough to leave one layer for each rank after it.
  std::int64_t before = 0, layer = 0;
  for (int r = 1; r < ranks; ++r) {
    const std::int64_t target = total * r / ranks;
    while (layer < layers && before + counts[static_cast<std::size_t>(layer)] <= target) {
      before += counts[static_cast<std::size_t>(layer)];
      ++layer;
    }
    std::int64_t start = std::max(layer, first_[static_cast<std::size_t>(r) - 1] + 1);
    start = std::min(start, layers - (ranks - r));
    first_[static_cast<std::size_t>(r)] = start;
    while (layer < start) before += counts[static_cast<std::size_t>(layer++)];
    while (layer > start) before -= counts[static_cast<std::size_t>(--layer)];
  }
}

int Slabs::owner(std::int64_t layer) const {
  assert(layer >= 0 && layer < layers());
  const auto after = std::upper_bound(first_.begin(), first_.end() - 1, layer);
  return static_cast<int>(after - first_.begin()) - 1;
}

std::vector<int> Slabs::windows_holding(std::int64_t layer) const {
  std::vector<int> holders;
  for (std::int64_t l = layer - 1; l <= layer + 1; ++l) {
    if (l < 0 || l >= layers()) continue;
    const int q = owner(l);
    if (in_window(q, layer) && (holders.empty() || holders.back() != q)) holders.push_back(q);
  }
  return holders;
}

}  // namespace sabo::sph::parallel
