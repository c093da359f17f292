// Periodic boundaries (sph_model.hpp; docs/physics.md, "Periodic boundaries"): particles
// wrapped back into the span, the image slots near the seams, and the wall images' state.
#include <cmath>
#include <cstdint>
#include <vector>

#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

// Puts every active particle back into the periodic span: x -= period past max, += below min.
void SphModel::wrap_positions() {
  for (const PeriodicAxis& periodic : periodic_) {
    const int a = periodic.axis;
    const double period = periodic.max - periodic.min;
    for (std::size_t i = 0; i < position_.size(); ++i) {
      if (!active_[i]) continue;
      double& x = position_[i][a];
      if (x >= periodic.min && x < periodic.max) continue;
      const double shift = -period * std::floor((x - periodic.min) / period);
      x += shift;
      if (x >= periodic.max) x = periodic.min;  // rounding of x + period just below min
      wrap_offset_[i][a] += shift;
    }
  }
}

// The image slots of this step: every active fluid particle and every wall particle within
// one support (plus a margin for the float positions) of a seam, shifted by the period
// towards the other side (both shifts at a corner of x and y). Serial: fixed order.
void SphModel::make_images() {
  f_image_source_.clear();
  b_image_source_.clear();
  if (periodic_.empty()) return;
  const double reach = kernel_.support() * (1.0 + 1e-3);
  const auto add_images = [&](const Vec3& p, std::uint32_t id, std::vector<Vec3>& out,
                              std::vector<std::uint32_t>& source) {
    Vec3 shifts[2] = {Vec3::Zero(), Vec3::Zero()};
    int count[2] = {1, 1};
    for (std::size_t k = 0; k < periodic_.size(); ++k) {
      const PeriodicAxis& periodic = periodic_[k];
      const double period = periodic.max - periodic.min;
      const double x = p[periodic.axis];
      if (x < periodic.min + reach) {
        shifts[k][periodic.axis] = period;
        count[k] = 2;
      } else if (x >= periodic.max - reach) {
        shifts[k][periodic.axis] = -period;
        count[k] = 2;
      }
    }
    for (int a = 0; a < count[0]; ++a) {
      for (int b = 0; b < count[1]; ++b) {
        if (a == 0 && b == 0) continue;
        out.push_back(p + static_cast<double>(a) * shifts[0] + static_cast<double>(b) * shifts[1]);
        source.push_back(id);
      }
    }
  };
  f_sort_position_.assign(position_.begin(), position_.end());
  for (std::size_t i = 0; i < position_.size(); ++i) {
    if (active_[i]) add_images(position_[i], static_cast<std::uint32_t>(i), f_sort_position_, f_image_source_);
  }
  b_sort_position_.assign(boundary_.position.begin(), boundary_.position.end());
  for (std::size_t b = 0; b < boundary_.size(); ++b) {
    add_images(boundary_.position[b], static_cast<std::uint32_t>(b), b_sort_position_, b_image_source_);
  }
}

// A wall image carries its source's state from boundary_state() and extrapolate_wall_stress().
void SphModel::copy_wall_image_state() {
  const std::size_t walls = boundary_.size();
  const std::size_t b_stride = b_order_.size() + kLanes;
  for (std::size_t s = 0; s < b_order_.size(); ++s) {
    const std::uint32_t slot_id = b_order_[s];
    if (slot_id < walls) continue;
    const std::uint32_t source = b_slot_of_[wall_source(slot_id)];
    bpr_[s] = bpr_[source];
    brho_[s] = brho_[source];
    bvol_[s] = bvol_[source];
    if (any_gradient_) {
      bvx_[s] = bvx_[source];
      bvy_[s] = bvy_[source];
      bvz_[s] = bvz_[source];
    }
    if (has_stress_) {
      for (std::size_t q = 0; q < 6; ++q) bstress_[q * b_stride + s] = bstress_[q * b_stride + source];
    }
  }
}

}  // namespace sabo::sph
