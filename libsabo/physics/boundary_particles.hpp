#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::physics {

// Wall particles sampled from structure surfaces by the coupler (Adami, Hu & Adams 2012).
// The SPH solver includes them in its density and pressure sums; their pressure is
// extrapolated from the fluid each step, and the force the fluid exerts on each of them
// goes back to the structure through the coupler.
struct BoundaryParticles {
  std::vector<Vec3> position;      // m
  std::vector<Vec3> velocity;      // m/s (prescribed wall velocity); empty: every particle at rest
  std::vector<Vec3> normal;        // unit, pointing into the fluid
  std::vector<Vec3> acceleration;  // m/s^2 of the wall (Adami's pressure term uses g - a_w); empty: zero
  std::vector<double> volume;      // m^3 (dx^3 for a layer sampling)
  // Optional, one per particle: 1 marks a free-slip wall particle for the viscous terms (its
  // velocity there keeps the fluid's tangential velocity, so the wall takes no viscous shear).
  // Empty: every particle is no-slip (what the coupler sends).
  std::vector<std::uint8_t> free_slip;

  [[nodiscard]] std::size_t size() const { return position.size(); }
  [[nodiscard]] Vec3 velocity_of(std::size_t b) const { return velocity.empty() ? Vec3::Zero() : velocity[b]; }
  [[nodiscard]] Vec3 acceleration_of(std::size_t b) const {
    return acceleration.empty() ? Vec3::Zero() : acceleration[b];
  }
  void resize(std::size_t n) {
    position.resize(n, Vec3::Zero());
    velocity.resize(n, Vec3::Zero());
    normal.resize(n, Vec3::Zero());
    acceleration.resize(n, Vec3::Zero());
    volume.resize(n, 0.0);
  }
};

}  // namespace sabo::physics
