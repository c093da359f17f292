// The model on several ranks (sph_model.hpp, "Ranks"): the global grid and the slabs, the
// particles of each rank's window from their owners, which sorted slots a rank computes, the
// halo exchanges of per-slot results, and the reductions over ranks.
#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <type_traits>
#include <vector>

#include "libsabo/core/error.hpp"
#include "sph_solver/passes/neighbours.hpp"
#include "sph_solver/sph_model.hpp"

namespace sabo::sph {
namespace {

// A particle's record between ranks: id, active flag, position, velocity, density, pressure,
// its fluid neighbours (0 before the first compute), then (where the model keeps them) 6 stress
// components, the wall work it holds back and its periodic wrap offset.
constexpr std::size_t kRecordCore = 11;

}  // namespace

std::size_t SphModel::record_size() const {
  return kRecordCore + (has_stress_ ? 6 : 0) + (wall_work_held_.empty() ? 0 : 1) + (wrap_offset_.empty() ? 0 : 3);
}

void SphModel::append_record(std::size_t i, std::vector<double>& out) const {
  out.insert(out.end(), {double(i), double(active_[i]), position_[i].x(), position_[i].y(), position_[i].z(),
                         velocity_[i].x(), velocity_[i].y(), velocity_[i].z(), density_[i], pressure_[i],
                         support_neighbours_.empty() ? 0.0 : double(support_neighbours_[i])});
  if (has_stress_) out.insert(out.end(), &stress_[6 * i], &stress_[6 * i] + 6);
  if (!wall_work_held_.empty()) out.push_back(double(wall_work_held_[i]));
  if (!wrap_offset_.empty()) out.insert(out.end(), {wrap_offset_[i].x(), wrap_offset_[i].y(), wrap_offset_[i].z()});
}

SphModel::Record SphModel::read_record(const double* r) const {
  const double* wrap = r + kRecordCore + (has_stress_ ? 6 : 0) + (wall_work_held_.empty() ? 0 : 1);
  return {static_cast<std::size_t>(r[0]),
          static_cast<std::uint8_t>(r[1]),
          Vec3(r[2], r[3], r[4]),
          Vec3(r[5], r[6], r[7]),
          r[8],
          r[9],
          static_cast<std::int32_t>(r[10]),
          r + kRecordCore,
          wall_work_held_.empty() ? 0.0f : static_cast<float>(r[kRecordCore + (has_stress_ ? 6 : 0)]),
          wrap_offset_.empty() ? Vec3::Zero() : Vec3(wrap[0], wrap[1], wrap[2])};
}

std::int64_t SphModel::layer_of(const Vec3& point) const {
  const auto layer = static_cast<std::int64_t>((point[slab_axis_] - grid_origin_[slab_axis_]) * inverse_cell_);
  return std::clamp<std::int64_t>(layer, 0, slab_layers() - 1);
}

bool SphModel::in_initial_share(std::size_t i) const {
  if (!decomposed()) return true;
  const auto count = static_cast<std::size_t>(ranks_->size());
  return i * count / position_.size() == static_cast<std::size_t>(ranks_->rank());
}

void SphModel::keep_initial_share() {
  for (std::size_t i = 0; i < position_.size(); ++i) {
    if (!in_initial_share(i)) active_[i] = 0;
  }
}

void SphModel::distribute() {
  const int rank = ranks_->rank();
  const std::size_t n = position_.size();
  // The grid of all ranks: the box around every rank's particles and the walls, and the range
  // of the fluid's materials (min and max; both as minima).
  // With periodic boundaries the images this rank's particles and the walls give (make_images() ran on
  // them): the box one model lays over every particle and image.
  Aabb box = bounds();
  for (const Vec3& p : boundary_.position) box.extend(p);
  for (std::size_t k = n; k < f_sort_position_.size(); ++k) box.extend(f_sort_position_[k]);
  for (std::size_t k = boundary_.size(); k < b_sort_position_.size(); ++k) box.extend(b_sort_position_[k]);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double material_min = kInf, material_max = -kInf;
  for (std::size_t i = 0; i < n; ++i) {
    if (!active_[i]) continue;
    material_min = std::min(material_min, double(material_[i]));
    material_max = std::max(material_max, double(material_[i]));
  }
  double low[8] = {kInf, kInf, kInf, -kInf, -kInf, -kInf, material_min, -material_max};
  if (!box.empty()) {
    for (int a = 0; a < 3; ++a) {
      low[a] = box.min[a];
      low[3 + a] = -box.max[a];
    }
  }
  ranks_->min(low);
  Aabb global;
  if (low[0] <= -low[3]) {
    global.extend(Vec3(low[0], low[1], low[2]));
    global.extend(Vec3(-low[3], -low[4], -low[5]));
  }
  uniform_material_ = low[6] == -low[7] ? static_cast<std::int64_t>(low[6]) : -1;
  set_grid_geometry(global);
  // Slabs along the axis with the most cells (ties: x, then y) that is not periodic (an image then lies in
  // its particle's layer), balanced by the particles per layer.
  const std::int64_t cells[3] = {nx_, ny_, nz_};
  slab_axis_ = -1;
  for (int a = 0; a < 3; ++a) {
    const bool periodic =
        std::any_of(periodic_.begin(), periodic_.end(), [&](const PeriodicAxis& p) { return p.axis == a; });
    if (!periodic && (slab_axis_ < 0 || cells[a] > cells[slab_axis_])) slab_axis_ = a;
  }
  std::vector<std::int64_t> counts(static_cast<std::size_t>(slab_layers()), 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (active_[i]) ++counts[static_cast<std::size_t>(layer_of(position_[i]))];
  }
  ranks_->sum(counts);
  global_particles_ = 0;
  for (std::int64_t c : counts) global_particles_ += c;
  slabs_ = parallel::Slabs(counts, ranks_->size());
  // Every particle this rank owned goes to each rank whose window now holds it; it stays here
  // only if this window holds it too.
  const bool neighbours = !support_neighbours_.empty(), held = !wall_work_held_.empty(), wraps = !wrap_offset_.empty();
  const std::size_t record = record_size();
  std::vector<std::vector<double>> to(static_cast<std::size_t>(ranks_->size()));
  for (std::size_t i = 0; i < n; ++i) {
    if (!active_[i]) continue;
    bool stays = false;
    for (const int q : slabs_.windows_holding(layer_of(position_[i]))) {
      if (q == rank) {
        stays = true;
      } else {
        append_record(i, to[static_cast<std::size_t>(q)]);
      }
    }
    if (!stays) active_[i] = 0;
  }
  for (const std::vector<double>& from : ranks_->all_to_all(to)) {
    assert(from.size() % record == 0);
    for (std::size_t k = 0; k < from.size(); k += record) {
      const Record r = read_record(&from[k]);
      active_[r.id] = r.active;
      position_[r.id] = r.position;
      velocity_[r.id] = r.velocity;
      density_[r.id] = r.density;
      pressure_[r.id] = r.pressure;
      if (neighbours) support_neighbours_[r.id] = r.support_neighbours;
      if (has_stress_) std::copy_n(r.stress, 6, &stress_[6 * r.id]);
      if (held) wall_work_held_[r.id] = r.wall_work_held;
      if (wraps) wrap_offset_[r.id] = r.wrap_offset;
    }
  }
  // The images of this window's particles, in id order as one model makes them: the same slots.
  if (!periodic_.empty()) make_images();
}

void SphModel::mark_slots() {
  const int rank = ranks_->rank(), count = ranks_->size();
  const std::int64_t first = slabs_.first(rank), end = slabs_.first(rank + 1);
  const auto layer_of_cell = [&](std::int64_t c) {
    switch (slab_axis_) {
      case 0: return c % nx_;
      case 1: return (c / nx_) % ny_;
      default: return c / (nx_ * ny_);
    }
  };
  halo_.clear();
  if (rank > 0) halo_.push_back({rank - 1, {}, {}, {}, {}});
  if (rank + 1 < count) halo_.push_back({rank + 1, {}, {}, {}, {}});
  // Cells in grid order, slots in order inside each: both sides of a halo list the slots of
  // the same cells in the same order.
  const auto mark = [&](const std::vector<std::uint32_t>& start, std::vector<std::uint8_t>& mine, bool fluid) {
    mine.assign(start.back(), 0);
    const auto cells = static_cast<std::int64_t>(start.size()) - 1;
    for (std::int64_t c = 0; c < cells; ++c) {
      const std::uint32_t begin = start[static_cast<std::size_t>(c)], stop = start[static_cast<std::size_t>(c) + 1];
      if (begin == stop) continue;
      const std::int64_t layer = layer_of_cell(c);
      const bool own = layer >= first && layer < end;
      for (HaloSide& side : halo_) {
        const bool lower = side.rank < rank;
        const bool send = own && (lower ? layer == first : layer == end - 1);
        const bool receive = lower ? layer == first - 1 : layer == end;
        if (!send && !receive) continue;
        std::vector<std::uint32_t>& list =
            fluid ? (send ? side.fluid_send : side.fluid_receive) : (send ? side.wall_send : side.wall_receive);
        for (std::uint32_t s = begin; s < stop; ++s) list.push_back(s);
      }
      if (own) std::fill(mine.begin() + begin, mine.begin() + stop, std::uint8_t{1});
    }
  };
  mark(f_cell_start_, fmine_, true);
  mark(b_cell_start_, bmine_, false);
  // The halo's particles are read, not integrated: this rank owns the rest until the next step.
  owned_count_ = halo_count_ = 0;
  for (std::size_t s = 0; s < f_order_.size(); ++s) {
    if (f_order_[s] >= position_.size()) continue;  // a periodic image
    if (fmine_[s]) {
      ++owned_count_;
    } else {
      active_[f_order_[s]] = 0;
      ++halo_count_;
    }
  }
}

void SphModel::exchange_halo(std::initializer_list<HaloField> fluid, std::initializer_list<HaloField> wall) {
  std::vector<int> peers;
  std::vector<std::vector<float>> sends;
  const auto pack = [](std::initializer_list<HaloField> fields, const std::vector<std::uint32_t>& slots,
                       std::vector<float>& out) {
    for (const HaloField& field : fields) {
      for (int q = 0; q < field.components; ++q) {
        const float* data = field.data + static_cast<std::size_t>(q) * field.stride;
        for (const std::uint32_t s : slots) out.push_back(data[s]);
      }
    }
  };
  for (const HaloSide& side : halo_) {
    peers.push_back(side.rank);
    sends.emplace_back();
    pack(fluid, side.fluid_send, sends.back());
    pack(wall, side.wall_send, sends.back());
  }
  const std::vector<std::vector<float>> received = ranks_->exchange(peers, sends);
  for (std::size_t k = 0; k < halo_.size(); ++k) {
    const HaloSide& side = halo_[k];
    const std::vector<float>& in = received[k];
    std::size_t expected = 0;
    for (const HaloField& f : fluid) expected += static_cast<std::size_t>(f.components) * side.fluid_receive.size();
    for (const HaloField& f : wall) expected += static_cast<std::size_t>(f.components) * side.wall_receive.size();
    if (in.size() != expected) {
      throw Error(fmt::format(
          "sph_solver: rank {} received {} halo values from rank {}, not the {} fluid and {} wall slots it reads "
          "there; the ranks' grids disagree (an internal error: please report it with the scene)",
          ranks_->rank(), in.size(), side.rank, side.fluid_receive.size(), side.wall_receive.size()));
    }
    std::size_t at = 0;
    const auto unpack = [&](std::initializer_list<HaloField> fields, const std::vector<std::uint32_t>& slots) {
      for (const HaloField& field : fields) {
        for (int q = 0; q < field.components; ++q) {
          float* data = field.data + static_cast<std::size_t>(q) * field.stride;
          for (const std::uint32_t s : slots) data[s] = in[at++];
        }
      }
    };
    unpack(fluid, side.fluid_receive);
    unpack(wall, side.wall_receive);
  }
}

void SphModel::exchange_wall_state() {
  const std::size_t stride = b_order_.size() + kLanes;
  exchange_halo({}, {{bpr_.data(), stride, 1},
                     {brho_.data(), stride, 1},
                     {bvol_.data(), stride, 1},
                     {bvx_.data(), stride, any_gradient_ ? 1 : 0},
                     {bvy_.data(), stride, any_gradient_ ? 1 : 0},
                     {bvz_.data(), stride, any_gradient_ ? 1 : 0},
                     {bstress_.data(), stride, has_stress_ ? 6 : 0},
                     {bcredit_.data(), stride, credits_wall_work() ? 1 : 0}});
}

void SphModel::exchange_viscosities() {
  const std::size_t stride = f_order_.size() + kLanes;
  exchange_halo(
      {{feta_.data(), stride, any_gradient_ ? 1 : 0}, {ftranspose_.data(), stride, ftranspose_.empty() ? 0 : 9}}, {});
}

void SphModel::exchange_velocities() {
  const std::size_t stride = f_order_.size() + kLanes;
  exchange_halo({{fvx_.data(), stride, 1}, {fvy_.data(), stride, 1}, {fvz_.data(), stride, 1}}, {});
}

void SphModel::exchange_wall_credit() {
  exchange_halo({}, {{bcredit_.data(), b_order_.size() + kLanes, 1}});
}

void SphModel::reduce_step_maxima() {
  double maxima[3] = {max_mu_, max_acceleration_, -min_viscous_dt_};
  ranks_->max(maxima);
  max_mu_ = maxima[0];
  max_acceleration_ = maxima[1];
  min_viscous_dt_ = -maxima[2];
  std::int64_t counts[2] = {neighbour_pairs_, static_cast<std::int64_t>(owned_count_)};
  ranks_->sum(counts);
  neighbour_pairs_ = counts[0];
  mean_neighbours_ = counts[1] > 0 ? static_cast<double>(counts[0]) / static_cast<double>(counts[1]) : 0.0;
  // Each wall particle's force (and stress) came from the rank that owns it; the others hold 0.
  ranks_->sum_disjoint({boundary_force_.data()->data(), 3 * boundary_force_.size()});
  if (!boundary_stress_.empty()) ranks_->sum_disjoint(boundary_stress_);
}

SphModel::ParticleState SphModel::gather_state(int root) const {
  const std::size_t n = position_.size();
  const bool held = !wall_work_held_.empty();
  ParticleState state;
  const bool receives = !decomposed() || root < 0 || ranks_->rank() == root;
  if (receives) {
    state.position = position_;
    state.velocity = velocity_;
    state.density = density_;
    state.pressure = pressure_;
    state.stress = stress_;
    state.wall_work_held = wall_work_held_;
    state.support_neighbours = support_neighbours_;
    state.active = active_;
    state.wrap_offset = wrap_offset_;
  }
  if (!decomposed()) return state;
  const bool neighbours = !support_neighbours_.empty(), wraps = !wrap_offset_.empty();
  const std::size_t record = record_size();
  std::vector<double> mine;
  for (std::size_t i = 0; i < n; ++i) {
    if (active_[i]) append_record(i, mine);
  }
  std::vector<std::vector<double>> to(static_cast<std::size_t>(ranks_->size()));
  for (std::size_t q = 0; q < to.size(); ++q) {
    if (root < 0 || static_cast<int>(q) == root) to[q] = mine;
  }
  const std::vector<std::vector<double>> received = ranks_->all_to_all(to);
  if (!receives) return state;
  // The particles out of the simulation are no rank's: they read inactive.
  std::fill(state.active.begin(), state.active.end(), std::uint8_t{0});
  for (const std::vector<double>& from : received) {
    for (std::size_t k = 0; k < from.size(); k += record) {
      const Record r = read_record(&from[k]);
      state.active[r.id] = r.active;
      state.position[r.id] = r.position;
      state.velocity[r.id] = r.velocity;
      state.density[r.id] = r.density;
      state.pressure[r.id] = r.pressure;
      if (neighbours) state.support_neighbours[r.id] = r.support_neighbours;
      if (has_stress_) std::copy_n(r.stress, 6, &state.stress[6 * r.id]);
      if (held) state.wall_work_held[r.id] = r.wall_work_held;
      if (wraps) state.wrap_offset[r.id] = r.wrap_offset;
    }
  }
  return state;
}

void SphModel::collect_state() {
  if (!decomposed()) return;
  ParticleState state = gather_state(0);
  if (ranks_->rank() != 0) return;
  // Only what a rank does not own changes: its own entries are what it sent.
  position_ = std::move(state.position);
  velocity_ = std::move(state.velocity);
  density_ = std::move(state.density);
  pressure_ = std::move(state.pressure);
  stress_ = std::move(state.stress);
  wall_work_held_ = std::move(state.wall_work_held);
  support_neighbours_ = std::move(state.support_neighbours);
  wrap_offset_ = std::move(state.wrap_offset);
  collected_active_ = std::move(state.active);
}

FluidSample SphModel::sample_on_ranks(const Vec3& point, bool kernel_sum_only) const {
  if (!decomposed()) return kernel_sum_only ? FluidSample{kernel_sum_here(point)} : sample_here(point);
  FluidSample here;
  if (slabs_.owner(layer_of(point)) == ranks_->rank()) {
    here = kernel_sum_only ? FluidSample{kernel_sum_here(point)} : sample_here(point);
  }
  double values[6] = {here.kernel_sum,   here.pressure,     here.velocity.x(),
                      here.velocity.y(), here.velocity.z(), here.linear_fit ? 1.0 : 0.0};
  ranks_->sum_disjoint(values);
  return FluidSample{values[0], values[1], Vec3(values[2], values[3], values[4]), values[5] != 0.0};
}

void SphModel::share_loaded_state() {
  if (!decomposed()) return;
  const std::size_t n = position_.size();
  // Rank 0's whole state, as doubles (flags, counts and single-precision values are exact in one).
  std::vector<double> all;
  if (ranks_->rank() == 0) {
    const auto vectors = [&](const std::vector<Vec3>& values) {
      for (const Vec3& v : values) all.insert(all.end(), {v.x(), v.y(), v.z()});
    };
    const auto sized = [&](const auto& values) {
      all.push_back(double(values.size()));
      all.insert(all.end(), values.begin(), values.end());
    };
    vectors(position_);
    vectors(velocity_);
    vectors(wrap_offset_);
    all.insert(all.end(), density_.begin(), density_.end());
    all.insert(all.end(), pressure_.begin(), pressure_.end());
    all.insert(all.end(), active_.begin(), active_.end());
    sized(stress_);
    sized(support_neighbours_);
    sized(wall_work_held_);
    sized(settle_factor_);
    all.push_back(double(boundary_force_.size()));
    vectors(boundary_force_);
    sized(boundary_stress_);
    all.insert(all.end(), {double(lost_), time_, max_mu_, max_acceleration_, min_viscous_dt_, stable_dt_,
                           mean_neighbours_, energies_.kinetic, energies_.potential, energies_.elastic,
                           energies_.wall_held, energies_.inflow, inflow_pending_});
    const std::vector<double> inflows = inflow_values();
    all.insert(all.end(), inflows.begin(), inflows.end());
  }
  ranks_->broadcast(all, 0);
  if (ranks_->rank() != 0) {
    std::size_t at = 0;
    const auto vectors = [&](std::vector<Vec3>& values, std::size_t count) {
      values.resize(count);
      for (Vec3& v : values) {
        v = Vec3(all[at], all[at + 1], all[at + 2]);
        at += 3;
      }
    };
    const auto scalars = [&](auto& values, std::size_t count) {
      using Value = typename std::remove_reference_t<decltype(values)>::value_type;
      values.resize(count);
      for (auto& v : values) v = static_cast<Value>(all[at++]);
    };
    const auto sized = [&](auto& values) { scalars(values, static_cast<std::size_t>(all[at++])); };
    vectors(position_, n);
    vectors(velocity_, n);
    vectors(wrap_offset_, wrap_offset_.size());
    scalars(density_, n);
    scalars(pressure_, n);
    scalars(active_, n);
    sized(stress_);
    sized(support_neighbours_);
    sized(wall_work_held_);
    sized(settle_factor_);
    vectors(boundary_force_, static_cast<std::size_t>(all[at++]));
    sized(boundary_stress_);
    lost_ = static_cast<std::size_t>(all[at++]);
    time_ = all[at++];
    max_mu_ = all[at++];
    max_acceleration_ = all[at++];
    min_viscous_dt_ = all[at++];
    stable_dt_ = all[at++];
    mean_neighbours_ = all[at++];
    energies_ = {all[at], all[at + 1], all[at + 2], all[at + 3], all[at + 4]};
    at += 5;
    inflow_pending_ = all[at++];
    set_inflow_values(std::span<const double>(all).subspan(at, kInflowValues * inflows_.size()));
    forces_ready_ = false;
  } else {
    collected_active_ = active_;
  }
  keep_initial_share();
}

}  // namespace sabo::sph
