#include "sph_solver/parallel/mpi_ranks.hpp"

#include <fmt/format.h>
#include <mpi.h>

#include <cstdlib>
#include <limits>

namespace sabo::sph::parallel {
namespace {

void check(int code, const char* call) {
  if (code == MPI_SUCCESS) return;
  char message[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(code, message, &length);
  throw MpiError(
      fmt::format("sph_solver: {} failed: {}", call, std::string(message, static_cast<std::size_t>(length))));
}

int count_of(std::size_t size, const char* what) {
  if (size > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw MpiError(fmt::format("sph_solver: {} of {} values is too large for one MPI message", what, size));
  }
  return static_cast<int>(size);
}

}  // namespace

bool launched_by_mpi() {
  // Open MPI's launcher sets the first, PMIx-based launchers (srun, prterun) the second,
  // MPICH's Hydra the third.
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE"}) {
    if (std::getenv(name) != nullptr) return true;
  }
  return false;
}

MpiSession::MpiSession(int& argc, char**& argv) {
  int provided = 0;
  check(MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
}

MpiSession::~MpiSession() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

void MpiSession::abort(int code) {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::abort();  // MPI_Abort does not return
}

MpiRanks::MpiRanks() {
  check(MPI_Comm_rank(MPI_COMM_WORLD, &rank_), "MPI_Comm_rank");
  check(MPI_Comm_size(MPI_COMM_WORLD, &size_), "MPI_Comm_size");
}

void MpiRanks::min(std::span<double> values) {
  check(MPI_Allreduce(MPI_IN_PLACE, values.data(), count_of(values.size(), "min"), MPI_DOUBLE, MPI_MIN, MPI_COMM_WORLD),
        "MPI_Allreduce(min)");
}

void MpiRanks::max(std::span<double> values) {
  check(MPI_Allreduce(MPI_IN_PLACE, values.data(), count_of(values.size(), "max"), MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD),
        "MPI_Allreduce(max)");
}

void MpiRanks::sum(std::span<std::int64_t> values) {
  check(
      MPI_Allreduce(MPI_IN_PLACE, values.data(), count_of(values.size(), "sum"), MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD),
      "MPI_Allreduce(sum)");
}

void MpiRanks::sum_disjoint(std::span<double> values) {
  check(MPI_Allreduce(MPI_IN_PLACE, values.data(), count_of(values.size(), "sum"), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD),
        "MPI_Allreduce(sum)");
}

std::vector<std::vector<double>> MpiRanks::all_to_all(const std::vector<std::vector<double>>& to) {
  const auto ranks = static_cast<std::size_t>(size_);
  std::vector<int> send_counts(ranks), send_offsets(ranks), receive_counts(ranks), receive_offsets(ranks);
  std::vector<double> sending;
  for (std::size_t q = 0; q < ranks; ++q) {
    send_offsets[q] = count_of(sending.size(), "all_to_all");
    send_counts[q] = count_of(to[q].size(), "all_to_all");
    sending.insert(sending.end(), to[q].begin(), to[q].end());
  }
  check(MPI_Alltoall(send_counts.data(), 1, MPI_INT, receive_counts.data(), 1, MPI_INT, MPI_COMM_WORLD),
        "MPI_Alltoall");
  std::size_t total = 0;
  for (std::size_t q = 0; q < ranks; ++q) {
    receive_offsets[q] = count_of(total, "all_to_all");
    total += static_cast<std::size_t>(receive_counts[q]);
  }
  std::vector<double> received(total);
  check(MPI_Alltoallv(sending.data(), send_counts.data(), send_offsets.data(), MPI_DOUBLE, received.data(),
                      receive_counts.data(), receive_offsets.data(), MPI_DOUBLE, MPI_COMM_WORLD),
        "MPI_Alltoallv");
  std::vector<std::vector<double>> from(ranks);
  for (std::size_t q = 0; q < ranks; ++q) {
    const auto begin = received.begin() + receive_offsets[q];
    from[q].assign(begin, begin + receive_counts[q]);
  }
  return from;
}

std::vector<std::vector<float>> MpiRanks::exchange(std::span<const int> peers,
                                                   const std::vector<std::vector<float>>& sends) {
  constexpr int kTag = 17;
  std::vector<MPI_Request> requests(peers.size());
  for (std::size_t k = 0; k < peers.size(); ++k) {
    check(MPI_Isend(sends[k].data(), count_of(sends[k].size(), "exchange"), MPI_FLOAT, peers[k], kTag, MPI_COMM_WORLD,
                    &requests[k]),
          "MPI_Isend");
  }
  std::vector<std::vector<float>> received(peers.size());
  for (std::size_t k = 0; k < peers.size(); ++k) {
    MPI_Status status;
    check(MPI_Probe(peers[k], kTag, MPI_COMM_WORLD, &status), "MPI_Probe");
    int count = 0;
    check(MPI_Get_count(&status, MPI_FLOAT, &count), "MPI_Get_count");
    received[k].resize(static_cast<std::size_t>(count));
    check(MPI_Recv(received[k].data(), count, MPI_FLOAT, peers[k], kTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
          "MPI_Recv");
  }
  check(MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  return received;
}

void MpiRanks::broadcast(std::vector<double>& values, int root) {
  std::int64_t count = static_cast<std::int64_t>(values.size());
  check(MPI_Bcast(&count, 1, MPI_INT64_T, root, MPI_COMM_WORLD), "MPI_Bcast");
  values.resize(static_cast<std::size_t>(count));
  check(MPI_Bcast(values.data(), count_of(values.size(), "broadcast"), MPI_DOUBLE, root, MPI_COMM_WORLD), "MPI_Bcast");
}

void MpiRanks::broadcast(std::vector<std::uint8_t>& bytes, int root) {
  std::int64_t count = static_cast<std::int64_t>(bytes.size());
  check(MPI_Bcast(&count, 1, MPI_INT64_T, root, MPI_COMM_WORLD), "MPI_Bcast");
  bytes.resize(static_cast<std::size_t>(count));
  check(MPI_Bcast(bytes.data(), count_of(bytes.size(), "broadcast"), MPI_BYTE, root, MPI_COMM_WORLD), "MPI_Bcast");
}

}  // namespace sabo::sph::parallel
