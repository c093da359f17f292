#pragma once
// Thin-walled structures of 4-node shells, Belytschko-Lin-Tsay or fully
// integrated (ShellFormulation; houses:
// walls, floors, roof), each panel with its thickness and material: lumped
// translational masses rho t A / 4 and rotational inertias, fixed DOFs,
// gravity, explicit central difference and erosion, as SolidBody
// (solid_body.hpp, the same step contract). Nodes carry 6 DOFs: velocity and
// angular velocity (the shell frame is rebuilt from the geometry every step,
// so no rotation needs integrating). Rotational inertia per node is scaled to
// m (t^2 + A) / 12, the usual explicit practice that keeps the bending modes
// from limiting the step; it slows rotations, not the static response.
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "fem_solver/elements/shell4.hpp"
#include "fem_solver/solid_body.hpp"

namespace sabo::fem {

struct ShellMesh {
  std::vector<Vec3> node;                             // m
  std::vector<std::array<std::uint32_t, 4>> element;  // counter-clockwise seen from the outer side
  std::vector<double> thickness;                      // m, per element
  std::vector<std::uint32_t> material;                // index into the body's materials, per element
};

// A flat rectangular panel: origin corner, two edge vectors, n1 x n2 elements.
void add_panel(ShellMesh& mesh, const Vec3& origin, const Vec3& edge1, const Vec3& edge2, std::size_t n1,
               std::size_t n2, double thickness, std::uint32_t material);
// Merges nodes closer than `tolerance` (m): panels sharing edges become one structure.
void weld(ShellMesh& mesh, double tolerance);

// How the shells integrate their stress (scene key element_formulation):
// Belytschko-Lin-Tsay one-point with hourglass control, or fully integrated
// (2 x 2 points, MITC4 transverse shear, no hourglass modes; shell4.hpp).
enum class ShellFormulation { one_point, fully_integrated };

class ShellBody {
 public:
  ShellBody(ShellMesh mesh, std::vector<MaterialParameters> materials, double hourglass_scale = 1.0,
            ShellFormulation formulation = ShellFormulation::one_point);
  ShellBody(ShellMesh mesh, std::vector<MaterialParameters> materials, ShellFormulation formulation)
      : ShellBody(std::move(mesh), std::move(materials), 1.0, formulation) {}

  [[nodiscard]] std::size_t node_count() const { return position_.size(); }
  [[nodiscard]] std::size_t element_count() const { return mesh_.element.size(); }
  [[nodiscard]] const ShellMesh& mesh() const { return mesh_; }
  [[nodiscard]] ShellFormulation formulation() const { return formulation_; }
  // J, energy of the fully integrated shells' drilling stiffness (part of
  // energies().internal; 0 for one-point shells), active elements.
  [[nodiscard]] double drilling_energy() const;
  [[nodiscard]] const MaterialParameters& material(std::size_t e) const { return materials_[mesh_.material[e]]; }
  // dofs: Dof bits for translations, and rotations in bits 3..5 (dof_all | rotations_all fixes all six).
  void fix(std::size_t node, unsigned dofs);
  std::size_t fix_in_box(const Aabb& box, unsigned dofs);
  void set_velocity(const Vec3& velocity);
  void set_gravity(const Vec3& gravity) { gravity_ = gravity; }
  // Mass-proportional damping (1/s) on velocities and angular velocities, for
  // static solutions by dynamic relaxation; its work counts as external work.
  void set_damping(double per_second) { damping_ = per_second; }

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
  [[nodiscard]] std::span<const Vec3> velocities() const { return velocity_; }
  [[nodiscard]] std::span<const Vec3> angular_velocities() const { return angular_velocity_; }
  [[nodiscard]] std::span<const double> masses() const { return mass_; }
  [[nodiscard]] const Shell4State& element_state(std::size_t e) const { return state_[e]; }
  [[nodiscard]] bool eroded(std::size_t e) const { return active_[e] == 0; }
  [[nodiscard]] std::span<const std::uint8_t> active() const { return active_; }
  [[nodiscard]] double total_mass() const { return sum_masses(mass_); }

  std::size_t compute_internal_forces(double dt_previous);
  void integrate(double dt_previous, double dt, std::span<const Vec3> external_force = {});
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
  ShellMesh mesh_;
  std::vector<MaterialParameters> materials_;
  double hourglass_scale_;
  ShellFormulation formulation_;
  Vec3 gravity_ = Vec3::Zero();
  std::ptrdiff_t parallel_minimum_ = 4096;
  double damping_ = 0;
  std::vector<Vec3> position_, velocity_, angular_velocity_, internal_force_, internal_moment_;
  std::vector<double> mass_, inertia_;
  std::vector<std::uint8_t> fixed_;
  std::vector<Shell4State> state_;
  std::vector<Shell4GaussPoints> gauss_;  // per element, fully integrated only
  std::vector<std::uint8_t> active_, element_failed_;
  std::vector<Vec3> element_force_, element_moment_;  // 4 per element
  std::vector<double> element_dt_;
  NodeGather gather_;
  double stable_dt_ = 0, kinetic_ = 0, external_work_ = 0;
  ErosionAccounts erosion_;
};

inline constexpr unsigned rotation_x = 8, rotation_y = 16, rotation_z = 32, rotations_all = 56;

}  // namespace sabo::fem
