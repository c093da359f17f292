#pragma once
// The 8-node hexahedron, with one-point integration (uniform strain at the
// centre) and physical hourglass stabilisation (docs/physics.md "FEM solids").
//
// Node order: 0..3 the face zeta = -1 counter-clockwise seen from outside...
// precisely, natural coordinates (xi, eta, zeta) of the nodes:
//   0 (-,-,-) 1 (+,-,-) 2 (+,+,-) 3 (-,+,-) 4 (-,-,+) 5 (+,-,+) 6 (+,+,+) 7 (-,+,+)
//
// Stress: Jaumann-rate hypoelastic/plastic update (materials/) with the rate
// of deformation at the mid-step geometry x_{n-1/2}; forces f_a = V sigma
// grad N_a at x_n.
//
// Hourglass: the Flanagan-Belytschko base vectors gamma_alpha = h_alpha -
// sum_j (h_alpha . x_j) grad_j N (orthogonal to every linear field), in a
// co-rotational frame from the element's natural axes, with generalised
// stiffnesses from an assumed strain field (after Belytschko & Bindeman 1993,
// "assumed strain stabilization of the eight node hexahedral element"): the
// bending modes carry normal strains varying linearly across the element; the
// two that vary along the same natural coordinate k are coupled in plane stress
// (sigma_kk = 0, modulus E / (1 - nu^2), Poisson coupling), so pure bending of
// a beam is exact with one element through the depth and there is no volumetric
// locking; their parasitic shear is dropped (no shear locking). The warping
// modes keep their two shears with G, and the xi*eta*zeta mode has E V / (9
// a_i^2) (a_i: half-lengths along the element axes). Forces are incremental (objective,
// rotated with the frame). `hourglass_scale` multiplies every stiffness.
#include <array>

#include "fem_solver/materials/plastic_kinematic.hpp"
#include "libsabo/core/types.hpp"

namespace sabo::fem {

using HexNodes = std::array<Vec3, 8>;

struct Hex8State {
  MaterialPoint point;
  std::array<double, 12> hourglass{};  // generalised hourglass forces Q[i * 4 + alpha], local frame, N
  double volume = 0;                   // m^3 at x_n
  double internal_energy = 0;          // J, work of the stress (elastic + plastic)
  double hourglass_energy = 0;         // J, work of the hourglass forces
  double plastic_work = 0;             // J
};

// Volume at the element centre, 8 det J, m^3 (exact for parallelepipeds).
[[nodiscard]] double hex8_volume(const HexNodes& x);

// Characteristic length for the explicit step, m: the smaller of volume / largest face area and
// Flanagan-Belytschko's 1 / sqrt(2 sum_a |grad N_a|^2), below every formulation's critical length.
[[nodiscard]] double hex8_characteristic_length(const HexNodes& x);

// Advances the stress with v_{n-1/2} over dt_previous (nothing at dt_previous
// = 0), then computes the internal force on each node at x_n (N; the
// acceleration is M^-1 (f_ext - f_int)). Returns false when the element is
// inverted (non-positive volume at x_n or at mid-step); the state is then
// unchanged and force is zero.
bool hex8_internal_force(const MaterialParameters& material, double hourglass_scale, const HexNodes& x,
                         const HexNodes& velocity, double dt_previous, Hex8State& state, HexNodes& force);

// The fully integrated hexahedron: 2 x 2 x 2 Gauss points, each with its own
// material history, and the volumetric strain rate and pressure taken at the
// element mean (mean dilatation, Nagtegaal-Parks-Rice / Hughes B-bar):
//   D_g = dev(sym L_g) + (1/3) div_mean I,  div_mean = sum_a v_a . b_a,
//   b_a = (1/V) sum_g det J_g grad N_a(g)   (exact volume average of grad N_a),
//   f_a = sum_g det J_g (dev(sigma_g) grad N_a(g) + p_g b_a).
// No zero-energy modes, hence no hourglass control (state.hourglass_energy
// stays 0), and no volumetric locking (plastic flow is isochoric). Like every
// fully integrated linear hexahedron it stiffens in bending with few elements
// through the depth (parasitic shear). `gauss` holds the points' histories;
// state.point receives their mean (output, erosion). Same return and time
// levels as hex8_internal_force.
using Hex8GaussPoints = std::array<MaterialPoint, 8>;
bool hex8_full_internal_force(const MaterialParameters& material, const HexNodes& x, const HexNodes& velocity,
                              double dt_previous, Hex8State& state, Hex8GaussPoints& gauss, HexNodes& force);

// The enhanced-strain hexahedron (element_formulation = "enhanced_strain"):
// the 2 x 2 x 2 Gauss points of the fully integrated element plus Wilson's
// nine incompatible modes u += alpha_mi (1 - xi_m^2) e_i, with Taylor's
// (QM6) gradients g_m(p) = (det J_0 / det J_p) J_0^-T d(1 - xi_m^2)/d xi at
// point p, so that the constant strain patch test holds. The incompatible
// parameters are condensed in rate form with the elastic operator C:
//   alpha_dot = -H^-1 l,  H = sum_p w_p Gamma_p^T C Gamma_p,  l = sum_p w_p Gamma_p^T C D_p(v),
// giving an assumed velocity gradient L_p = grad v(p) + sum_m a_m (x) g_m(p)
// (a B-bar-type operator B~ = B - Gamma H^-1 L, linear in v, recomputed on the
// mid-step geometry each step) and the consistent forces
//   f_a = sum_p w_p (sigma_p - C : sym(sum_m s_m (x) g_m(p))) grad N_a(p),
//   s = H^-1 sum_p w_p Gamma_p^T sigma_p   (zero for an elastic body).
// Exact in pure bending of rectangular elements (the incompatible modes carry
// the parasitic shear and the Poisson strain through the depth), no
// zero-energy modes (the condensed stiffness is the Wilson/QM6 one: rank 18),
// hence no hourglass control; the volume change is not averaged (no mean
// dilatation). Same arguments, return and time levels as
// hex8_full_internal_force.
bool hex8_enhanced_internal_force(const MaterialParameters& material, const HexNodes& x, const HexNodes& velocity,
                                  double dt_previous, Hex8State& state, Hex8GaussPoints& gauss, HexNodes& force);

}  // namespace sabo::fem
