// Run-time choice of the instruction set for hot loops: a loop body handed to
// with_best_isa() is compiled three times (x86-64 baseline, x86-64-v3: AVX2 + FMA,
// x86-64-v4: AVX-512) with every call inside it inlined, and the best copy the CPU
// has runs, the same one for every call. So the binaries stay portable, and the
// results are the same bits on any thread count (not across instruction sets: FMA).
#pragma once

#include <fmt/format.h>

#include <cstdlib>
#include <string>

#include "libsabo/core/error.hpp"

namespace sabo {

enum class Isa { generic, avx2, avx512 };

// The CPU's best instruction set, or a lower one asked for by SABO_ISA=generic|avx2
// (to test those copies; asking for more than the CPU has gives its best).
inline Isa best_isa() {
  static const Isa isa = [] {
    Isa best = Isa::generic;
#if defined(__x86_64__) && defined(__GNUC__)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("x86-64-v4")) {
      best = Isa::avx512;
    } else if (__builtin_cpu_supports("x86-64-v3")) {
      best = Isa::avx2;
    }
#endif
    const char* asked = std::getenv("SABO_ISA");
    if (asked == nullptr || *asked == '\0') return best;
    const std::string name(asked);
    const Isa wanted = name == "generic" ? Isa::generic
                       : name == "avx2"  ? Isa::avx2
                       : name == "avx512"
                           ? Isa::avx512
                           : throw Error(fmt::format("SABO_ISA={}: unknown instruction set. Fix: generic, avx2, "
                                                     "avx512 or unset (the best the CPU has)",
                                                     name));
    return wanted < best ? wanted : best;
  }();
  return isa;
}

namespace detail {
#if defined(__x86_64__) && defined(__GNUC__)
template <class F>
[[gnu::target("arch=x86-64-v4,prefer-vector-width=512"), gnu::flatten]] void run_avx512(F f) {
  f();
}
template <class F>
[[gnu::target("arch=x86-64-v3"), gnu::flatten]] void run_avx2(F f) {
  f();
}
#endif
template <class F>
[[gnu::flatten]] void run_generic(F f) {
  f();
}
}  // namespace detail

// f() compiled for the best instruction set (see best_isa()), every call inside inlined.
template <class F>
void with_best_isa(F f) {
#if defined(__x86_64__) && defined(__GNUC__)
  switch (best_isa()) {
    case Isa::avx512: detail::run_avx512(f); return;
    case Isa::avx2: detail::run_avx2(f); return;
    case Isa::generic: break;
  }
#endif
  detail::run_generic(f);
}

}  // namespace sabo
