#include "fem_solver/elements/hex8.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "fem_solver/mesh/hex_mesh.hpp"
#include "libsabo/geometry/hexahedron.hpp"

namespace sabo::fem {
namespace {

constexpr std::array<std::array<double, 3>, 8> kNatural{
    {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, {-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}}};

// Hourglass vectors h1 = eta zeta, h2 = xi zeta, h3 = xi eta, h4 = xi eta zeta at the nodes.
constexpr double hourglass_vector(int alpha, int node) {
  const auto& n = kNatural[static_cast<std::size_t>(node)];
  switch (alpha) {
    case 0: return n[1] * n[2];
    case 1: return n[0] * n[2];
    case 2: return n[0] * n[1];
    default: return n[0] * n[1] * n[2];
  }
}

struct Geometry {
  Mat3 jacobian;                 // column j: d x / d xi_j at the centre (half-length vectors)
  std::array<Vec3, 8> gradient;  // grad N_a at the centre
  double volume = 0;
};

bool geometry(const HexNodes& x, Geometry& g) {
  g.jacobian.setZero();
  for (int a = 0; a < 8; ++a) {
    const auto& n = kNatural[static_cast<std::size_t>(a)];
    for (int j = 0; j < 3; ++j)
      g.jacobian.col(j) += x[static_cast<std::size_t>(a)] * (n[static_cast<std::size_t>(j)] / 8.0);
  }
  const double det = g.jacobian.determinant();
  g.volume = 8.0 * det;
  if (!(det > 0)) return false;
  const Mat3 inverse_transpose = g.jacobian.inverse().transpose();
  for (int a = 0; a < 8; ++a) {
    const auto& n = kNatural[static_cast<std::size_t>(a)];
    g.gradient[static_cast<std::size_t>(a)] = inverse_transpose * Vec3(n[0], n[1], n[2]) / 8.0;
  }
  return true;
}

// Shape function derivatives at the 2 x 2 x 2 Gauss points, d N_a / d xi_j.
struct GaussTable {
  std::array<std::array<Vec3, 8>, 8> natural_gradient;  // [g][a]
};

const GaussTable& gauss_table() {
  static const GaussTable table = [] {
    GaussTable t;
    const double r = 1.0 / std::sqrt(3.0);
    for (std::size_t g = 0; g < 8; ++g) {
      const auto& gn = kNatural[g];
      const std::array<double, 3> xi{r * gn[0], r * gn[1], r * gn[2]};
      for (std::size_t a = 0; a < 8; ++a) {
        const auto& n = kNatural[a];
        const std::array<double, 3> factor{1 + n[0] * xi[0], 1 + n[1] * xi[1], 1 + n[2] * xi[2]};
        t.natural_gradient[g][a] =
            Vec3(n[0] * factor[1] * factor[2], n[1] * factor[0] * factor[2], n[2] * factor[0] * factor[1]) / 8.0;
      }
    }
    return t;
  }();
  return table;
}

// Cartesian gradients and det J (the point's volume weight) at the Gauss points;
// false when any det J is not positive.
struct GaussGeometry {
  std::array<std::array<Vec3, 8>, 8> gradient;  // [g][a]
  std::array<double, 8> weight{};               // det J_g, m^3
  std::array<Vec3, 8> mean_gradient;            // b_a
  double volume = 0;
};

bool gauss_geometry(const HexNodes& x, GaussGeometry& g) {
  const GaussTable& table = gauss_table();
  g.volume = 0;
  for (auto& b : g.mean_gradient) b.setZero();
  for (std::size_t p = 0; p < 8; ++p) {
    Mat3 jacobian = Mat3::Zero();
    for (std::size_t a = 0; a < 8; ++a) jacobian += x[a] * table.natural_gradient[p][a].transpose();
    const double det = jacobian.determinant();
    if (!(det > 0)) return false;
    const Mat3 inverse_transpose = jacobian.inverse().transpose();
    g.weight[p] = det;
    g.volume += det;
    for (std::size_t a = 0; a < 8; ++a) {
      g.gradient[p][a] = inverse_transpose * table.natural_gradient[p][a];
      g.mean_gradient[a] += det * g.gradient[p][a];
    }
  }
  for (auto& b : g.mean_gradient) b /= g.volume;
  return true;
}

// The incompatible modes' gradients at the Gauss points of a geometry and
// their elastic condensation matrix H (factorised).
struct EnhancedGeometry {
  std::array<std::array<Vec3, 3>, 8> gradient;  // [p][m]: g_m(p), 1/m
  Eigen::LLT<Eigen::Matrix<double, 9, 9>> condensation;
};

bool enhanced_geometry(const HexNodes& x, const GaussGeometry& gauss, const MaterialParameters& material,
                       EnhancedGeometry& e) {
  Geometry centre;
  if (!geometry(x, centre)) return false;
  const double centre_det = centre.volume / 8.0;
  // Columns: grad xi_m at the centre, J_0^-T e_m.
  const Mat3 natural_gradient = centre.jacobian.inverse().transpose();
  const double r = 1.0 / std::sqrt(3.0);
  for (std::size_t p = 0; p < 8; ++p) {
    const double scale = centre_det / gauss.weight[p];
    for (std::size_t m = 0; m < 3; ++m)
      e.gradient[p][m] = (-2.0 * r * kNatural[p][m] * scale) * natural_gradient.col(static_cast<Eigen::Index>(m));
  }
  // H_(m,i)(n,j) = sum_p w_p [lambda g_m,i g_n,j + G (delta_ij g_m . g_n + g_m,j g_n,i)].
  const double lambda = material.lame_lambda(), shear = material.shear_modulus();
  Eigen::Matrix<double, 9, 9> h = Eigen::Matrix<double, 9, 9>::Zero();
  for (std::size_t p = 0; p < 8; ++p) {
    const auto& g = e.gradient[p];
    const double w = gauss.weight[p];
    for (Eigen::Index m = 0; m < 3; ++m) {
      for (Eigen::Index n = 0; n < 3; ++n) {
        const Vec3& gm = g[static_cast<std::size_t>(m)];
        const Vec3& gn = g[static_cast<std::size_t>(n)];
        const Mat3 block =
            w * (lambda * gm * gn.transpose() + shear * gm.dot(gn) * Mat3::Identity() + shear * gn * gm.transpose());
        h.block<3, 3>(3 * m, 3 * n) += block;
      }
    }
  }
  e.condensation.compute(h);
  return e.condensation.info() == Eigen::Success;
}

// sum_p w_p Gamma_p^T tau_p: component (m, i) = sum_p w_p (tau_p g_m(p))_i.
Eigen::Matrix<double, 9, 1> project_on_modes(const GaussGeometry& gauss, const EnhancedGeometry& e,
                                             const std::array<Mat3, 8>& tau) {
  Eigen::Matrix<double, 9, 1> out = Eigen::Matrix<double, 9, 1>::Zero();
  for (std::size_t p = 0; p < 8; ++p) {
    for (Eigen::Index m = 0; m < 3; ++m)
      out.segment<3>(3 * m) += gauss.weight[p] * (tau[p] * e.gradient[p][static_cast<std::size_t>(m)]);
  }
  return out;
}

// sum_m a_m (x) g_m(p): the incompatible modes' velocity (or displacement) gradient at p.
Mat3 enhanced_gradient(const EnhancedGeometry& e, std::size_t p, const Eigen::Matrix<double, 9, 1>& a) {
  Mat3 out = Mat3::Zero();
  for (Eigen::Index m = 0; m < 3; ++m)
    out += Vec3(a.segment<3>(3 * m)) * e.gradient[p][static_cast<std::size_t>(m)].transpose();
  return out;
}

// C : sym(m) for the isotropic elastic operator.
Mat3 elastic_stress(const MaterialParameters& material, const Mat3& m) {
  const Mat3 symmetric = 0.5 * (m + m.transpose());
  return material.lame_lambda() * symmetric.trace() * Mat3::Identity() + 2.0 * material.shear_modulus() * symmetric;
}

// The nodes at x_{n-1/2} = x_n - dt/2 v_{n-1/2}.
HexNodes mid_step(const HexNodes& x, const HexNodes& velocity, double dt) {
  HexNodes mid;
  for (std::size_t a = 0; a < 8; ++a) mid[a] = x[a] - 0.5 * dt * velocity[a];
  return mid;
}

// The mean of the points' histories (output, erosion).
MaterialPoint mean_point(const Hex8GaussPoints& gauss) {
  MaterialPoint mean;
  for (const MaterialPoint& point : gauss) add_weighted(mean, point, 1.0 / 8.0);
  return mean;
}

// Advances one Gauss point of volume `weight` (m^3) by D = rate and W = spin over dt and adds its stress
// work (trapezoidal in the stress) and plastic work to the element's.
void advance_point(const MaterialParameters& material, const Mat3& rate, const Mat3& spin, double dt, double weight,
                   MaterialPoint& point, Hex8State& state) {
  const Mat3 old_stress = point.stress;
  const MaterialUpdate update = update_stress(material, rate, spin, dt, point);
  state.internal_energy += dt * weight * 0.5 * (old_stress + point.stress).cwiseProduct(rate).sum();
  state.plastic_work += weight * update.plastic_work_density;
}

Mat3 deviator(const Mat3& m) {
  return m - (m.trace() / 3.0) * Mat3::Identity();
}

}  // namespace

double hex8_volume(const HexNodes& x) {
  return geometry::hexahedron_volume(x);  // the same sums as geometry(): its volume, bit for bit
}

double hex8_characteristic_length(const HexNodes& x) {
  // The centre's half-length Jacobian, summed as geometry() does: 8 det J is hex8_volume(x), bit for bit.
  Mat3 jacobian = Mat3::Zero();
  for (std::size_t a = 0; a < 8; ++a) {
    const auto& n = kNatural[a];
    for (int j = 0; j < 3; ++j) jacobian.col(j) += x[a] * (n[static_cast<std::size_t>(j)] / 8.0);
  }
  const double volume = 8.0 * jacobian.determinant();
  double largest_area = 0;
  for (const auto& face : hex_faces()) {
    const Vec3 d1 = x[static_cast<std::size_t>(face[2])] - x[static_cast<std::size_t>(face[0])];
    const Vec3 d2 = x[static_cast<std::size_t>(face[3])] - x[static_cast<std::size_t>(face[1])];
    largest_area = std::max(largest_area, 0.5 * d1.cross(d2).norm());
  }
  if (!(largest_area > 0 && volume > 0)) return 0.0;
  // V / A_max alone exceeds the critical step of a cube by 1.36 (its volumetric mode stiffens all three
  // directions at once). Flanagan & Belytschko (1981) bound the uniform-strain element's highest frequency by
  // omega^2 <= 8 c^2 sum_a |grad N_a|^2, i.e. L = 1 / sqrt(2 sum_a |grad N_a|^2) = 2 / |J^-1|_F
  // (sum_a n_a n_a^T = 8 I) [HexElement.StableStepIsBelowTheCriticalStepOfEveryShape].
  const double gradient_bound = 2.0 / jacobian.inverse().norm();
  return std::min(volume / largest_area, gradient_bound);
}

bool hex8_internal_force(const MaterialParameters& material, double hourglass_scale, const HexNodes& x,
                         const HexNodes& velocity, double dt_previous, Hex8State& state, HexNodes& force) {
  for (auto& f : force) f.setZero();
  Geometry g;
  if (dt_previous > 0) {
    const HexNodes mid = mid_step(x, velocity, dt_previous);
    Geometry gm;
    if (!geometry(mid, gm)) return false;
    Mat3 velocity_gradient = Mat3::Zero();
    for (std::size_t a = 0; a < 8; ++a) velocity_gradient += velocity[a] * gm.gradient[a].transpose();
    const Mat3 rate = 0.5 * (velocity_gradient + velocity_gradient.transpose());
    const Mat3 spin = 0.5 * (velocity_gradient - velocity_gradient.transpose());
    const Mat3 old_stress = state.point.stress;
    const MaterialUpdate update = update_stress(material, rate, spin, dt_previous, state.point);
    state.internal_energy += dt_previous * gm.volume * 0.5 * (old_stress + state.point.stress).cwiseProduct(rate).sum();
    state.plastic_work += gm.volume * update.plastic_work_density;
  }
  if (!geometry(x, g)) return false;
  state.volume = g.volume;
  for (std::size_t a = 0; a < 8; ++a) force[a] = g.volume * (state.point.stress * g.gradient[a]);

  // Hourglass: co-rotational frame from the natural axes (Gram-Schmidt).
  Mat3 frame;
  Vec3 half_length;
  for (int j = 0; j < 3; ++j) half_length(j) = g.jacobian.col(j).norm();
  frame.col(0) = g.jacobian.col(0) / half_length(0);
  const Vec3 second = g.jacobian.col(1) - frame.col(0).dot(g.jacobian.col(1)) * frame.col(0);
  frame.col(1) = second.normalized();
  frame.col(2) = frame.col(0).cross(frame.col(1));

  std::array<std::array<double, 8>, 4> gamma{};
  for (int alpha = 0; alpha < 4; ++alpha) {
    Vec3 projection = Vec3::Zero();  // h_alpha . x_j for j = x, y, z
    for (std::size_t a = 0; a < 8; ++a) projection += hourglass_vector(alpha, static_cast<int>(a)) * x[a];
    for (std::size_t a = 0; a < 8; ++a) {
      gamma[static_cast<std::size_t>(alpha)][a] =
          hourglass_vector(alpha, static_cast<int>(a)) - projection.dot(g.gradient[a]);
    }
  }
  // Generalised hourglass rates q_dot[i][alpha] = gamma_alpha . v_i / 8 (local components).
  std::array<std::array<double, 4>, 3> rate{};
  for (int i = 0; i < 3; ++i) {
    for (int alpha = 0; alpha < 4; ++alpha) {
      double sum = 0;
      for (std::size_t a = 0; a < 8; ++a)
        sum += gamma[static_cast<std::size_t>(alpha)][a] * frame.col(i).dot(velocity[a]);
      rate[static_cast<std::size_t>(i)][static_cast<std::size_t>(alpha)] = sum / 8.0;
    }
  }
  if (dt_previous > 0) {
    const double youngs = hourglass_scale * material.youngs_modulus;
    const double shear = hourglass_scale * material.shear_modulus();
    const double nu = material.poisson_ratio;
    const double plane_modulus = youngs / (1 - nu * nu);
    const double v3 = g.volume / 3.0;
    // Per axis i, the sum over the two other axes j of 1 / a_j^2 (the warping mode's shears).
    std::array<double, 3> warping_sum{};
    for (std::size_t i = 0; i < 3; ++i) {
      for (std::size_t j = 0; j < 3; ++j) {
        if (j != i)
          warping_sum[i] +=
              1.0 / (half_length(static_cast<Eigen::Index>(j)) * half_length(static_cast<Eigen::Index>(j)));
      }
    }
    std::array<std::array<double, 4>, 3> increment{};
    for (std::size_t i = 0; i < 3; ++i) {
      // Warping mode (no normal strain): its two shears with G.
      increment[i][i] = shear * v3 * warping_sum[i] * rate[i][i];
      // xi eta zeta mode: uniaxial normal strain varying as the product of the other two coordinates.
      const double li = half_length(static_cast<Eigen::Index>(i));
      increment[i][3] = youngs * g.volume / 9.0 / (li * li) * rate[i][3];
    }
    // Bending modes: for each natural coordinate k, the normal strains of the two
    // other axes varying linearly in k, in plane stress (sigma_kk = 0).
    for (std::size_t k = 0; k < 3; ++k) {
      const std::size_t a = (k + 1) % 3, b = (k + 2) % 3;
      const double la = half_length(static_cast<Eigen::Index>(a)), lb = half_length(static_cast<Eigen::Index>(b));
      const double strain_a = rate[a][b] / la, strain_b = rate[b][a] / lb;
      increment[a][b] = plane_modulus * v3 * (strain_a + nu * strain_b) / la;
      increment[b][a] = plane_modulus * v3 * (strain_b + nu * strain_a) / lb;
    }
    // Plastic materials: the stress variation a mode stands for cannot exceed
    // the current yield stress (shear modes: yield / sqrt 3); the generalised
    // force is capped at that level, like a radial return per mode.
    std::array<std::array<double, 4>, 3> limit{};
    for (auto& row : limit) row.fill(std::numeric_limits<double>::infinity());
    if (material.plastic()) {
      const double yield =
          material.yield_stress + material.hardening * material.hardening_modulus() * state.point.plastic_strain;
      for (std::size_t i = 0; i < 3; ++i) {
        const double li = half_length(static_cast<Eigen::Index>(i));
        for (std::size_t alpha = 0; alpha < 3; ++alpha) {
          limit[i][alpha] = alpha == i ? yield / std::sqrt(3.0) * v3 * std::sqrt(warping_sum[i]) : yield * v3 / li;
        }
        limit[i][3] = yield * g.volume / 9.0 / li;
      }
    }
    for (std::size_t i = 0; i < 3; ++i) {
      for (std::size_t alpha = 0; alpha < 4; ++alpha) {
        double& q_force = state.hourglass[i * 4 + alpha];
        const double old = q_force;
        q_force = std::clamp(q_force + increment[i][alpha] * dt_previous, -limit[i][alpha], limit[i][alpha]);
        state.hourglass_energy += 0.5 * (old + q_force) * rate[i][alpha] * dt_previous;
      }
    }
  }
  std::array<Vec3, 8> local_force;
  for (auto& f : local_force) f.setZero();
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t alpha = 0; alpha < 4; ++alpha) {
      const double q_force = state.hourglass[i * 4 + alpha];
      for (std::size_t a = 0; a < 8; ++a)
        local_force[a](static_cast<Eigen::Index>(i)) += q_force * gamma[alpha][a] / 8.0;
    }
  }
  for (std::size_t a = 0; a < 8; ++a) force[a] += frame * local_force[a];
  return true;
}

bool hex8_full_internal_force(const MaterialParameters& material, const HexNodes& x, const HexNodes& velocity,
                              double dt_previous, Hex8State& state, Hex8GaussPoints& gauss, HexNodes& force) {
  for (auto& f : force) f.setZero();
  if (dt_previous > 0) {
    const HexNodes mid = mid_step(x, velocity, dt_previous);
    GaussGeometry gm;
    if (!gauss_geometry(mid, gm)) return false;
    double mean_divergence = 0;
    for (std::size_t a = 0; a < 8; ++a) mean_divergence += velocity[a].dot(gm.mean_gradient[a]);
    for (std::size_t p = 0; p < 8; ++p) {
      Mat3 velocity_gradient = Mat3::Zero();
      for (std::size_t a = 0; a < 8; ++a) velocity_gradient += velocity[a] * gm.gradient[p][a].transpose();
      const Mat3 rate = deviator(0.5 * (velocity_gradient + velocity_gradient.transpose())) +
                        (mean_divergence / 3.0) * Mat3::Identity();
      const Mat3 spin = 0.5 * (velocity_gradient - velocity_gradient.transpose());
      advance_point(material, rate, spin, dt_previous, gm.weight[p], gauss[p], state);
    }
  }
  GaussGeometry g;
  if (!gauss_geometry(x, g)) return false;
  state.volume = g.volume;
  for (std::size_t p = 0; p < 8; ++p) {
    const Mat3& stress = gauss[p].stress;
    const Mat3 stress_deviator = deviator(stress);
    const double pressure_weight = g.weight[p] * stress.trace() / 3.0;
    for (std::size_t a = 0; a < 8; ++a)
      force[a] += g.weight[p] * (stress_deviator * g.gradient[p][a]) + pressure_weight * g.mean_gradient[a];
  }
  state.point = mean_point(gauss);
  return true;
}

bool hex8_enhanced_internal_force(const MaterialParameters& material, const HexNodes& x, const HexNodes& velocity,
                                  double dt_previous, Hex8State& state, Hex8GaussPoints& gauss, HexNodes& force) {
  for (auto& f : force) f.setZero();
  if (dt_previous > 0) {
    const HexNodes mid = mid_step(x, velocity, dt_previous);
    GaussGeometry gm;
    EnhancedGeometry em;
    if (!gauss_geometry(mid, gm) || !enhanced_geometry(mid, gm, material, em)) return false;
    std::array<Mat3, 8> velocity_gradient, elastic_rate;
    for (std::size_t p = 0; p < 8; ++p) {
      velocity_gradient[p].setZero();
      for (std::size_t a = 0; a < 8; ++a) velocity_gradient[p] += velocity[a] * gm.gradient[p][a].transpose();
      elastic_rate[p] = elastic_stress(material, velocity_gradient[p]);
    }
    const Eigen::Matrix<double, 9, 1> mode_rate = -em.condensation.solve(project_on_modes(gm, em, elastic_rate));
    for (std::size_t p = 0; p < 8; ++p) {
      const Mat3 gradient = velocity_gradient[p] + enhanced_gradient(em, p, mode_rate);
      const Mat3 rate = 0.5 * (gradient + gradient.transpose());
      const Mat3 spin = 0.5 * (gradient - gradient.transpose());
      advance_point(material, rate, spin, dt_previous, gm.weight[p], gauss[p], state);
    }
  }
  GaussGeometry g;
  EnhancedGeometry e;
  if (!gauss_geometry(x, g) || !enhanced_geometry(x, g, material, e)) return false;
  state.volume = g.volume;
  std::array<Mat3, 8> stress;
  for (std::size_t p = 0; p < 8; ++p) stress[p] = gauss[p].stress;
  const Eigen::Matrix<double, 9, 1> residual = e.condensation.solve(project_on_modes(g, e, stress));
  for (std::size_t p = 0; p < 8; ++p) {
    const Mat3 effective = stress[p] - elastic_stress(material, enhanced_gradient(e, p, residual));
    for (std::size_t a = 0; a < 8; ++a) force[a] += g.weight[p] * (effective * g.gradient[p][a]);
  }
  state.point = mean_point(gauss);
  return true;
}

}  // namespace sabo::fem
