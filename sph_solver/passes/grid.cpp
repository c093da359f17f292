// The neighbour grid: a counting sort of the fluid and wall particles (and their images) on
// a uniform grid of cell size 2h, x-sorted inside each cell, and the gather of their state
// into the cell-ordered single-precision arrays the pair loops read (sph_model.hpp,
// "Internally the particles are gathered into cell order").
#include <fmt/format.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "libsabo/core/error.hpp"
#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/passes/pair_terms.hpp"
#include "sph_solver/passes/particle_for.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// More cells than this means a domain far larger than the particles need.
constexpr std::int64_t kMaxCells = std::int64_t{1} << 27;
// Padding slots sit this far (m) from everything: outside every support.
constexpr float kFarAway = 1e6f;

// Resizes a cell-ordered array to count + kLanes entries, the padding set to `pad`.
template <class V>
void resize_padded(std::vector<V>& array, std::size_t count, V pad) {
  array.resize(count + kLanes);
  std::fill(array.begin() + static_cast<std::ptrdiff_t>(count), array.end(), pad);
}

}  // namespace

Aabb SphModel::bounds() const {
  Aabb box;
  for (std::size_t i = 0; i < position_.size(); ++i) {
    if (active_[i]) box.extend(position_[i]);
  }
  return box;
}

void SphModel::set_grid_geometry(Aabb box) {
  const double cell = kernel_.support();
  if (box.empty()) box = Aabb{Vec3::Zero(), Vec3::Zero()};
  grid_origin_ = box.min.array() - 0.5 * cell;
  const Vec3 extent = box.max - grid_origin_;
  nx_ = static_cast<std::int64_t>(extent.x() / cell) + 2;
  ny_ = static_cast<std::int64_t>(extent.y() / cell) + 2;
  nz_ = static_cast<std::int64_t>(extent.z() / cell) + 2;
  if (nx_ * ny_ * nz_ > kMaxCells) {
    throw Error(
        fmt::format("sph_solver: the particles span {:.1f} x {:.1f} x {:.1f} m, {} cells of {:.3g} m; "
                    "a particle has probably run away. Fix: give sph.domain_min/domain_max so that particles "
                    "leaving the domain are taken out, or close the walls.",
                    extent.x(), extent.y(), extent.z(), nx_ * ny_ * nz_, cell));
  }
  inverse_cell_ = 1.0 / cell;
}

void SphModel::build_grid() {
  const bool periodic = !periodic_.empty();
  const std::vector<Vec3>& f_position = periodic ? f_sort_position_ : position_;
  const std::vector<Vec3>& b_position = periodic ? b_sort_position_ : boundary_.position;
  const std::size_t particles = position_.size();
  if (!decomposed()) {  // distribute() set the grid of all ranks
    Aabb box = bounds();
    for (const Vec3& p : b_position) box.extend(p);
    for (std::size_t k = particles; k < f_position.size(); ++k) box.extend(f_position[k]);
    set_grid_geometry(box);
  }
  const std::size_t cells = static_cast<std::size_t>(nx_ * ny_ * nz_);
  const double inverse_cell = inverse_cell_;
  const auto cell_of = [&](const Vec3& p) {
    const auto ix = static_cast<std::int64_t>((p.x() - grid_origin_.x()) * inverse_cell);
    const auto iy = static_cast<std::int64_t>((p.y() - grid_origin_.y()) * inverse_cell);
    const auto iz = static_cast<std::int64_t>((p.z() - grid_origin_.z()) * inverse_cell);
    return static_cast<std::size_t>((iz * ny_ + iy) * nx_ + ix);
  };
  // Counting sort by cell, ids ascending inside a cell; the cell is computed twice
  // rather than stored (memory per particle).
  const auto sort = [&](const std::vector<Vec3>& position, auto is_active, std::vector<std::uint32_t>& start,
                        std::vector<std::uint32_t>& order) {
    start.assign(cells + 1, 0);
    std::size_t used = 0;
    for (std::size_t i = 0; i < position.size(); ++i) {
      if (!is_active(i)) continue;
      ++start[cell_of(position[i]) + 1];
      ++used;
    }
    for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
    order.resize(used);
    cell_next_.assign(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < position.size(); ++i) {
      if (!is_active(i)) continue;
      order[cell_next_[cell_of(position[i])]++] = static_cast<std::uint32_t>(i);
    }
  };
  // Then by x inside each cell (ties by id): every row of cells is x-sorted.
  const auto sort_by_x = [&](const std::vector<Vec3>& position, const std::vector<std::uint32_t>& start,
                             std::vector<std::uint32_t>& order, std::size_t images) {
    const bool parallel = in_parallel(order.size() - images);
    particle_for<Compile::baseline>(cells, parallel, [&](std::int64_t first, std::int64_t last) {
      for (std::int64_t c = first; c < last; ++c) {
        const auto begin = order.begin() + start[static_cast<std::size_t>(c)];
        const auto end = order.begin() + start[static_cast<std::size_t>(c) + 1];
        if (end - begin < 2) continue;
        std::sort(begin, end, [&](std::uint32_t a, std::uint32_t b) {
          const double xa = position[a].x(), xb = position[b].x();
          return xa < xb || (xa == xb && a < b);
        });
      }
    });
  };
  sort(
      f_position, [&](std::size_t i) { return i >= particles || active_[i] != 0; }, f_cell_start_, f_order_);
  sort_by_x(f_position, f_cell_start_, f_order_, f_image_source_.size());
  // Decomposed: the wall particles of this rank's window only.
  sort(
      b_position,
      [&](std::size_t b) { return !decomposed() || slabs_.in_window(ranks_->rank(), layer_of(b_position[b])); },
      b_cell_start_, b_order_);
  sort_by_x(b_position, b_cell_start_, b_order_, b_image_source_.size());
  if (periodic) {
    f_slot_of_.resize(particles);
    for (std::size_t s = 0; s < f_order_.size(); ++s) {
      if (f_order_[s] < particles) f_slot_of_[f_order_[s]] = static_cast<std::uint32_t>(s);
    }
    b_slot_of_.resize(boundary_.size());
    for (std::size_t s = 0; s < b_order_.size(); ++s) {
      if (b_order_[s] < boundary_.size()) b_slot_of_[b_order_[s]] = static_cast<std::uint32_t>(s);
    }
  }
}

void SphModel::gather() {
  const std::size_t n = f_order_.size();
  const std::size_t particles = position_.size(), walls = boundary_.size();
  const Vec3 origin = grid_origin_;
  resize_padded(fx_, n, kFarAway);
  resize_padded(fy_, n, kFarAway);
  resize_padded(fz_, n, kFarAway);
  for (auto* v : {&fvx_, &fvy_, &fvz_, &fpr_}) resize_padded(*v, n, 0.0f);
  resize_padded(fm_, n, 0.0);
  resize_padded(ffull_, n, 0.0f);
  resize_padded(frho_, n, 1.0f);
  resize_padded(fmat_, n, std::uint32_t{0});
  if (any_gradient_) resize_padded(feta_, n, 0.0f);
  if (has_stress_) fstress_.assign(6 * (n + kLanes), 0.0f);                 // component-major, stride n + kLanes
  if (any_artificial_stress_) fartificial_.assign(6 * (n + kLanes), 0.0f);  // like fstress_
  out_drho_.resize(n);
  const bool parallel = in_parallel(n - f_image_source_.size());
  particle_for<Compile::baseline>(n, parallel, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t k = first; k < last; ++k) {
      const auto s = static_cast<std::size_t>(k);
      const std::uint32_t slot_id = f_order_[s];
      // An image slot: its own position, its source's state.
      const bool image = slot_id >= particles;
      const std::uint32_t i = fluid_source(slot_id);
      const Vec3& position = image ? f_sort_position_[slot_id] : position_[i];
      fx_[s] = static_cast<float>(position.x() - origin.x());
      fy_[s] = static_cast<float>(position.y() - origin.y());
      fz_[s] = static_cast<float>(position.z() - origin.z());
      fvx_[s] = static_cast<float>(velocity_[i].x());
      fvy_[s] = static_cast<float>(velocity_[i].y());
      fvz_[s] = static_cast<float>(velocity_[i].z());
      frho_[s] = static_cast<float>(density_[i]);
      // p(rho_n): set by the fill and by integrate().
      fpr_[s] = static_cast<float>(pressure_[i] / (density_[i] * density_[i]));
      fm_[s] = mass_[i];
      ffull_[s] = support_neighbours_.empty() || support_neighbours_[i] >= full_support_neighbours_ ||
                          materials_[material_[i]].rheology == Rheology::elastic_plastic
                      ? 1.0f
                      : 0.0f;
      fmat_[s] = material_[i];
      if (any_gradient_) feta_[s] = 0;
      if (has_stress_) {
        for (std::size_t q = 0; q < 6; ++q) fstress_[q * (n + kLanes) + s] = static_cast<float>(stress_[6 * i + q]);
      }
      if (any_artificial_stress_) {
        const double epsilon = materials_[material_[i]].artificial_stress;
        if (epsilon > 0) {
          double r[6];
          artificial_stress(&stress_[6 * i], pressure_[i], density_[i], epsilon, r);
          for (std::size_t q = 0; q < 6; ++q) fartificial_[q * (n + kLanes) + s] = static_cast<float>(r[q]);
        }
      }
    }
  });
  const std::size_t nb = b_order_.size();
  resize_padded(bx_, nb, kFarAway);
  resize_padded(by_, nb, kFarAway);
  resize_padded(bz_, nb, kFarAway);
  for (auto* v : {&bwx_, &bwy_, &bwz_, &bvol_, &bpr_}) resize_padded(*v, nb, 0.0f);
  for (auto* v : {&bsx_, &bsy_, &bsz_}) {
    if (any_free_slip_) {
      resize_padded(*v, nb, 0.0f);
    } else {
      std::vector<float>().swap(*v);
    }
  }
  if (credits_wall_work()) resize_padded(bcredit_, nb, 0.0f);
  resize_padded(brho_, nb, 1.0f);
  if (has_stress_) bstress_.assign(6 * (nb + kLanes), 0.0f);  // component-major, stride nb + kLanes
  if (any_gradient_) {
    for (auto* v : {&bvx_, &bvy_, &bvz_}) resize_padded(*v, nb, 0.0f);
  }
  for (std::size_t s = 0; s < nb; ++s) {
    const std::uint32_t slot_id = b_order_[s];
    const bool image = slot_id >= walls;
    const std::uint32_t b = wall_source(slot_id);
    const Vec3& position = image ? b_sort_position_[slot_id] : boundary_.position[b];
    bx_[s] = static_cast<float>(position.x() - origin.x());
    by_[s] = static_cast<float>(position.y() - origin.y());
    bz_[s] = static_cast<float>(position.z() - origin.z());
    const Vec3 wall_velocity = boundary_.velocity_of(b);
    bwx_[s] = static_cast<float>(wall_velocity.x());
    bwy_[s] = static_cast<float>(wall_velocity.y());
    bwz_[s] = static_cast<float>(wall_velocity.z());
    bvol_[s] = static_cast<float>(boundary_.volume[b]);
    if (any_free_slip_) {
      const Vec3 slip_normal = boundary_.free_slip[b] != 0 ? boundary_.normal[b] : Vec3::Zero();
      bsx_[s] = static_cast<float>(slip_normal.x());
      bsy_[s] = static_cast<float>(slip_normal.y());
      bsz_[s] = static_cast<float>(slip_normal.z());
    }
  }
  if (!periodic_.empty()) {
    fm_wall_.assign(fm_.begin(), fm_.end());
    for (std::size_t s = 0; s < n; ++s) {
      if (f_order_[s] >= particles) fm_wall_[s] = 0.0;
    }
  }
}

}  // namespace sabo::sph
