#pragma once
// The element-to-node gather shared by the element loops: each element writes
// its corner forces into its own slots (element * corners + corner), then each
// node sums the slots that touch it in element order. No two threads write the
// same memory and the sum order is fixed, so 1 and 2 threads give the same bits.
#include <array>
#include <cstdint>
#include <vector>

namespace sabo::fem {

class NodeGather {
 public:
  NodeGather() = default;
  template <std::size_t Corners>
  NodeGather(std::size_t nodes, const std::vector<std::array<std::uint32_t, Corners>>& elements) {
    start_.assign(nodes + 1, 0);
    for (const auto& element : elements) {
      for (std::uint32_t node : element) ++start_[node + 1];
    }
    for (std::size_t i = 0; i < nodes; ++i) start_[i + 1] += start_[i];
    slots_.resize(Corners * elements.size());
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t e = 0; e < elements.size(); ++e) {
      for (std::size_t a = 0; a < Corners; ++a)
        slots_[fill[elements[e][a]]++] = static_cast<std::uint32_t>(Corners * e + a);
    }
  }

  // Sum over the slots of `node` of values[slot], in element order.
  template <typename Value>
  [[nodiscard]] Value sum(std::size_t node, const std::vector<Value>& values) const {
    Value total = Value::Zero();
    for (std::uint32_t s = start_[node]; s < start_[node + 1]; ++s) total += values[slots_[s]];
    return total;
  }

 private:
  std::vector<std::uint32_t> start_, slots_;  // CSR: node -> element slots
};

}  // namespace sabo::fem
