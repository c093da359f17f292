// Inflows (inflow.hpp): the pools, the buffers' motion, release, entry and end. The buffers hold few
// particles against the fluid's, so their loops are serial. On ranks every rank advances each inflow's
// state alike (it depends on the hydrograph and the steps only) and moves the buffer particles it owns; a
// layer entering the buffer goes to the ranks by the share of ids the first step's slabs start from, and
// its owners follow from the next step's slabs.
#include <algorithm>
#include <cassert>

#include "sph_solver/sph_model.hpp"

namespace sabo::sph {

void SphModel::start_inflows(std::size_t bodies) {
  buffer_velocity_.assign(bodies, Vec3::Zero());
  for (InflowState& inflow : inflows_) {
    std::fill_n(active_.begin() + inflow.first, inflow.lattice.particles(), kOut);
    inflow.speed = inflow.previous_speed = inflow.section.discharge(0.0) / inflow.lattice.area;
    // The first buffer, at rest or moving at U(0): the layers with s_l >= -buffer_layers dx at X = 0.
    advance_inflows_to(inflow);
  }
}

void SphModel::set_inflow_velocities(double dt) {
  for (InflowState& inflow : inflows_) {
    inflow.previous_speed = inflow.speed;
    inflow.speed = inflow.ended ? 0.0 : inflow.section.discharge(time_ + 0.5 * dt) / inflow.lattice.area;
    buffer_velocity_[inflow.body] = inflow.speed * inflow.section.direction;
  }
}

// The layers of the pool that the buffer's advance has reached enter it, at their places, with the
// buffer's velocity and density.
void SphModel::advance_inflows_to(InflowState& inflow) {
  const double dx = inflow.spacing;
  const double back = static_cast<double>(inflow.lattice.buffer_layers);
  const Vec3 velocity = inflow.speed * inflow.section.direction;
  while (inflow.entered < inflow.lattice.layers &&
         inflow.advance >= (static_cast<double>(inflow.entered) + 0.5 - back) * dx) {
    for (std::size_t k = 0; k < inflow.lattice.per_layer(); ++k) {
      const std::uint32_t i = inflow.id(inflow.entered, k);
      if (!in_initial_share(i)) continue;
      active_[i] = kEntering;
      position_[i] = inflow.position(inflow.entered, k, inflow.advance);
      velocity_[i] = velocity;
      acceleration_[i].setZero();
      density_[i] = inflow.row_density[k / inflow.lattice.across];
      pressure_[i] = materials_[material_[i]].eos.pressure(density_[i]);
    }
    ++inflow.entered;
  }
}

void SphModel::advance_inflows(double dt, ExactSum& pending) {
  for (InflowState& inflow : inflows_) {
    if (inflow.ended) continue;
    const std::size_t per_layer = inflow.lattice.per_layer();
    const std::size_t first = inflow.released;
    const double from = inflow.advance;
    inflow.advance += dt * inflow.speed;
    // Layers past the section are free fluid from now on.
    while (inflow.released < inflow.entered &&
           inflow.advance >= (static_cast<double>(inflow.released) + 0.5) * inflow.spacing) {
      ++inflow.released;
    }
    // Once the hydrograph has ended, the buffer's particles leave.
    const bool ending = time_ + dt >= inflow.section.end_time();
    for (std::size_t layer = first; layer < inflow.entered; ++layer) {
      const bool released = layer < inflow.released;
      for (std::size_t k = 0; k < per_layer; ++k) {
        const std::uint32_t i = inflow.id(layer, k);
        if (active_[i] == kOut) continue;  // another rank's (a buffer's particles are never lost)
        const EquationOfState& eos = materials_[material_[i]].eos;
        const double rho = inflow.row_density[k / inflow.lattice.across];
        if (released || !ending) {
          // Where the advance puts it, its density reset: what the reset adds to its energy shows in the next
          // step's energies, so the account takes it then.
          pending.add(mass_[i] * (eos.specific_energy(rho) - eos.specific_energy(density_[i])));
          density_[i] = rho;
          pressure_[i] = eos.pressure(rho);
          position_[i] = inflow.position(layer, k, inflow.advance);
          active_[i] = released ? kFree : kBuffer;
        } else {
          // Taken out: the account gives back the energy it has in this step's energies (at x_n, with the
          // prescribed density, 1/2 m v_{n-1/2}.v_{n+1/2}).
          pending.add(-(0.5 * mass_[i] * inflow.previous_speed * inflow.speed -
                        mass_[i] * gravity_.dot(inflow.position(layer, k, from)) +
                        mass_[i] * eos.specific_energy(rho)));
          active_[i] = kOut;
          velocity_[i].setZero();
        }
      }
    }
    if (ending) {
      inflow.ended = true;
    } else {
      advance_inflows_to(inflow);
    }
  }
}

std::vector<double> SphModel::inflow_values() const {
  std::vector<double> values;
  for (const InflowState& inflow : inflows_) {
    values.insert(values.end(), {inflow.advance, inflow.speed, inflow.previous_speed, double(inflow.entered),
                                 double(inflow.released), inflow.ended ? 1.0 : 0.0});
  }
  return values;
}

void SphModel::set_inflow_values(std::span<const double> values) {
  assert(values.size() == kInflowValues * inflows_.size());
  for (std::size_t k = 0; k < inflows_.size(); ++k) {
    const double* v = &values[kInflowValues * k];
    InflowState& inflow = inflows_[k];
    inflow.advance = v[0];
    inflow.speed = v[1];
    inflow.previous_speed = v[2];
    inflow.entered = static_cast<std::size_t>(v[3]);
    inflow.released = static_cast<std::size_t>(v[4]);
    inflow.ended = v[5] != 0;
  }
}

}  // namespace sabo::sph
