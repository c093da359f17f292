#pragma once
// The 4-node Belytschko-Lin-Tsay shell (docs/physics.md "FEM shells"):
// co-rotational local frame per element (e3 along the cross product of the
// diagonals, e1 along side 1-2 projected), one-point in-plane integration,
// Mindlin kinematics v(z) = v + z theta x e3 with rotational velocities at the
// nodes, kThicknessPoints Gauss-Lobatto points through the thickness in plane
// stress (sigma_zz = 0 solved by iteration on the thickness strain rate),
// transverse shear elastic with factor 5/6, and Flanagan-Belytschko stiffness
// hourglass control of the membrane, w and rotation modes. Stresses are kept
// in the co-rotational frame (objective without a Jaumann term).
#include <array>

#include "fem_solver/materials/plastic_kinematic.hpp"
#include "libsabo/core/types.hpp"

namespace sabo::fem {

inline constexpr std::size_t kThicknessPoints = 5;

using QuadNodes = std::array<Vec3, 4>;

struct Shell4State {
  std::array<MaterialPoint, kThicknessPoints> point;  // local frame, through the thickness
  double shear_x = 0, shear_y = 0;                    // transverse shear resultants q_xz, q_yz, N/m
  std::array<double, 5> hourglass{};                  // membrane x, y, w, theta x, theta y (N, N, N, N m, N m)
  double area = 0;                                    // m^2 at x_n
  double internal_energy = 0, hourglass_energy = 0, plastic_work = 0;  // J
};

// Area and characteristic length (area / the longest of the sides and diagonals, m) at x.
[[nodiscard]] double shell4_area(const QuadNodes& x);
[[nodiscard]] double shell4_characteristic_length(const QuadNodes& x);

// Advances the stresses with the velocities v_{n-1/2} and angular velocities
// over dt_previous, then the internal forces and moments on the nodes at x_n
// (global frame; N and N m). Returns false for a degenerate element.
bool shell4_internal_force(const MaterialParameters& material, double thickness, double hourglass_scale,
                           const QuadNodes& x, const QuadNodes& velocity, const QuadNodes& angular_velocity,
                           double dt_previous, Shell4State& state, QuadNodes& force, QuadNodes& moment);

// The fully integrated 4-node shell (docs/physics.md "FEM shells, fully
// integrated"): the BLT co-rotational frame and flat local geometry, 2 x 2
// in-plane Gauss points each with kThicknessPoints through the thickness
// (membrane and bending from the bilinear shape functions), transverse shear
// by assumed natural strain (MITC4, Bathe-Dvorkin: covariant shears tied at
// the edge midpoints, so thin shells do not lock), and no hourglass control:
// the element has no spurious zero-energy modes (state.hourglass and
// state.hourglass_energy stay 0). The drilling rotation (about e3) gets a
// small elastic stiffness kDrillingFactor G t A per node on the difference
// between the node's drilling rate and the element's in-plane spin, so that
// it is no zero-energy mode either; its energy counts in
// state.internal_energy and, separately, in gauss.drilling_energy.
// `gauss` holds the histories; state.point and state.shear_x/y receive their
// means over the Gauss points (output, erosion). Same time levels and return
// as shell4_internal_force.
inline constexpr double kDrillingFactor = 0.01;

struct Shell4GaussPoints {
  std::array<std::array<MaterialPoint, kThicknessPoints>, 4> point;  // per Gauss point, through the thickness
  std::array<double, 8> shear{};                                     // q_xz, q_yz per Gauss point, local frame, N/m
  std::array<double, 4> drilling{};                                  // drilling moments per node about e3, N m
  double drilling_energy = 0;                                        // J, included in Shell4State::internal_energy
};

bool shell4_full_internal_force(const MaterialParameters& material, double thickness, const QuadNodes& x,
                                const QuadNodes& velocity, const QuadNodes& angular_velocity, double dt_previous,
                                Shell4State& state, Shell4GaussPoints& gauss, QuadNodes& force, QuadNodes& moment);

}  // namespace sabo::fem
