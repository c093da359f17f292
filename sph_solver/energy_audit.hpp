#pragma once
// What the fluid dissipates, as an energy audit: the energy the fluid lost
// beyond the work done on it from outside. Each step,
//   dissipated += E_{n-1} - E_n + W_n,
// E = kinetic + potential + compression (SphModel::energies().total()) and W_n
// the work of the step's outside forces over dt_avg = (dt_{n-1} + dt_n) / 2:
//   * the coupler's contact forces on the particles (penalty walls, the SPH-DEM
//     penalty), F . (v_{n-1/2} + v_{n+1/2}) / 2;
//   * the walls (structures and boulders as boundary particles), minus the force
//     the fluid put on each wall particle times that particle's prescribed
//     velocity: the work the walls lose to the fluid, so that what the fluid is
//     credited is what the structure or boulder on the other side of the coupler
//     gave up.
// What it holds: viscosity, artificial viscosity and density diffusion, the
// settling phase's damping, the walls' work held back by sph.wall_work =
// "bounded", the energy of particles that left the domain, the interface's own
// work (fluid sliding past a wall) and the time integration's error. What the
// inflows bring (Energies::inflow, inflow.hpp) counts as work done on the fluid. Summed over
// the coupled run, every solver's energy plus its dissipated energy then differs
// from the start only by what the coupling does not conserve (docs/physics.md,
// "Energy balance").
#include <cstdint>
#include <span>
#include <vector>

#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

class EnergyAudit {
 public:
  explicit EnergyAudit(const SphModel& model)
      : previous_total_(model.energies().total()), previous_inflow_(model.energies().inflow) {}

  // After the step's forces (compute_internal_forces, add_external_forces), before integrate():
  // `index` and `force` are the external forces added this step (3 doubles each, N).
  void before_integrate(const SphModel& model, std::span<const std::uint32_t> index, std::span<const double> force);
  // After integrate(dt_previous, dt).
  void after_integrate(const SphModel& model, double dt_previous, double dt);

  // J, accumulated: what the fluid lost beyond the work done on it.
  [[nodiscard]] double dissipated() const { return dissipated_; }
  // J, accumulated: the work done on the fluid from outside (walls and contact forces).
  [[nodiscard]] double work_in() const { return work_in_; }
  // Its accounts in and out of a checkpoint (between steps: nothing of a step is pending).
  void save(io::hdf5::Group& group) const {
    group.set_attribute("audit_previous_total", previous_total_);
    group.set_attribute("audit_dissipated", dissipated_);
    group.set_attribute("audit_work_in", work_in_);
    group.set_attribute("audit_previous_inflow", previous_inflow_);
  }
  void load(const io::hdf5::Group& group) {
    previous_total_ = group.double_attribute("audit_previous_total");
    dissipated_ = group.double_attribute("audit_dissipated");
    work_in_ = group.double_attribute("audit_work_in");
    previous_inflow_ = group.double_attribute("audit_previous_inflow");
  }

 private:
  double previous_total_;
  double previous_inflow_;
  double dissipated_ = 0, work_in_ = 0;
  double wall_power_ = 0;  // W, this step: the walls' power into the fluid
  std::vector<std::uint32_t> index_;
  std::vector<Vec3> force_, velocity_before_;
};

}  // namespace sabo::sph
