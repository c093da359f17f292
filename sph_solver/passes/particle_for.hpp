#pragma once
// The loop of every pass over particles (fluid slots, wall slots or particle ids), as
// SPHinXsys's particle_for: the passes say what one range of particles computes, this
// file how the ranges are spread over threads and compiled. Private to sph_solver/.
//
// [0, size) is cut into chunks of `chunk` indices, handed to the threads by OpenMP's
// static schedule (the same chunks to the same thread on every call) when `parallel`
// holds, else run in order on the calling thread. Every chunk's results go to its own
// indices, so the bits do not depend on the number of threads; particle_reduce() joins
// per-thread partials, and their join must not depend on the order either (max, min,
// integer sums: no floating-point sum).
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "libsabo/core/isa.hpp"

namespace sabo::sph {
namespace {

// Above this many particles (or wall particles; images not counted: the loops skip them) the loops run in parallel.
constexpr std::size_t kParallelThreshold = 512;
// Particles per unit of work handed to with_best_isa() by the parallel loops.
constexpr std::size_t kChunk = 64;

// Whether a loop over `particles` real particles runs on several threads.
inline bool in_parallel(std::size_t particles) {
  return particles > kParallelThreshold;
}

// How a body is compiled. best_isa: with_best_isa() (libsabo/core/isa.hpp), one copy per
// instruction set with every call inlined: the single-precision pair loops, vectorised.
// baseline: once, for x86-64 (no FMA): the loops in double precision (sorting, gather,
// wall stress, integration), whose bits then do not depend on the CPU.
enum class Compile { best_isa, baseline };

// body(first, last) for every chunk [first, last) of [0, size). The pair loops' bodies
// capture by value ([=, this]), and each chunk's compiled copy gets its own copy of the
// body: the captured pointers are locals of that copy, which the compiler can keep in
// registers. always_inline: the wrapper adds no call of its own around the OpenMP loop.
template <Compile How = Compile::best_isa, class Body>
[[gnu::always_inline]] inline void particle_for(std::size_t size, bool parallel, std::size_t chunk, Body body) {
  const auto count = static_cast<std::int64_t>(size), step = static_cast<std::int64_t>(chunk);
  const std::int64_t chunks = (count + step - 1) / step;
#pragma omp parallel for schedule(static) if (parallel)
  for (std::int64_t c = 0; c < chunks; ++c) {
    const std::int64_t first = c * step, last = std::min(count, first + step);
    if constexpr (How == Compile::best_isa) {
      with_best_isa([body, first, last] { body(first, last); });
    } else {
      body(first, last);
    }
  }
}

// In chunks of kChunk.
template <Compile How = Compile::best_isa, class Body>
[[gnu::always_inline]] inline void particle_for(std::size_t size, bool parallel, Body body) {
  particle_for<How>(size, parallel, kChunk, body);
}

// particle_for() with a reduction: body(first, last, partial) folds its chunk into its
// thread's partial (a copy of `identity`), and total.join(partial) folds each thread's
// partial into the result, which starts as `identity`. Same chunks, same schedule.
template <Compile How = Compile::best_isa, class Partial, class Body>
[[gnu::always_inline]] inline Partial particle_reduce(std::size_t size, bool parallel, const Partial& identity,
                                                      Body body) {
  const auto count = static_cast<std::int64_t>(size), step = static_cast<std::int64_t>(kChunk);
  const std::int64_t chunks = (count + step - 1) / step;
  Partial total = identity;
#pragma omp parallel if (parallel)
  {
    Partial partial = identity;
#pragma omp for schedule(static) nowait
    for (std::int64_t c = 0; c < chunks; ++c) {
      const std::int64_t first = c * step, last = std::min(count, first + step);
      if constexpr (How == Compile::best_isa) {
        with_best_isa([body, first, last, &partial] { body(first, last, partial); });
      } else {
        body(first, last, partial);
      }
    }
#pragma omp critical(sabo_sph_particle_reduce)
    total.join(partial);
  }
  return total;
}

}  // namespace
}  // namespace sabo::sph
