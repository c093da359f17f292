#pragma once
// The ranks an SphModel is decomposed over (docs/architecture.md, "The slurry on several
// processes"): the collective operations the model needs, behind one interface so that the
// physics does not see MPI (mpi_ranks.hpp implements it; a model without ranks runs alone).
//
// Every call is collective over the ranks that share the model: all of them call it, in the
// same order. Reductions that the results depend on are exact whatever the rank count
// (min, max, integer sums, a sum where one rank holds each nonzero entry).
#include <cstdint>
#include <span>
#include <vector>

namespace sabo::sph::parallel {

class Ranks {
 public:
  virtual ~Ranks() = default;
  [[nodiscard]] virtual int rank() const = 0;
  [[nodiscard]] virtual int size() const = 0;

  // Element-wise over the ranks, in place.
  virtual void min(std::span<double> values) = 0;
  virtual void max(std::span<double> values) = 0;
  virtual void sum(std::span<std::int64_t> values) = 0;
  // Element-wise sum; exact where at most one rank holds a nonzero value of each element.
  virtual void sum_disjoint(std::span<double> values) = 0;
  // to[q] goes to rank q; returns what each rank sent this one (index: sender).
  [[nodiscard]] virtual std::vector<std::vector<double>> all_to_all(const std::vector<std::vector<double>>& to) = 0;
  // Point-to-point among neighbours: sends[k] goes to peers[k] and the result's k-th entry
  // is what peers[k] sent this rank (each pair of ranks calls it with each other as peers).
  [[nodiscard]] virtual std::vector<std::vector<float>> exchange(std::span<const int> peers,
                                                                 const std::vector<std::vector<float>>& sends) = 0;
  // root's values to every rank (resized on the others).
  virtual void broadcast(std::vector<double>& values, int root) = 0;
  virtual void broadcast(std::vector<std::uint8_t>& bytes, int root) = 0;
};

}  // namespace sabo::sph::parallel
