#include "sph_solver/sph_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "libsabo/core/error.hpp"

namespace sabo::sph {
namespace {

using Rheology = scene::Material::Rheology;

// Above this many particles the loops run in parallel.
constexpr std::size_t kParallelThreshold = 512;
// More cells than this means a domain far larger than the particles need.
constexpr std::int64_t kMaxCells = std::int64_t{1} << 27;

// Adds S . (f r) to a, S symmetric 3x3 stored as xx yy zz xy yz zx.
inline void add_stress_dot(const double* s, double f, double rx, double ry, double rz, double& ax, double& ay,
                           double& az) {
  const double gx = f * rx, gy = f * ry, gz = f * rz;
  ax += s[0] * gx + s[3] * gy + s[5] * gz;
  ay += s[3] * gx + s[1] * gy + s[4] * gz;
  az += s[5] * gx + s[4] * gy + s[2] * gz;
}

// Stress term of a fluid particle (stress s_i, density rho_i) and a wall particle
// (mass m_wall, density rho_wall, stress s_wall extrapolated in compute_boundary_state).
inline void add_wall_stress(const double* s_i, const double* s_wall, double m_wall, double rho_i, double rho_wall,
                            double f, double rx, double ry, double rz, double& ax, double& ay, double& az) {
  double sum[6];
  for (int q = 0; q < 6; ++q) sum[q] = m_wall * (s_i[q] / (rho_i * rho_i) + s_wall[q] / (rho_wall * rho_wall));
  add_stress_dot(sum, f, rx, ry, rz, ax, ay, az);
}

// Adds to s (xx yy zz xy yz zx) the deviatoric stress that the shear traction grows by
// over the distance d_n (m) along the wall normal n: t n + n t, t = rho (a_w - g)
// less its part along n, times d_n (the tangential momentum balance next to a wall,
// d(S.n)/dn = rho (a - g) along the wall; its normal part is the pressure's, eq. 27).
inline void add_wall_shear(double rho, const Vec3& a_minus_g, const Vec3& n, double d_n, double* s) {
  const Vec3 t = rho * d_n * (a_minus_g - a_minus_g.dot(n) * n);
  s[0] += 2.0 * t.x() * n.x();
  s[1] += 2.0 * t.y() * n.y();
  s[2] += 2.0 * t.z() * n.z();
  s[3] += t.x() * n.y() + n.x() * t.y();
  s[4] += t.y() * n.z() + n.y() * t.z();
  s[5] += t.z() * n.x() + n.z() * t.x();
}

// Density difference that delta-SPH diffuses between fluid particles i and j (Fourtakas et
// al. 2019, in its dynamic-pressure form): the pressure difference less the hydrostatic
// one, (p_j - p_i - rho_mean g.(x_j - x_i)) / c^2. It vanishes in a fluid at rest for any
// EOS; the density difference less rho0 g.(x_j - x_i) / c^2 does not: Tait stiffens by
// (rho/rho0)^(gamma-1), 6 % at rho = 1.01 rho0. r = x_i - x_j.
inline double dynamic_density_difference(double p_i, double p_j, double rho_i, double rho_j, double gx, double gy,
                                         double gz, double rx, double ry, double rz, double inverse_c2) {
  const double hydrostatic = -0.5 * (rho_i + rho_j) * (gx * rx + gy * ry + gz * rz);
  return (p_j - p_i - hydrostatic) * inverse_c2;
}

}  // namespace

double FluidMaterial::max_viscosity() const {
  switch (rheology) {
    case Rheology::inviscid: return 0;
    case Rheology::newtonian: return viscosity;
    case Rheology::bingham: return viscosity + yield_stress / yield_shear_rate;
    case Rheology::elastic_plastic: return viscosity;
  }
  return 0;
}

SphModel::SphModel(const scene::Scene& scene)
    : settings_(scene.sph),
      kernel_(scene.sph.kernel, scene.sph.smoothing_length()),
      gravity_(scene.run.gravity),
      sound_speed_(scene.sph.sound_speed) {
  eta_squared_ = 0.01 * kernel_.h * kernel_.h;
  // Materials used by fluids, in scene material order (index = material id).
  std::vector<std::uint32_t> body_material;
  materials_.resize(scene.materials.size());
  for (std::size_t m = 0; m < scene.materials.size(); ++m) {
    const scene::Material& source = scene.materials[m];
    FluidMaterial& material = materials_[m];
    material.eos = EquationOfState(source, sound_speed_);
    material.rheology = source.rheology;
    material.viscosity = source.viscosity;
    material.yield_stress = source.yield_stress.value_or(0.0);
    material.yield_shear_rate = source.yield_shear_rate;
    material.shear_modulus = source.fluid_shear_modulus > 0 ? source.fluid_shear_modulus : source.shear_modulus();
    if (material.rheology == Rheology::elastic_plastic) {
      // Elastic waves: c_eff^2 = c^2 + 4 G / (3 rho0).
      const double c_eff =
          std::sqrt(sound_speed_ * sound_speed_ + 4.0 * material.shear_modulus / (3.0 * material.eos.rest_density));
      elastic_wave_dt_ = std::min(elastic_wave_dt_, kernel_.h / c_eff);
    }
  }
  for (const auto& body : scene.fluids) {
    const auto m = static_cast<std::uint32_t>(scene.material_index(body.material));
    body_material.push_back(m);
    any_gradient_ = any_gradient_ || materials_[m].needs_velocity_gradient();
    has_stress_ = has_stress_ || materials_[m].rheology == Rheology::elastic_plastic;
  }
  FluidFill fill = fill_fluids(scene, materials_, body_material);
  position_ = std::move(fill.position);
  velocity_ = std::move(fill.velocity);
  density_ = std::move(fill.density);
  pressure_ = std::move(fill.pressure);
  mass_ = std::move(fill.mass);
  material_ = std::move(fill.material);
  body_ = std::move(fill.body);
  const std::size_t n = position_.size();
  acceleration_.assign(n, Vec3::Zero());
  external_force_.assign(n, Vec3::Zero());
  density_rate_.assign(n, 0.0);
  stress_ = std::move(fill.stress);
  stress_rate_.assign(6 * n, 0.0);
  active_.assign(n, 1);
  particle_kinetic_.assign(n, 0.0);
  particle_potential_.assign(n, 0.0);
  particle_elastic_.assign(n, 0.0);
  stable_dt_ = initial_stable_dt();
  energies_.kinetic = 0;
  for (std::size_t i = 0; i < n; ++i) {
    energies_.kinetic += 0.5 * mass_[i] * velocity_[i].squaredNorm();
    energies_.potential -= mass_[i] * gravity_.dot(position_[i]);
    energies_.elastic += mass_[i] * materials_[material_[i]].eos.specific_energy(density_[i]);
  }
}

double SphModel::initial_stable_dt() const {
  const double h = kernel_.h;
  double dt = h / sound_speed_;
  const double g = gravity_.norm();
  if (g > 0) dt = std::min(dt, std::sqrt(h / g));
  double max_speed = 0;
  for (const Vec3& v : velocity_) max_speed = std::max(max_speed, v.norm());
  dt = std::min(dt, h / (sound_speed_ + max_speed));
  for (std::size_t m = 0; m < materials_.size(); ++m) {
    const double eta = materials_[m].max_viscosity();
    if (eta > 0 && std::find(material_.begin(), material_.end(), m) != material_.end()) {
      dt = std::min(dt, materials_[m].eos.rest_density * h * h / (8.0 * eta));
    }
  }
  return settings_.cfl * dt;
}

void SphModel::set_boundary(const physics::BoundaryParticles& boundary) {
  const std::size_t n = boundary.size();
  if (boundary.velocity.size() != n || boundary.normal.size() != n || boundary.acceleration.size() != n ||
      boundary.volume.size() != n) {
    throw ProtocolError(fmt::format(
        "boundary particles: {} positions but {} velocities, {} normals, {} "
        "accelerations, {} volumes; every array needs one entry per particle",
        n, boundary.velocity.size(), boundary.normal.size(), boundary.acceleration.size(), boundary.volume.size()));
  }
  boundary_ = boundary;
}

Aabb SphModel::bounds() const {
  Aabb box;
  for (std::size_t i = 0; i < position_.size(); ++i) {
    if (active_[i]) box.extend(position_[i]);
  }
  return box;
}

void SphModel::build_grid() {
  const double cell = kernel_.support();
  Aabb box = bounds();
  for (const Vec3& p : boundary_.position) box.extend(p);
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
  const std::size_t cells = static_cast<std::size_t>(nx_ * ny_ * nz_);
  const double inverse_cell = 1.0 / cell;
  inverse_cell_ = inverse_cell;
  const auto cell_of = [&](const Vec3& p) {
    const auto ix = static_cast<std::int64_t>((p.x() - grid_origin_.x()) * inverse_cell);
    const auto iy = static_cast<std::int64_t>((p.y() - grid_origin_.y()) * inverse_cell);
    const auto iz = static_cast<std::int64_t>((p.z() - grid_origin_.z()) * inverse_cell);
    return static_cast<std::uint32_t>((iz * ny_ + iy) * nx_ + ix);
  };
  const auto sort = [&](std::size_t count, auto position_of, auto is_active, std::vector<std::uint32_t>& cell_id,
                        std::vector<std::uint32_t>& start, std::vector<std::uint32_t>& order) {
    cell_id.resize(count);
    start.assign(cells + 1, 0);
    std::size_t used = 0;
    for (std::size_t i = 0; i < count; ++i) {
      if (!is_active(i)) {
        cell_id[i] = std::numeric_limits<std::uint32_t>::max();
        continue;
      }
      cell_id[i] = cell_of(position_of(i));
      ++start[cell_id[i] + 1];
      ++used;
    }
    for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
    order.resize(used);
    cell_next_.assign(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < count; ++i) {
      if (cell_id[i] == std::numeric_limits<std::uint32_t>::max()) continue;
      order[cell_next_[cell_id[i]]++] = static_cast<std::uint32_t>(i);
    }
  };
  sort(
      position_.size(), [&](std::size_t i) -> const Vec3& { return position_[i]; },
      [&](std::size_t i) { return active_[i] != 0; }, f_cell_of_, f_cell_start_, f_order_);
  sort(
      boundary_.size(), [&](std::size_t i) -> const Vec3& { return boundary_.position[i]; },
      [](std::size_t) { return true; }, b_cell_of_, b_cell_start_, b_order_);
}

void SphModel::gather() {
  const std::size_t n = f_order_.size();
  for (auto* v : {&fx_, &fy_, &fz_, &fvx_, &fvy_, &fvz_, &frho_, &fp_, &fm_, &feta_, &out_ax_, &out_ay_, &out_az_,
                  &out_drho_, &out_dtcv_, &out_neigh_}) {
    v->resize(n);
  }
  fmat_.resize(n);
  fstress_.assign(has_stress_ ? 6 * n : 0, 0.0);
  for (std::size_t s = 0; s < n; ++s) {
    const std::uint32_t i = f_order_[s];
    fx_[s] = position_[i].x();
    fy_[s] = position_[i].y();
    fz_[s] = position_[i].z();
    fvx_[s] = velocity_[i].x();
    fvy_[s] = velocity_[i].y();
    fvz_[s] = velocity_[i].z();
    frho_[s] = density_[i];
    fp_[s] = pressure_[i];  // p(rho_n): set by the fill and by integrate()
    fm_[s] = mass_[i];
    fmat_[s] = material_[i];
    feta_[s] = 0;
    if (has_stress_) std::copy_n(&stress_[6 * i], 6, &fstress_[6 * s]);
  }
  const std::size_t nb = b_order_.size();
  bstress_.assign(has_stress_ ? 6 * nb : 0, 0.0);
  for (auto* v : {&bx_, &by_, &bz_, &bvx_, &bvy_, &bvz_, &bvol_, &bp_, &brho_, &bwx_, &bwy_, &bwz_, &out_bfx_,
                  &out_bfy_, &out_bfz_}) {
    v->resize(nb);
  }
  for (std::size_t s = 0; s < nb; ++s) {
    const std::uint32_t b = b_order_[s];
    bx_[s] = boundary_.position[b].x();
    by_[s] = boundary_.position[b].y();
    bz_[s] = boundary_.position[b].z();
    bwx_[s] = boundary_.velocity[b].x();
    bwy_[s] = boundary_.velocity[b].y();
    bwz_[s] = boundary_.velocity[b].z();
    bvol_[s] = boundary_.volume[b];
  }
}

void SphModel::compute_boundary_state() {
  const std::size_t nb = b_order_.size();
  const double support2 = kernel_.support() * kernel_.support();
  const auto count = static_cast<std::int64_t>(nb);
  boundary_pressure_.assign(boundary_.size(), 0.0);
#pragma omp parallel for schedule(static) if (nb > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto s = static_cast<std::size_t>(k);
    const std::uint32_t id = b_order_[s];
    const Vec3 g_minus_a = gravity_ - boundary_.acceleration[id];
    double sum_w = 0, sum_pw = 0, sum_rho_r_g = 0, svx = 0, svy = 0, svz = 0, best_w = -1;
    std::uint32_t material = fmat_.empty() ? 0 : fmat_[0];
    const double x = bx_[s], y = by_[s], z = bz_[s];
    for_neighbours(x, y, z, f_cell_start_, [&](std::uint32_t j) {
      const double rx = x - fx_[j], ry = y - fy_[j], rz = z - fz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 < support2) {
        const double w = kernel_.value(std::sqrt(r2));
        sum_w += w;
        sum_pw += fp_[j] * w;
        sum_rho_r_g += frho_[j] * w * (g_minus_a.x() * rx + g_minus_a.y() * ry + g_minus_a.z() * rz);
        svx += fvx_[j] * w;
        svy += fvy_[j] * w;
        svz += fvz_[j] * w;
        if (w > best_w) {
          best_w = w;
          material = fmat_[j];
        }
      }
    });
    const EquationOfState& eos = materials_.empty() ? EquationOfState() : materials_[material].eos;
    if (has_stress_) {
      // Elastic-plastic fluids: the wall carries the fluid's deviatoric stress extrapolated
      // like the pressure, S_w = sum_f (S_f + shear growth over (x_w - x_f).n) W / sum W.
      // With S_w = S_f (no growth) the bed takes too little shear: in the S8 set-up the bottom
      // row slid at 0.05 m/s at 0.8 tau_y (0.03 m/s with the growth).
      double* s_w = &bstress_[6 * s];
      std::fill_n(s_w, 6, 0.0);
      if (sum_w > 0) {
        const Vec3& n = boundary_.normal[id];
        for_neighbours(x, y, z, f_cell_start_, [&](std::uint32_t j) {
          const double rx = x - fx_[j], ry = y - fy_[j], rz = z - fz_[j];
          const double r2 = rx * rx + ry * ry + rz * rz;
          if (r2 >= support2) return;
          const double w = kernel_.value(std::sqrt(r2));
          double s_f[6];
          std::copy_n(&fstress_[6 * j], 6, s_f);
          add_wall_shear(frho_[j], -g_minus_a, n, rx * n.x() + ry * n.y() + rz * n.z(), s_f);
          for (int q = 0; q < 6; ++q) s_w[q] += s_f[q] * w / sum_w;
        });
      }
    }
    if (sum_w > 0) {
      // Adami et al. 2012 eq. 27; negative wall pressure would glue the fluid to the wall.
      const double p = std::max(0.0, (sum_pw + sum_rho_r_g) / sum_w);
      bp_[s] = p;
      brho_[s] = eos.density(p);
      // No-slip wall velocity for the viscous terms: 2 v_w - v_extrapolated (Adami eq. 22).
      bvx_[s] = 2.0 * bwx_[s] - svx / sum_w;
      bvy_[s] = 2.0 * bwy_[s] - svy / sum_w;
      bvz_[s] = 2.0 * bwz_[s] - svz / sum_w;
    } else {
      bp_[s] = 0;
      brho_[s] = eos.rest_density;
      bvx_[s] = bwx_[s];
      bvy_[s] = bwy_[s];
      bvz_[s] = bwz_[s];
    }
    boundary_pressure_[id] = bp_[s];
  }
}

void SphModel::compute_velocity_gradients() {
  const std::size_t n = f_order_.size();
  fgrad_.assign(9 * n, 0.0);
  if (!any_gradient_) return;
  const double support2 = kernel_.support() * kernel_.support();
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (n > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const FluidMaterial& material = materials_[fmat_[i]];
    if (!material.needs_velocity_gradient()) continue;
    const double x = fx_[i], y = fy_[i], z = fz_[i];
    double L[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    const auto add = [&](double rx, double ry, double rz, double r2, double dvx, double dvy, double dvz,
                         double volume) {
      const double f = kernel_.gradient_factor(std::sqrt(r2)) * volume;
      const double g[3] = {f * rx, f * ry, f * rz};
      const double dv[3] = {dvx, dvy, dvz};
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) L[3 * a + b] += dv[a] * g[b];
      }
    };
    for_neighbours(x, y, z, f_cell_start_, [&](std::uint32_t j) {
      if (j == i) return;
      const double rx = x - fx_[j], ry = y - fy_[j], rz = z - fz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 < support2)
        add(rx, ry, rz, r2, fvx_[j] - fvx_[i], fvy_[j] - fvy_[i], fvz_[j] - fvz_[i], fm_[j] / frho_[j]);
    });
    for_neighbours(x, y, z, b_cell_start_, [&](std::uint32_t j) {
      const double rx = x - bx_[j], ry = y - by_[j], rz = z - bz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 < support2) add(rx, ry, rz, r2, bvx_[j] - fvx_[i], bvy_[j] - fvy_[i], bvz_[j] - fvz_[i], bvol_[j]);
    });
    std::copy_n(L, 9, &fgrad_[9 * i]);
    // Strain rate D = (L + L^T)/2; shear rate sqrt(2 D':D').
    double d[6] = {L[0], L[4], L[8], 0.5 * (L[1] + L[3]), 0.5 * (L[5] + L[7]), 0.5 * (L[6] + L[2])};
    const double trace = (d[0] + d[1] + d[2]) / 3.0;
    d[0] -= trace;
    d[1] -= trace;
    d[2] -= trace;
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * (d[3] * d[3] + d[4] * d[4] + d[5] * d[5]);
    const double shear_rate = std::sqrt(2.0 * dd);
    switch (material.rheology) {
      case Rheology::newtonian: feta_[i] = material.viscosity; break;
      case Rheology::bingham: {
        // Papanastasiou: eta = mu_p + tau_y (1 - exp(-gamma_dot / gamma_0)) / gamma_dot, limit mu_p + tau_y / gamma_0.
        const double x_rate = shear_rate / material.yield_shear_rate;
        const double factor = x_rate > 1e-8 ? -std::expm1(-x_rate) / shear_rate : 1.0 / material.yield_shear_rate;
        feta_[i] = material.viscosity + material.yield_stress * factor;
        break;
      }
      case Rheology::elastic_plastic: feta_[i] = material.viscosity; break;
      case Rheology::inviscid: break;
    }
  }
}

void SphModel::compute_fluid_forces() {
  const std::size_t n = f_order_.size();
  const double support2 = kernel_.support() * kernel_.support();
  const double h = kernel_.h, c = sound_speed_, eta2 = eta_squared_;
  const double alpha_hc = settings_.artificial_viscosity * h * c;
  const bool diffusion = settings_.density_diffusion != scene::SphSettings::DensityDiffusion::none;
  const bool hydrostatic_diffusion = settings_.density_diffusion == scene::SphSettings::DensityDiffusion::fourtakas;
  const double diffusion_scale = 2.0 * settings_.density_diffusion_delta * h * c;
  const double gx = gravity_.x(), gy = gravity_.y(), gz = gravity_.z();
  const double inverse_c2 = 1.0 / (c * c);
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (n > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double x = fx_[i], y = fy_[i], z = fz_[i];
    const double vx = fvx_[i], vy = fvy_[i], vz = fvz_[i];
    const double rho_i = frho_[i], p_i = fp_[i];
    const double p_over_rho2_i = p_i / (rho_i * rho_i);
    const double eta_i = feta_[i];
    const double* s_i = has_stress_ ? &fstress_[6 * i] : nullptr;
    double ax = 0, ay = 0, az = 0, diffuse = 0, max_mu = 0, neighbours = 0;
    for_neighbours(x, y, z, f_cell_start_, [&](std::uint32_t j) {
      if (j == i) return;
      const double rx = x - fx_[j], ry = y - fy_[j], rz = z - fz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 >= support2) return;
      neighbours += 1;
      const double f = kernel_.gradient_factor(std::sqrt(r2));
      const double m_j = fm_[j], rho_j = frho_[j];
      const double dvx = vx - fvx_[j], dvy = vy - fvy_[j], dvz = vz - fvz_[j];
      const double vr = dvx * rx + dvy * ry + dvz * rz;
      const double mu = h * vr / (r2 + eta2);
      max_mu = std::max(max_mu, std::abs(mu));
      double scalar = -m_j * (p_over_rho2_i + fp_[j] / (rho_j * rho_j));
      if (vr < 0) scalar += m_j * alpha_hc * vr / ((r2 + eta2) * 0.5 * (rho_i + rho_j));
      ax += scalar * f * rx;
      ay += scalar * f * ry;
      az += scalar * f * rz;
      const double eta_sum = eta_i + feta_[j];
      if (eta_sum > 0) {
        const double viscous = m_j * eta_sum / (rho_i * rho_j) * f * r2 / (r2 + eta2);
        ax += viscous * dvx;
        ay += viscous * dvy;
        az += viscous * dvz;
      }
      if (s_i != nullptr) {
        const double* s_j = &fstress_[6 * j];
        double sum[6];
        for (int q = 0; q < 6; ++q) sum[q] = m_j * (s_i[q] / (rho_i * rho_i) + s_j[q] / (rho_j * rho_j));
        add_stress_dot(sum, f, rx, ry, rz, ax, ay, az);
      }
      if (diffusion) {
        const double psi = hydrostatic_diffusion ? dynamic_density_difference(p_i, fp_[j], rho_i, rho_j, gx, gy, gz, rx,
                                                                              ry, rz, inverse_c2)
                                                 : rho_j - rho_i;
        diffuse += psi * (-f * r2) / (r2 + eta2) * m_j / rho_j;
      }
    });
    for_neighbours(x, y, z, b_cell_start_, [&](std::uint32_t j) {
      const double rx = x - bx_[j], ry = y - by_[j], rz = z - bz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 >= support2) return;
      neighbours += 1;
      const double f = kernel_.gradient_factor(std::sqrt(r2));
      const double rho_j = brho_[j], m_j = rho_j * bvol_[j];
      const double dvx = vx - bwx_[j], dvy = vy - bwy_[j], dvz = vz - bwz_[j];
      const double vr = dvx * rx + dvy * ry + dvz * rz;
      const double mu = h * vr / (r2 + eta2);
      max_mu = std::max(max_mu, std::abs(mu));
      double scalar = -m_j * (p_over_rho2_i + bp_[j] / (rho_j * rho_j));
      if (vr < 0) scalar += m_j * alpha_hc * vr / ((r2 + eta2) * 0.5 * (rho_i + rho_j));
      ax += scalar * f * rx;
      ay += scalar * f * ry;
      az += scalar * f * rz;
      if (eta_i > 0) {
        const double viscous = m_j * 2.0 * eta_i / (rho_i * rho_j) * f * r2 / (r2 + eta2);
        ax += viscous * (vx - bvx_[j]);
        ay += viscous * (vy - bvy_[j]);
        az += viscous * (vz - bvz_[j]);
      }
      if (s_i != nullptr) add_wall_stress(s_i, &bstress_[6 * j], m_j, rho_i, rho_j, f, rx, ry, rz, ax, ay, az);
    });
    out_ax_[i] = ax + gx;
    out_ay_[i] = ay + gy;
    out_az_[i] = az + gz;
    out_drho_[i] = diffusion ? diffusion_scale * diffuse : 0.0;
    out_dtcv_[i] = max_mu;
    out_neigh_[i] = neighbours;
  }
}

void SphModel::compute_boundary_forces() {
  const std::size_t nb = b_order_.size();
  const double support2 = kernel_.support() * kernel_.support();
  const double h = kernel_.h, c = sound_speed_, eta2 = eta_squared_;
  const double alpha_hc = settings_.artificial_viscosity * h * c;
  const auto count = static_cast<std::int64_t>(nb);
  // The same pair terms as in compute_fluid_forces, from the wall particle's side: the
  // force on the wall particle is minus the sum of the forces it puts on the fluid.
#pragma omp parallel for schedule(static) if (nb > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto b = static_cast<std::size_t>(k);
    const double x = bx_[b], y = by_[b], z = bz_[b];
    const double rho_b = brho_[b], m_b = rho_b * bvol_[b];
    const double p_over_rho2_b = bp_[b] / (rho_b * rho_b);
    double fx = 0, fy = 0, fz = 0;
    for_neighbours(x, y, z, f_cell_start_, [&](std::uint32_t j) {
      const double rx = fx_[j] - x, ry = fy_[j] - y, rz = fz_[j] - z;  // r_ib, i the fluid particle
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 >= support2) return;
      const double f = kernel_.gradient_factor(std::sqrt(r2));
      const double rho_i = frho_[j], m_i = fm_[j];
      const double dvx = fvx_[j] - bwx_[b], dvy = fvy_[j] - bwy_[b], dvz = fvz_[j] - bwz_[b];
      const double vr = dvx * rx + dvy * ry + dvz * rz;
      double scalar = -m_b * (fp_[j] / (rho_i * rho_i) + p_over_rho2_b);
      if (vr < 0) scalar += m_b * alpha_hc * vr / ((r2 + eta2) * 0.5 * (rho_i + rho_b));
      double ax = scalar * f * rx, ay = scalar * f * ry, az = scalar * f * rz;
      const double eta_i = feta_[j];
      if (eta_i > 0) {
        const double viscous = m_b * 2.0 * eta_i / (rho_i * rho_b) * f * r2 / (r2 + eta2);
        ax += viscous * (fvx_[j] - bvx_[b]);
        ay += viscous * (fvy_[j] - bvy_[b]);
        az += viscous * (fvz_[j] - bvz_[b]);
      }
      if (has_stress_) {
        add_wall_stress(&fstress_[6 * j], &bstress_[6 * b], m_b, rho_i, rho_b, f, rx, ry, rz, ax, ay, az);
      }
      fx -= m_i * ax;
      fy -= m_i * ay;
      fz -= m_i * az;
    });
    out_bfx_[b] = fx;
    out_bfy_[b] = fy;
    out_bfz_[b] = fz;
  }
  boundary_force_.assign(boundary_.size(), Vec3::Zero());
  for (std::size_t s = 0; s < nb; ++s) boundary_force_[b_order_[s]] = Vec3(out_bfx_[s], out_bfy_[s], out_bfz_[s]);
}

// Continuity at x_n with the new velocities v_{n+1/2} (the density is a position-like
// variable of the leapfrog: with v_{n-1/2} the acoustic modes would grow).
void SphModel::compute_velocity_divergence() {
  const std::size_t n = f_order_.size();
  const double support2 = kernel_.support() * kernel_.support();
  for (std::size_t s = 0; s < n; ++s) {
    const Vec3& v = velocity_[f_order_[s]];
    fvx_[s] = v.x();
    fvy_[s] = v.y();
    fvz_[s] = v.z();
  }
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (n > kParallelThreshold)
  for (std::int64_t k = 0; k < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double x = fx_[i], y = fy_[i], z = fz_[i];
    const double vx = fvx_[i], vy = fvy_[i], vz = fvz_[i];
    double drho = 0;
    for_neighbours(x, y, z, f_cell_start_, [&](std::uint32_t j) {
      const double rx = x - fx_[j], ry = y - fy_[j], rz = z - fz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 >= support2 || j == i) return;
      const double vr = (vx - fvx_[j]) * rx + (vy - fvy_[j]) * ry + (vz - fvz_[j]) * rz;
      drho += fm_[j] * vr * kernel_.gradient_factor(std::sqrt(r2));
    });
    for_neighbours(x, y, z, b_cell_start_, [&](std::uint32_t j) {
      const double rx = x - bx_[j], ry = y - by_[j], rz = z - bz_[j];
      const double r2 = rx * rx + ry * ry + rz * rz;
      if (r2 >= support2) return;
      const double vr = (vx - bwx_[j]) * rx + (vy - bwy_[j]) * ry + (vz - bwz_[j]) * rz;
      drho += brho_[j] * bvol_[j] * vr * kernel_.gradient_factor(std::sqrt(r2));
    });
    out_drho_[i] += drho;
  }
  for (std::size_t s = 0; s < n; ++s) density_rate_[f_order_[s]] = out_drho_[s];
}

void SphModel::scatter_and_stable_dt() {
  const std::size_t n = f_order_.size();
  const double h = kernel_.h;
  double dt_cv = std::numeric_limits<double>::infinity(), dt_force = dt_cv, dt_viscous = dt_cv;
  double neighbour_sum = 0;
  for (std::size_t s = 0; s < n; ++s) {
    const std::uint32_t i = f_order_[s];
    acceleration_[i] = Vec3(out_ax_[s], out_ay_[s], out_az_[s]);
    dt_cv = std::min(dt_cv, h / (sound_speed_ + out_dtcv_[s]));
    const double a = acceleration_[i].norm();
    if (a > 0) dt_force = std::min(dt_force, std::sqrt(h / a));
    if (feta_[s] > 0) dt_viscous = std::min(dt_viscous, frho_[s] * h * h / (8.0 * feta_[s]));
    neighbour_sum += out_neigh_[s];
  }
  dt_cv = std::min(dt_cv, elastic_wave_dt_);
  mean_neighbours_ = n > 0 ? neighbour_sum / static_cast<double>(n) : 0.0;
  if (n == 0) dt_cv = h / sound_speed_;
  stable_dt_ = settings_.cfl * std::min({dt_cv, dt_force, dt_viscous});

  if (has_stress_) {
    // Jaumann rate dS/dt = 2 G D' + W S - S W, W = (L - L^T)/2.
    for (std::size_t s = 0; s < n; ++s) {
      const std::uint32_t i = f_order_[s];
      double* rate = &stress_rate_[6 * i];
      std::fill_n(rate, 6, 0.0);
      const FluidMaterial& material = materials_[material_[i]];
      if (material.rheology != Rheology::elastic_plastic) continue;
      const double* L = &fgrad_[9 * s];
      Mat3 grad;
      grad << L[0], L[1], L[2], L[3], L[4], L[5], L[6], L[7], L[8];
      const Mat3 d = 0.5 * (grad + grad.transpose());
      const Mat3 w = 0.5 * (grad - grad.transpose());
      const double* st = &stress_[6 * i];
      Mat3 stress;
      stress << st[0], st[3], st[5], st[3], st[1], st[4], st[5], st[4], st[2];
      const Mat3 deviatoric = d - (d.trace() / 3.0) * Mat3::Identity();
      const Mat3 r = 2.0 * material.shear_modulus * deviatoric + w * stress - stress * w;
      rate[0] = r(0, 0);
      rate[1] = r(1, 1);
      rate[2] = r(2, 2);
      rate[3] = r(0, 1);
      rate[4] = r(1, 2);
      rate[5] = r(2, 0);
    }
  }
}

void SphModel::compute_internal_forces(double dt_previous) {
  (void)dt_previous;
  build_grid();
  gather();
  compute_boundary_state();
  compute_velocity_gradients();
  compute_fluid_forces();
  compute_boundary_forces();
  scatter_and_stable_dt();
  forces_ready_ = true;
}

void SphModel::add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force) {
  if (force.size() != 3 * index.size()) {
    throw ProtocolError(
        fmt::format("sph_solver: {} particle indices but {} force values; 3 values per particle expected", index.size(),
                    force.size()));
  }
  for (std::size_t k = 0; k < index.size(); ++k) {
    const std::uint32_t i = index[k];
    if (i >= size()) {
      throw ProtocolError(fmt::format("sph_solver: force for particle {} but there are only {}", i, size()));
    }
    external_force_[i] += Vec3(force[3 * k], force[3 * k + 1], force[3 * k + 2]);
  }
}

void SphModel::integrate(double dt_previous, double dt) {
  assert(forces_ready_ && "compute_internal_forces() must run before integrate()");
  assert(dt > 0 && dt_previous >= 0);
  const bool first_step = dt_previous == 0;
  const double dt_update = first_step ? 0.5 * dt : 0.5 * (dt_previous + dt);
  const auto n = static_cast<std::int64_t>(size());
  const bool parallel = size() > kParallelThreshold;
#pragma omp parallel for schedule(static) if (parallel)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (!active_[i]) {
      particle_kinetic_[i] = 0;
      external_force_[i].setZero();
      continue;
    }
    const FluidMaterial& material = materials_[material_[i]];
    particle_potential_[i] = -mass_[i] * gravity_.dot(position_[i]);
    particle_elastic_[i] = mass_[i] * material.eos.specific_energy(density_[i]);
    const Vec3 a = acceleration_[i] + external_force_[i] / mass_[i];
    const Vec3 velocity = velocity_[i] + dt_update * a;
    particle_kinetic_[i] =
        first_step ? 0.5 * mass_[i] * velocity_[i].squaredNorm() : 0.5 * mass_[i] * velocity_[i].dot(velocity);
    velocity_[i] = velocity;
    external_force_[i].setZero();
  }
  compute_velocity_divergence();
#pragma omp parallel for schedule(static) if (parallel)
  for (std::int64_t k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (!active_[i]) continue;
    const FluidMaterial& material = materials_[material_[i]];
    position_[i] += dt * velocity_[i];
    density_[i] += dt * density_rate_[i];
    if (has_stress_ && material.rheology == Rheology::elastic_plastic) {
      double* s = &stress_[6 * i];
      for (int q = 0; q < 6; ++q) s[q] += dt * stress_rate_[6 * i + q];
      // Radial return onto the von Mises surface sqrt(3/2 S:S) = sigma_y.
      const double ss = s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + 2.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
      const double equivalent = std::sqrt(1.5 * ss);
      if (equivalent > material.yield_stress) {
        const double scale = material.yield_stress / equivalent;
        for (int q = 0; q < 6; ++q) s[q] *= scale;
      }
    }
    pressure_[i] = material.eos.pressure(density_[i]);
  }
  double kinetic = 0, potential = 0, elastic = 0;
  for (std::size_t i = 0; i < size(); ++i) {
    if (!active_[i]) continue;
    if (!std::isfinite(position_[i].x() + position_[i].y() + position_[i].z() + density_[i])) {
      throw Error(
          fmt::format("sph_solver: particle {} is no longer finite (position {} {} {}, density {}) after a "
                      "step of {:.3e} s. Fix: lower [solvers.sph] beta or sph.cfl.",
                      i, position_[i].x(), position_[i].y(), position_[i].z(), density_[i], dt));
    }
    kinetic += particle_kinetic_[i];
    potential += particle_potential_[i];
    elastic += particle_elastic_[i];
    if (settings_.domain && !settings_.domain->contains(position_[i])) {
      active_[i] = 0;
      velocity_[i].setZero();
      ++lost_;
    }
  }
  energies_ = {kinetic, potential, elastic};
  forces_ready_ = false;
}

}  // namespace sabo::sph
