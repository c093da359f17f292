#pragma once
// Restart of deformable state (docs/design.md, "The traffic log"): every value of a body that
// evolves from step to step, as flat arrays a checkpoint stores and a body
// built from the same scene restores. What the next compute_internal_forces()
// recomputes (internal forces, element steps) is not in it.
#include <fmt/format.h>

#include <cstdint>
#include <string>
#include <vector>

#include "fem_solver/elements/hex8.hpp"
#include "fem_solver/elements/shell4.hpp"
#include "libsabo/core/error.hpp"

namespace sabo::fem {

struct BodyState {
  std::vector<double> real;             // positions, velocities, element states, energy accounts, stable dt
  std::vector<std::uint8_t> active;     // per element, 1: not eroded
  std::vector<std::uint64_t> counters;  // topology revision, eroded elements
};

// Appends the x, y, z of every vector of `field` (positions, velocities).
inline void append_vectors(BodyState& state, const std::vector<Vec3>& field) {
  for (const Vec3& v : field) {
    for (int d = 0; d < 3; ++d) state.real.push_back(v(d));
  }
}

// Calls f(value) for every double of a material point / element state, in a
// fixed order (the checkpoint layout). Works on const and mutable states.
template <typename Point, typename F>
void for_each_value_of_point(Point& point, F&& f) {
  for (auto* matrix : {&point.stress, &point.back_stress, &point.strain}) {
    for (Eigen::Index k = 0; k < 9; ++k) f(matrix->data()[k]);
  }
  f(point.plastic_strain);
}

template <typename State, typename F>
void for_each_value_of_hex(State& state, F&& f) {
  for_each_value_of_point(state.point, f);
  for (auto& q : state.hourglass) f(q);
  f(state.volume);
  f(state.internal_energy);
  f(state.hourglass_energy);
  f(state.plastic_work);
}

template <typename State, typename F>
void for_each_value_of_shell(State& state, F&& f) {
  for (auto& point : state.point) for_each_value_of_point(point, f);
  f(state.shear_x);
  f(state.shear_y);
  for (auto& q : state.hourglass) f(q);
  f(state.area);
  f(state.internal_energy);
  f(state.hourglass_energy);
  f(state.plastic_work);
}

template <typename Gauss, typename F>
void for_each_value_of_shell_gauss(Gauss& gauss, F&& f) {
  for (auto& points : gauss.point) {
    for (auto& point : points) for_each_value_of_point(point, f);
  }
  for (auto& q : gauss.shear) f(q);
  for (auto& m : gauss.drilling) f(m);
  f(gauss.drilling_energy);
}

// Reads a BodyState back in the order it was written; throws FileError when
// the sizes do not match the body (a checkpoint of another scene or mesh).
class BodyStateReader {
 public:
  BodyStateReader(const BodyState& state, std::string what) : state_(state), what_(std::move(what)) {}
  void expect_sizes(std::size_t reals, std::size_t elements, std::size_t counters) const {
    if (state_.real.size() != reals || state_.active.size() != elements || state_.counters.size() != counters) {
      throw FileError(fmt::format(
          "{}: the checkpoint holds {} values, {} element flags and {} counters, the body needs {}, {} and {}. Fix: "
          "restart from a checkpoint written for this scene (same structures, meshes and element sizes)",
          what_, state_.real.size(), state_.active.size(), state_.counters.size(), reals, elements, counters));
    }
  }
  double next() { return state_.real[position_++]; }
  // Reads back what append_vectors wrote.
  void read_vectors(std::vector<Vec3>& field) {
    for (Vec3& v : field) {
      for (int d = 0; d < 3; ++d) v(d) = next();
    }
  }

 private:
  const BodyState& state_;
  std::string what_;
  std::size_t position_ = 0;
};

}  // namespace sabo::fem
