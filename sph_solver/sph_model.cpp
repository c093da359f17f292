// SphModel: the particles a scene fills, and the order of the passes of a step. The passes
// themselves are in sph_solver/passes/ (README.md): grid.cpp (the neighbour grid and the
// gather into cell order), periodic.cpp, walls.cpp (boundary particles), momentum.cpp,
// continuity.cpp, rheology.cpp (viscosity, velocity gradients, stress rates) and
// integrate.cpp (the leapfrog step, energies, stable steps); their loops are particle_for()
// (passes/particle_for.hpp), their pair terms passes/pair_terms.hpp.
#include "sph_solver/sph_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "libsabo/core/error.hpp"
#include "sph_solver/exact_sum.hpp"

namespace sabo::sph {
namespace {

using Rheology = scene::Material::Rheology;
using WallWork = scene::SphSettings::WallWork;

// Neighbours of a point of a cubic lattice within `reach` lattice spacings (itself excluded).
int lattice_neighbours(double reach) {
  const auto cells = static_cast<int>(std::ceil(reach));
  int count = 0;
  for (int a = -cells; a <= cells; ++a) {
    for (int b = -cells; b <= cells; ++b) {
      for (int c = -cells; c <= cells; ++c) count += (a * a + b * b + c * c) < reach * reach ? 1 : 0;
    }
  }
  return count - 1;
}

}  // namespace

SphModel::SphModel(const scene::Scene& scene, std::shared_ptr<parallel::Ranks> ranks)
    : settings_(scene.sph),
      kernel_(scene.sph.kernel, scene.sph.smoothing_length()),
      gravity_(scene.run.gravity),
      sound_speed_(scene.sph.sound_speed) {
  eta_squared_ = 0.01 * kernel_.h * kernel_.h;
  // Penalty walls put no particles into a kernel: the fluid beside them, cut off like a free
  // surface, needs the diffusion (S4 with penalty walls: pressure error 8.9 % with it, 52 %
  // without), so there every pair diffuses.
  if (scene.sph.wall_model == scene::SphSettings::WallModel::boundary_particles) {
    full_support_neighbours_ = static_cast<std::int32_t>(
        std::ceil(kFullSupportFraction * lattice_neighbours(kernel_.support() / scene.sph.particle_spacing)));
  }
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
    material.consistency_index = source.consistency_index;
    material.flow_index = source.flow_index;
    material.shear_modulus = source.fluid_shear_modulus > 0 ? source.fluid_shear_modulus : source.shear_modulus();
    if (material.rheology == Rheology::elastic_plastic) {
      material.artificial_stress = source.artificial_stress.value_or(kDefaultArtificialStress);
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
    any_artificial_stress_ = any_artificial_stress_ || materials_[m].artificial_stress > 0;
    strain_rate_viscosity_ = strain_rate_viscosity_ || materials_[m].max_viscosity() > 0;
  }
  strain_rate_viscosity_ =
      strain_rate_viscosity_ && settings_.viscous_operator == scene::SphSettings::ViscousOperator::strain_rate;
  FluidFill fill = fill_fluids(scene, materials_, body_material);
  position_ = std::move(fill.position);
  velocity_ = std::move(fill.velocity);
  density_ = std::move(fill.density);
  pressure_ = std::move(fill.pressure);
  mass_ = std::move(fill.mass);
  material_ = std::move(fill.material);
  body_ = std::move(fill.body);
  inflows_ = std::move(fill.inflows);
  const std::size_t n = position_.size();
  acceleration_.assign(n, Vec3::Zero());
  if (has_stress_) {
    stress_ = std::move(fill.stress);
    stress_rate_.assign(6 * n, 0.0);
  }
  active_.assign(n, kFree);
  start_inflows(scene.fluids.size());
  for (const scene::FluidBody& body : scene.fluids) settle_time_.push_back(body.settle_time);
  const std::optional<std::array<double, 2>>* spans[2] = {&settings_.periodic_x, &settings_.periodic_y};
  for (int axis = 0; axis < 2; ++axis) {
    const auto& span = *spans[axis];
    if (!span) continue;
    const double period = (*span)[1] - (*span)[0];
    if (!(period >= 2.0 * kernel_.support())) {
      throw SceneError(fmt::format(
          "sph.periodic_{} = [{}, {}]: the period {} m is shorter than two kernel supports (4h = {} m). Fix: widen "
          "the span or lower sph.particle_spacing",
          axis == 0 ? 'x' : 'y', (*span)[0], (*span)[1], period, 2.0 * kernel_.support()));
    }
    periodic_.push_back({axis, (*span)[0], (*span)[1]});
  }
  if (!periodic_.empty()) {
    wrap_offset_.assign(n, Vec3::Zero());
    wrap_positions();
  }
  if (credits_wall_work() && settings_.wall_work == WallWork::bounded) wall_work_held_.assign(n, 0.0f);
  stable_dt_ = initial_stable_dt();
  // Exact sums, as integrate() takes them (exact_sum.hpp): a state that does not change keeps its energies' bits.
  ExactSum kinetic, potential, elastic;
  for (std::size_t i = 0; i < n; ++i) {
    if (active_[i] != kFree) continue;  // an inflow's buffer enters the account at the first step
    kinetic.add(0.5 * mass_[i] * velocity_[i].squaredNorm());
    potential.add(-mass_[i] * gravity_.dot(wrap_offset_.empty() ? position_[i] : Vec3(position_[i] - wrap_offset_[i])));
    elastic.add(mass_[i] * materials_[material_[i]].eos.specific_energy(density_[i]));
  }
  energies_.kinetic = kinetic.value();
  energies_.potential = potential.value();
  energies_.elastic = elastic.value();
  if (ranks) {
    ranks_ = std::move(ranks);
    if (ranks_->rank() == 0) collected_active_ = active_;  // it starts with the whole state
    keep_initial_share();
  }
}

void SphModel::compute_internal_forces(double dt_previous) {
  (void)dt_previous;
  if (!periodic_.empty()) {
    wrap_positions();  // positions() is writable
    make_images();
  }
  if (decomposed()) distribute();
  build_grid();
  if (decomposed()) mark_slots();
  gather();
  compute_boundary_state();
  if (decomposed()) exchange_wall_state();
  compute_velocity_gradients(false);
  if (decomposed()) exchange_viscosities();
  compute_fluid_forces();
  compute_boundary_forces();
  if (decomposed()) reduce_step_maxima();
  stable_dt_ = forces_stable_dt();
  forces_ready_ = true;
}

}  // namespace sabo::sph
