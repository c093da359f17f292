#pragma once
// Constitutive update of the structures' materials (docs/model.md, "Materials of the Wenjia model"):
// isotropic linear elasticity, and LS-DYNA's MAT_PLASTIC_KINEMATIC (MAT_003):
// bilinear J2 plasticity with yield stress sigma_0, tangent modulus E_t,
// hardening mixed between kinematic (beta = 0) and isotropic (beta = 1), an
// optional Cowper-Symonds rate factor 1 + (rate / C)^(1/p), and failure at a
// plastic strain or a maximum principal strain.
//
// Hypoelastic, objective (Jaumann) rate form for large deformation: the stress
// and back stress are first rotated by the spin W over dt, then advanced by the
// rate of deformation D with a radial return (closed form for linear hardening):
//   E_p = E E_t / (E - E_t)                    plastic hardening modulus
//   sigma_y = R (sigma_0 + beta E_p eps_p)     R = 1 + (eps_dot / C)^(1/p), or 1
//   d eps_p = (q_trial - sigma_y) / (3 G + (1 - beta) E_p + R beta E_p)
//   back stress += (2/3) (1 - beta) E_p d eps_p * flow direction
// with q_trial the von Mises stress of the trial deviator relative to the back
// stress, eps_dot = sqrt(2/3 D':D') the effective total strain rate.
#include <limits>

#include "libsabo/core/types.hpp"

namespace sabo::fem {

struct MaterialParameters {
  double density = 0;         // kg/m^3
  double youngs_modulus = 0;  // Pa
  double poisson_ratio = 0;
  double yield_stress = std::numeric_limits<double>::infinity();  // Pa; infinite: elastic
  double tangent_modulus = 0;                                     // Pa, in [0, E)
  double hardening = 0;                                           // beta: 0 kinematic, 1 isotropic
  double cowper_symonds_c = 0;                                    // 1/s; 0: no rate effect
  double cowper_symonds_p = 1;
  double failure_plastic_strain = 0;    // 0: none
  double failure_principal_strain = 0;  // 0: none; maximum principal (total) strain

  [[nodiscard]] bool plastic() const { return yield_stress < std::numeric_limits<double>::infinity(); }
  [[nodiscard]] bool erodes() const { return failure_plastic_strain > 0 || failure_principal_strain > 0; }
  [[nodiscard]] double shear_modulus() const { return youngs_modulus / (2 * (1 + poisson_ratio)); }
  [[nodiscard]] double bulk_modulus() const { return youngs_modulus / (3 * (1 - 2 * poisson_ratio)); }
  // E_p = E E_t / (E - E_t), Pa: the plastic hardening modulus (0 without a tangent modulus).
  [[nodiscard]] double hardening_modulus() const {
    return tangent_modulus > 0 ? youngs_modulus * tangent_modulus / (youngs_modulus - tangent_modulus) : 0.0;
  }
  [[nodiscard]] double lame_lambda() const {
    return youngs_modulus * poisson_ratio / ((1 + poisson_ratio) * (1 - 2 * poisson_ratio));
  }
  // Dilatational wave speed sqrt((lambda + 2 G) / rho), m/s: the explicit step limit of solids.
  [[nodiscard]] double wave_speed() const;
  // Plate wave speed sqrt(E / (rho (1 - nu^2))), m/s: the limit of shells.
  [[nodiscard]] double plate_wave_speed() const;
};

// The history of one integration point.
struct MaterialPoint {
  Mat3 stress = Mat3::Zero();       // Cauchy, Pa
  Mat3 back_stress = Mat3::Zero();  // Pa (deviatoric)
  Mat3 strain = Mat3::Zero();       // total logarithmic-like strain, integrated from D (rotated with the spin)
  double plastic_strain = 0;        // effective plastic strain
};

// sum += weight * point, field by field (means over integration points).
inline void add_weighted(MaterialPoint& sum, const MaterialPoint& point, double weight) {
  sum.stress += weight * point.stress;
  sum.back_stress += weight * point.back_stress;
  sum.strain += weight * point.strain;
  sum.plastic_strain += weight * point.plastic_strain;
}

struct MaterialUpdate {
  double plastic_work_density = 0;  // J/m^3 dissipated in this update
  bool yielded = false;
};

// Advances `point` by the velocity gradient split into D (symmetric) and W
// (skew) over dt (s).
MaterialUpdate update_stress(const MaterialParameters& material, const Mat3& rate_of_deformation, const Mat3& spin,
                             double dt, MaterialPoint& point);

// Largest principal value of a symmetric tensor.
[[nodiscard]] double max_principal(const Mat3& symmetric);
[[nodiscard]] double von_mises(const Mat3& stress);

// Whether the point has reached a failure criterion of `material`.
[[nodiscard]] bool failed(const MaterialParameters& material, const MaterialPoint& point);

}  // namespace sabo::fem
