#pragma once
// A sum of doubles that does not depend on the order of its terms: each term is rounded once
// to a multiple of 2^-64 (J, for the energies: far below a double's rounding of any sum of
// them) and the multiples are added exactly in 128-bit integers. So the model's energies are
// the same bits on any number of threads and ranks (sph_model.hpp, "Ranks"). The integer part
// holds |sum| < 2^63 (9.2e18 J).
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>

namespace sabo::sph {

// GCC's and Clang's 128-bit integers (__extension__: not ISO C++, and -Wpedantic says so).
__extension__ typedef __int128 Int128;
__extension__ typedef unsigned __int128 UInt128;

class ExactSum {
 public:
  static constexpr int kFractionBits = 64;
  // The sum travels between ranks as 4 limbs of 32 bits in int64s, whose element-wise sum over
  // up to 2^31 ranks is exact; from_limbs() carries them back.
  using Limbs = std::array<std::int64_t, 4>;

  void add(double term) {
    const double scaled = std::nearbyint(std::ldexp(term, kFractionBits));
    assert(std::abs(scaled) < 0x1p126 && "an energy term beyond the exact sum's range");
    sum_ += static_cast<Int128>(scaled);
  }
  void join(const ExactSum& other) { sum_ += other.sum_; }
  [[nodiscard]] double value() const { return std::ldexp(static_cast<double>(sum_), -kFractionBits); }

  [[nodiscard]] Limbs limbs() const {
    const auto bits = static_cast<UInt128>(sum_);
    Limbs out{};
    for (int k = 0; k < 4; ++k)
      out[static_cast<std::size_t>(k)] = static_cast<std::int64_t>((bits >> (32 * k)) & 0xffffffffu);
    return out;
  }
  static ExactSum from_limbs(const Limbs& limbs) {
    UInt128 bits = 0;
    for (int k = 3; k >= 0; --k) {
      bits = (bits << 32) + static_cast<UInt128>(static_cast<Int128>(limbs[static_cast<std::size_t>(k)]));
    }
    ExactSum sum;
    sum.sum_ = static_cast<Int128>(bits);
    return sum;
  }

 private:
  Int128 sum_ = 0;
};

}  // namespace sabo::sph
