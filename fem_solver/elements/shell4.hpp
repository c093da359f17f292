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

// Area and characteristic length (area / longest side, m) at x.
[[nodiscard]] double shell4_area(const QuadNodes& x);
[[nodiscard]] double shell4_characteristic_length(const QuadNodes& x);

// Advances the stresses with the velocities v_{n-1/2} and angular velocities
// over dt_previous, then the internal forces and moments on the nodes at x_n
// (global frame; N and N m). Returns false for a degenerate element.
bool shell4_internal_force(const MaterialParameters& material, double thickness, double hourglass_scale,
                           const QuadNodes& x, const QuadNodes& velocity, const QuadNodes& angular_velocity,
                           double dt_previous, Shell4State& state, QuadNodes& force, QuadNodes& moment);

}  // namespace sabo::fem
