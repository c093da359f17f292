#pragma once
// A deformable solid: hexahedra of one material, lumped nodal masses, fixed
// degrees of freedom, gravity, explicit central-difference integration and
// element erosion (docs/physics.md "FEM solids"); one-point, fully integrated
// or enhanced-strain hexahedra (HexFormulation).
//
// Step n (the CoupledSolver contract, docs/design.md, "An explicit, lock-step step"): the body holds x_n and
// v_{n-1/2}.
//   compute_internal_forces(dt_{n-1}): stresses advanced with v_{n-1/2} over
//     dt_{n-1} at the mid-step geometry, then f_int(x_n); failed elements are
//     eroded (their forces vanish from now on, their nodes keep their mass).
//   integrate(dt_{n-1}, dt_n, f_contact): a_n = M^-1 (f_contact + M g - f_int),
//     fixed DOFs held at zero velocity,
//     v_{n+1/2} = v_{n-1/2} + (dt_{n-1} + dt_n)/2 a_n, x_{n+1} = x_n + dt_n v_{n+1/2}.
// Parallel (OpenMP) over elements, each writing its own 8 nodal forces; nodes
// gather them in a fixed order: the same bits on any number of threads.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "fem_solver/body_common.hpp"
#include "fem_solver/body_state.hpp"
#include "fem_solver/elements/hex8.hpp"
#include "fem_solver/materials/plastic_kinematic.hpp"
#include "fem_solver/mesh/hex_mesh.hpp"
#include "fem_solver/node_gather.hpp"

namespace sabo::fem {

// How the hexahedra integrate their stress (scene key element_formulation).
enum class HexFormulation {
  one_point,         // one point, hourglass stabilised (hex8_internal_force)
  fully_integrated,  // 2 x 2 x 2 points, mean dilatation (hex8_full_internal_force)
  enhanced_strain,   // 2 x 2 x 2 points, condensed incompatible modes (hex8_enhanced_internal_force)
};

enum Dof : unsigned { dof_x = 1, dof_y = 2, dof_z = 4, dof_all = 7 };

class SolidBody {
 public:
  SolidBody(HexMesh mesh, const MaterialParameters& material, double hourglass_scale = 1.0);
  SolidBody(HexMesh mesh, const MaterialParameters& material, HexFormulation formulation);
  // hourglass_scale applies to one-point elements only.
  SolidBody(HexMesh mesh, const MaterialParameters& material, double hourglass_scale, HexFormulation formulation);

  [[nodiscard]] std::size_t node_count() const { return position_.size(); }
  [[nodiscard]] std::size_t element_count() const { return mesh_.element.size(); }
  [[nodiscard]] const HexMesh& mesh() const { return mesh_; }
  [[nodiscard]] const MaterialParameters& material() const { return material_; }
  [[nodiscard]] HexFormulation formulation() const { return formulation_; }

  // Fixes the DOFs in `dofs` (Dof bits) of a node; its velocity there stays zero.
  void fix(std::size_t node, unsigned dofs);
  // Fixes the DOFs of every node inside `box`; returns how many nodes.
  std::size_t fix_in_box(const Aabb& box, unsigned dofs);
  void set_velocity(const Vec3& velocity);  // m/s, every node (fixed DOFs stay zero)
  void set_node_velocity(std::size_t node, const Vec3& velocity);
  void set_gravity(const Vec3& gravity) { gravity_ = gravity; }

  // Loops over fewer elements or nodes than this run on one thread: for
  // small meshes the threads' start and barrier cost more than the work.
  void set_parallel_minimum(std::ptrdiff_t count) { parallel_minimum_ = count; }

  // Replay (--take): a node's recorded position (m) and/or velocity (m/s) in place of its own; nullptr: kept.
  void take_node(std::size_t node, const Vec3* position, const Vec3* velocity) {
    if (position != nullptr) position_.at(node) = *position;
    if (velocity != nullptr) velocity_.at(node) = *velocity;
  }
  [[nodiscard]] std::span<const Vec3> positions() const { return position_; }
  [[nodiscard]] std::span<const Vec3> reference_positions() const { return mesh_.node; }
  [[nodiscard]] std::span<const Vec3> velocities() const { return velocity_; }  // v_{n-1/2} (v_{n+1/2} after integrate)
  [[nodiscard]] std::span<const double> masses() const { return mass_; }
  [[nodiscard]] std::span<const Vec3> internal_forces() const { return internal_force_; }
  [[nodiscard]] const Hex8State& element_state(std::size_t e) const { return state_[e]; }
  [[nodiscard]] bool eroded(std::size_t e) const { return active_[e] == 0; }
  [[nodiscard]] std::span<const std::uint8_t> active() const { return active_; }  // 1: not eroded
  [[nodiscard]] double total_mass() const { return sum_masses(mass_); }

  // The active elements whose volume at the current positions is not positive (inside out), in index order.
  [[nodiscard]] std::vector<std::size_t> inverted_elements() const;

  // See the class comment. Returns the number of elements eroded now.
  std::size_t compute_internal_forces(double dt_previous);
  // external_force: per node (N), or empty for none.
  void integrate(double dt_previous, double dt, std::span<const Vec3> external_force = {});

  // Smallest element's L / c (eq. 7's FEM term without beta), s; after compute_internal_forces.
  [[nodiscard]] double stable_dt() const { return stable_dt_; }
  [[nodiscard]] SolidEnergies energies() const;
  // Checkpoint and restart: the evolving state (body_state.hpp). restore_state
  // takes a state saved by a body built from the same mesh and settings and
  // continues with the same bits; FileError when the sizes do not match.
  [[nodiscard]] BodyState save_state() const;
  void restore_state(const BodyState& state, const std::string& what);
  // Incremented whenever elements erode (the exterior surface changed).
  [[nodiscard]] std::uint64_t topology_revision() const { return erosion_.topology_revision; }
  [[nodiscard]] std::size_t eroded_count() const { return erosion_.count; }

 private:
  HexMesh mesh_;
  MaterialParameters material_;
  double hourglass_scale_;
  HexFormulation formulation_ = HexFormulation::one_point;
  Vec3 gravity_ = Vec3::Zero();
  std::ptrdiff_t parallel_minimum_ = 4096;
  std::vector<Vec3> position_, velocity_, internal_force_;
  std::vector<double> mass_;
  std::vector<std::uint8_t> fixed_;  // Dof bits per node
  std::vector<Hex8State> state_;
  std::vector<Hex8GaussPoints> gauss_;  // per element, 2 x 2 x 2 formulations only
  std::vector<std::uint8_t> active_;    // 1: not eroded
  std::vector<Vec3> element_force_;     // 8 per element
  std::vector<double> element_dt_;      // per element
  std::vector<std::uint8_t> element_failed_;
  NodeGather gather_;
  double stable_dt_ = 0;
  double kinetic_ = 0, external_work_ = 0;
  ErosionAccounts erosion_;
};

}  // namespace sabo::fem
