#include "fem_solver/materials/plastic_kinematic.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace sabo::fem {

double MaterialParameters::wave_speed() const {
  return std::sqrt((lame_lambda() + 2 * shear_modulus()) / density);
}

double MaterialParameters::plate_wave_speed() const {
  return std::sqrt(youngs_modulus / (density * (1 - poisson_ratio * poisson_ratio)));
}

namespace {

Mat3 deviator(const Mat3& m) {
  return m - (m.trace() / 3.0) * Mat3::Identity();
}

// Jaumann rotation over dt: m + dt (W m - m W).
void rotate(Mat3& m, const Mat3& spin, double dt) {
  const Mat3 wm = spin * m;
  m += dt * (wm - wm.transpose());
}

}  // namespace

MaterialUpdate update_stress(const MaterialParameters& material, const Mat3& rate_of_deformation, const Mat3& spin,
                             double dt, MaterialPoint& point) {
  MaterialUpdate result;
  rotate(point.stress, spin, dt);
  rotate(point.strain, spin, dt);
  point.strain += dt * rate_of_deformation;

  const double shear = material.shear_modulus();
  const double bulk = material.bulk_modulus();
  const Mat3 strain_increment = dt * rate_of_deformation;
  const double volumetric = strain_increment.trace();
  const double pressure_free = point.stress.trace() / 3.0 + bulk * volumetric;  // mean stress
  Mat3 deviatoric = deviator(point.stress) + 2.0 * shear * deviator(strain_increment);

  if (material.plastic()) {
    rotate(point.back_stress, spin, dt);
    const double hardening_modulus = material.hardening_modulus();
    double rate_factor = 1.0;
    if (material.cowper_symonds_c > 0 && dt > 0) {
      const Mat3 d_dev = deviator(rate_of_deformation);
      const double strain_rate = std::sqrt(2.0 / 3.0 * d_dev.cwiseProduct(d_dev).sum());
      rate_factor += std::pow(strain_rate / material.cowper_symonds_c, 1.0 / material.cowper_symonds_p);
    }
    const double beta = material.hardening;
    const Mat3 relative = deviatoric - point.back_stress;
    const double relative_norm = std::sqrt(relative.cwiseProduct(relative).sum());
    const double trial = std::sqrt(1.5) * relative_norm;
    const double yield = rate_factor * (material.yield_stress + beta * hardening_modulus * point.plastic_strain);
    if (trial > yield) {
      const double plastic_increment =
          (trial - yield) / (3.0 * shear + (1.0 - beta) * hardening_modulus + rate_factor * beta * hardening_modulus);
      const Mat3 direction = relative / relative_norm;  // unit
      const double flow = std::sqrt(1.5) * plastic_increment;
      deviatoric -= 2.0 * shear * flow * direction;
      point.back_stress += (2.0 / 3.0) * (1.0 - beta) * hardening_modulus * flow * direction;
      point.plastic_strain += plastic_increment;
      // Work of the (returned) stress on the plastic strain increment flow * direction.
      result.plastic_work_density = flow * deviatoric.cwiseProduct(direction).sum();
      result.yielded = true;
    }
  }
  point.stress = deviatoric + pressure_free * Mat3::Identity();
  return result;
}

double max_principal(const Mat3& symmetric) {
  Eigen::SelfAdjointEigenSolver<Mat3> solver(symmetric, Eigen::EigenvaluesOnly);
  return solver.eigenvalues()(2);
}

double von_mises(const Mat3& stress) {
  const Mat3 s = deviator(stress);
  return std::sqrt(1.5 * s.cwiseProduct(s).sum());
}

bool failed(const MaterialParameters& material, const MaterialPoint& point) {
  if (material.failure_plastic_strain > 0 && point.plastic_strain >= material.failure_plastic_strain) return true;
  if (material.failure_principal_strain > 0 && max_principal(point.strain) >= material.failure_principal_strain) {
    return true;
  }
  return false;
}

}  // namespace sabo::fem
