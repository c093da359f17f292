#pragma once
// Ranks over MPI (Open MPI from Debian): a thin RAII session and the collectives of
// ranks.hpp on MPI_COMM_WORLD. Every MPI call's error comes back as MpiError carrying MPI's
// own message (the communicator's handler is MPI_ERRORS_RETURN).
#include <string>

#include "libsabo/core/error.hpp"
#include "sph_solver/parallel/ranks.hpp"

namespace sabo::sph::parallel {

class MpiError : public Error {
 public:
  using Error::Error;
};

// Whether this process was started by mpirun (or another MPI launcher): only then does
// sph_solver start MPI, so that a plain start stays a plain process.
[[nodiscard]] bool launched_by_mpi();

// MPI_Init_thread (funneled: OpenMP threads never call MPI) on construction, MPI_Finalize on
// destruction. One per process.
class MpiSession {
 public:
  MpiSession(int& argc, char**& argv);
  ~MpiSession();
  // Ends every rank of the job with `code` (MPI_Abort): for a failure that may have left the
  // other ranks waiting inside a collective call.
  [[noreturn]] void abort(int code);
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
};

class MpiRanks final : public Ranks {
 public:
  MpiRanks();  // MPI_COMM_WORLD of the live session
  [[nodiscard]] int rank() const override { return rank_; }
  [[nodiscard]] int size() const override { return size_; }
  void min(std::span<double> values) override;
  void max(std::span<double> values) override;
  void sum(std::span<std::int64_t> values) override;
  void sum_disjoint(std::span<double> values) override;
  [[nodiscard]] std::vector<std::vector<double>> all_to_all(const std::vector<std::vector<double>>& to) override;
  [[nodiscard]] std::vector<std::vector<float>> exchange(std::span<const int> peers,
                                                         const std::vector<std::vector<float>>& sends) override;
  void broadcast(std::vector<double>& values, int root) override;
  void broadcast(std::vector<std::uint8_t>& bytes, int root) override;

 private:
  int rank_ = 0, size_ = 1;
};

}  // namespace sabo::sph::parallel
