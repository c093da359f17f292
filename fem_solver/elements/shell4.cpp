#include "fem_solver/elements/shell4.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace sabo::fem {
namespace {

// 5-point Gauss-Lobatto rule on [-1, 1].
constexpr std::array<double, kThicknessPoints> kZeta{-1.0, -0.6546536707079771, 0.0, 0.6546536707079771, 1.0};
constexpr std::array<double, kThicknessPoints> kWeight{0.1, 49.0 / 90.0, 32.0 / 45.0, 49.0 / 90.0, 0.1};
constexpr std::array<double, 4> kHourglass{1, -1, 1, -1};
constexpr double kShearFactor = 5.0 / 6.0;
constexpr double kHourglassCoefficient = 0.05;

struct Frame {
  Mat3 axes;                       // columns e1, e2, e3
  std::array<double, 4> x{}, y{};  // local in-plane coordinates of the nodes
  std::array<double, 4> b1{}, b2{};
  double area = 0;
};

bool frame_of(const QuadNodes& p, Frame& f) {
  const Vec3 normal = (p[2] - p[0]).cross(p[3] - p[1]);
  if (!(normal.norm() > 0)) return false;
  const Vec3 e3 = normal.normalized();
  Vec3 e1 = (p[1] - p[0]) - (p[1] - p[0]).dot(e3) * e3;
  if (!(e1.norm() > 0)) return false;
  e1.normalize();
  const Vec3 e2 = e3.cross(e1);
  f.axes.col(0) = e1;
  f.axes.col(1) = e2;
  f.axes.col(2) = e3;
  const Vec3 centre = 0.25 * (p[0] + p[1] + p[2] + p[3]);
  for (std::size_t a = 0; a < 4; ++a) {
    f.x[a] = (p[a] - centre).dot(e1);
    f.y[a] = (p[a] - centre).dot(e2);
  }
  f.area = 0.5 * ((f.x[2] - f.x[0]) * (f.y[3] - f.y[1]) + (f.x[1] - f.x[3]) * (f.y[2] - f.y[0]));
  if (!(f.area > 0)) return false;
  const double s = 1.0 / (2.0 * f.area);
  f.b1 = {s * (f.y[1] - f.y[3]), s * (f.y[2] - f.y[0]), s * (f.y[3] - f.y[1]), s * (f.y[0] - f.y[2])};
  f.b2 = {s * (f.x[3] - f.x[1]), s * (f.x[0] - f.x[2]), s * (f.x[1] - f.x[3]), s * (f.x[2] - f.x[0])};
  return true;
}

// Plane stress: the thickness strain rate is solved so that sigma_zz = 0.
MaterialUpdate plane_stress_update(const MaterialParameters& material, double dxx, double dyy, double dxy, double dt,
                                   MaterialPoint& point) {
  const double nu = material.poisson_ratio;
  const double constrained = material.lame_lambda() + 2.0 * material.shear_modulus();
  Mat3 d = Mat3::Zero();
  d(0, 0) = dxx;
  d(1, 1) = dyy;
  d(0, 1) = d(1, 0) = dxy;
  d(2, 2) = -nu / (1.0 - nu) * (dxx + dyy) - point.stress(2, 2) / (constrained * dt);
  MaterialPoint trial;
  MaterialUpdate update;
  for (int iteration = 0; iteration < 6; ++iteration) {
    trial = point;
    update = update_stress(material, d, Mat3::Zero(), dt, trial);
    if (std::abs(trial.stress(2, 2)) <= 1e-9 * (std::abs(trial.stress(0, 0)) + std::abs(trial.stress(1, 1)) + 1.0)) {
      break;
    }
    d(2, 2) -= trial.stress(2, 2) / (constrained * dt);
  }
  trial.stress(2, 2) = 0;
  point = trial;
  return update;
}

}  // namespace

double shell4_area(const QuadNodes& x) {
  Frame f;
  return frame_of(x, f) ? f.area : 0.0;
}

double shell4_characteristic_length(const QuadNodes& x) {
  // Area / longest side exceeds a square element's critical step by 1.14 (its in-plane areal mode); the
  // longest diagonal keeps it below [Shell.FullyIntegratedCriticalStepAsOnePoint].
  double longest = std::max((x[2] - x[0]).norm(), (x[3] - x[1]).norm());
  for (std::size_t a = 0; a < 4; ++a) longest = std::max(longest, (x[(a + 1) % 4] - x[a]).norm());
  const double area = shell4_area(x);
  return longest > 0 ? area / longest : 0.0;
}

bool shell4_internal_force(const MaterialParameters& material, double thickness, double hourglass_scale,
                           const QuadNodes& x, const QuadNodes& velocity, const QuadNodes& angular_velocity,
                           double dt_previous, Shell4State& state, QuadNodes& force, QuadNodes& moment) {
  for (auto& f : force) f.setZero();
  for (auto& m : moment) m.setZero();
  Frame f;
  if (!frame_of(x, f)) return false;
  state.area = f.area;
  // Local velocities and angular velocities.
  std::array<Vec3, 4> v, w;
  for (std::size_t a = 0; a < 4; ++a) {
    v[a] = f.axes.transpose() * velocity[a];
    w[a] = f.axes.transpose() * angular_velocity[a];
  }
  double m_dxx = 0, m_dyy = 0, m_dxy2 = 0, b_dxx = 0, b_dyy = 0, b_dxy2 = 0, s_xz2 = 0, s_yz2 = 0;
  for (std::size_t a = 0; a < 4; ++a) {
    m_dxx += f.b1[a] * v[a].x();
    m_dyy += f.b2[a] * v[a].y();
    m_dxy2 += f.b2[a] * v[a].x() + f.b1[a] * v[a].y();
    b_dxx += f.b1[a] * w[a].y();
    b_dyy -= f.b2[a] * w[a].x();
    b_dxy2 += f.b2[a] * w[a].y() - f.b1[a] * w[a].x();
    s_xz2 += f.b1[a] * v[a].z() + 0.25 * w[a].y();
    s_yz2 += f.b2[a] * v[a].z() - 0.25 * w[a].x();
  }
  const double half = 0.5 * thickness;
  const double shear = material.shear_modulus();
  if (dt_previous > 0) {
    double power = 0;
    for (std::size_t k = 0; k < kThicknessPoints; ++k) {
      const double z = kZeta[k] * half, weight = kWeight[k] * half;
      const double dxx = m_dxx + z * b_dxx, dyy = m_dyy + z * b_dyy, dxy = 0.5 * (m_dxy2 + z * b_dxy2);
      MaterialPoint& p = state.point[k];
      const Mat3 old = p.stress;
      const MaterialUpdate update = plane_stress_update(material, dxx, dyy, dxy, dt_previous, p);
      const Mat3 mid = 0.5 * (old + p.stress);
      power += weight * (mid(0, 0) * dxx + mid(1, 1) * dyy + 2.0 * mid(0, 1) * dxy);
      state.plastic_work += f.area * weight * update.plastic_work_density;
    }
    const double old_x = state.shear_x, old_y = state.shear_y;
    state.shear_x += kShearFactor * shear * thickness * s_xz2 * dt_previous;
    state.shear_y += kShearFactor * shear * thickness * s_yz2 * dt_previous;
    power += 0.5 * (old_x + state.shear_x) * s_xz2 + 0.5 * (old_y + state.shear_y) * s_yz2;
    state.internal_energy += f.area * power * dt_previous;
  }
  // Resultants per unit length: membrane N and moment M.
  double nxx = 0, nyy = 0, nxy = 0, mxx = 0, myy = 0, mxy = 0;
  for (std::size_t k = 0; k < kThicknessPoints; ++k) {
    const double z = kZeta[k] * half, weight = kWeight[k] * half;
    const Mat3& s = state.point[k].stress;
    nxx += weight * s(0, 0);
    nyy += weight * s(1, 1);
    nxy += weight * s(0, 1);
    mxx += weight * z * s(0, 0);
    myy += weight * z * s(1, 1);
    mxy += weight * z * s(0, 1);
  }
  const double qx = state.shear_x, qy = state.shear_y;
  std::array<Vec3, 4> local_force, local_moment;
  for (std::size_t a = 0; a < 4; ++a) {
    const double b1 = f.b1[a], b2 = f.b2[a];
    local_force[a] = f.area * Vec3(b1 * nxx + b2 * nxy, b2 * nyy + b1 * nxy, b1 * qx + b2 * qy);
    local_moment[a] = f.area * Vec3(-b2 * myy - b1 * mxy - 0.25 * qy, b1 * mxx + b2 * mxy + 0.25 * qx, 0.0);
  }
  // Hourglass control.
  std::array<double, 4> gamma{};
  double hx = 0, hy = 0, bb = 0;
  for (std::size_t a = 0; a < 4; ++a) {
    hx += kHourglass[a] * f.x[a];
    hy += kHourglass[a] * f.y[a];
    bb += f.b1[a] * f.b1[a] + f.b2[a] * f.b2[a];
  }
  for (std::size_t a = 0; a < 4; ++a) gamma[a] = kHourglass[a] - hx * f.b1[a] - hy * f.b2[a];
  std::array<double, 5> rate{};
  for (std::size_t a = 0; a < 4; ++a) {
    rate[0] += gamma[a] * v[a].x();
    rate[1] += gamma[a] * v[a].y();
    rate[2] += gamma[a] * v[a].z();
    rate[3] += gamma[a] * w[a].x();
    rate[4] += gamma[a] * w[a].y();
  }
  const double c = kHourglassCoefficient * hourglass_scale;
  const double bending = material.youngs_modulus * thickness * thickness * thickness / 12.0;
  const std::array<double, 5> stiffness{c * material.youngs_modulus * thickness * f.area * bb / 4.0,
                                        c * material.youngs_modulus * thickness * f.area * bb / 4.0,
                                        c * bending * f.area * bb * bb / 4.0, c * bending * f.area * bb / 4.0,
                                        c * bending * f.area * bb / 4.0};
  if (dt_previous > 0) {
    for (std::size_t k = 0; k < 5; ++k) {
      const double old = state.hourglass[k];
      state.hourglass[k] += stiffness[k] * rate[k] * dt_previous;
      state.hourglass_energy += 0.5 * (old + state.hourglass[k]) * rate[k] * dt_previous;
    }
  }
  for (std::size_t a = 0; a < 4; ++a) {
    local_force[a] += gamma[a] * Vec3(state.hourglass[0], state.hourglass[1], state.hourglass[2]);
    local_moment[a] += gamma[a] * Vec3(state.hourglass[3], state.hourglass[4], 0.0);
    force[a] = f.axes * local_force[a];
    moment[a] = f.axes * local_moment[a];
  }
  return true;
}

namespace {

constexpr double kGaussCoordinate = 0.5773502691896257;  // 1 / sqrt(3)
constexpr std::array<double, 4> kNodeXi{-1, 1, 1, -1}, kNodeEta{-1, -1, 1, 1};

// Local nodal rates, 5 per node: v_x, v_y, v_z, w_x, w_y (the drilling w_z apart).
using NodalRates = Eigen::Matrix<double, 20, 1>;
// Generalised strain rates from the nodal rates: membrane d_xx, d_yy, 2 d_xy,
// curvatures k_xx, k_yy, 2 k_xy, transverse shears g_xz, g_yz.
using StrainMap = Eigen::Matrix<double, 8, 20>;
using ShearRow = Eigen::Matrix<double, 1, 20>;

// Covariant transverse shear rate g_xi (along_xi) or g_eta at (xi, eta): the
// derivative of v_z plus the rotated normal's in-plane velocity (w_y, -w_x)
// projected on the natural base vector.
ShearRow covariant_shear(const Frame& f, double xi, double eta, bool along_xi) {
  std::array<double, 4> n{}, dn{};
  double dx = 0, dy = 0;
  for (std::size_t a = 0; a < 4; ++a) {
    n[a] = 0.25 * (1 + kNodeXi[a] * xi) * (1 + kNodeEta[a] * eta);
    dn[a] = along_xi ? 0.25 * kNodeXi[a] * (1 + kNodeEta[a] * eta) : 0.25 * kNodeEta[a] * (1 + kNodeXi[a] * xi);
    dx += dn[a] * f.x[a];
    dy += dn[a] * f.y[a];
  }
  ShearRow row = ShearRow::Zero();
  for (std::size_t a = 0; a < 4; ++a) {
    const auto i = static_cast<Eigen::Index>(5 * a);
    row(i + 2) = dn[a];
    row(i + 3) = -n[a] * dy;
    row(i + 4) = n[a] * dx;
  }
  return row;
}

}  // namespace

bool shell4_full_internal_force(const MaterialParameters& material, double thickness, const QuadNodes& x,
                                const QuadNodes& velocity, const QuadNodes& angular_velocity, double dt_previous,
                                Shell4State& state, Shell4GaussPoints& gauss, QuadNodes& force, QuadNodes& moment) {
  for (auto& f : force) f.setZero();
  for (auto& m : moment) m.setZero();
  Frame f;
  if (!frame_of(x, f)) return false;
  NodalRates rate;
  std::array<double, 4> drilling_rate{};
  for (std::size_t a = 0; a < 4; ++a) {
    const Vec3 v = f.axes.transpose() * velocity[a], w = f.axes.transpose() * angular_velocity[a];
    const auto i = static_cast<Eigen::Index>(5 * a);
    rate.segment<3>(i) = v;
    rate(i + 3) = w.x();
    rate(i + 4) = w.y();
    drilling_rate[a] = w.z();
  }
  // MITC4 tying points: g_xi at the edge midpoints eta = -1, +1; g_eta at xi = -1, +1.
  const ShearRow xi_low = covariant_shear(f, 0, -1, true), xi_high = covariant_shear(f, 0, 1, true);
  const ShearRow eta_low = covariant_shear(f, -1, 0, false), eta_high = covariant_shear(f, 1, 0, false);
  const double half = 0.5 * thickness, shear_stiffness = kShearFactor * material.shear_modulus() * thickness;
  // The strain maps of the Gauss points first: a degenerate element changes no state.
  std::array<StrainMap, 4> maps;
  std::array<double, 4> jacobian{};
  for (std::size_t g = 0; g < 4; ++g) {
    const double xi = kGaussCoordinate * kNodeXi[g], eta = kGaussCoordinate * kNodeEta[g];
    std::array<double, 4> dxi{}, deta{};
    double x_xi = 0, y_xi = 0, x_eta = 0, y_eta = 0;
    for (std::size_t a = 0; a < 4; ++a) {
      dxi[a] = 0.25 * kNodeXi[a] * (1 + kNodeEta[a] * eta);
      deta[a] = 0.25 * kNodeEta[a] * (1 + kNodeXi[a] * xi);
      x_xi += dxi[a] * f.x[a];
      y_xi += dxi[a] * f.y[a];
      x_eta += deta[a] * f.x[a];
      y_eta += deta[a] * f.y[a];
    }
    const double det = x_xi * y_eta - y_xi * x_eta;
    if (!(det > 0)) return false;
    // Inverse Jacobian: (d/dx, d/dy) = J^-1 (d/dxi, d/deta), J rows (x_xi, y_xi), (x_eta, y_eta).
    const double j11 = y_eta / det, j12 = -y_xi / det, j21 = -x_eta / det, j22 = x_xi / det;
    StrainMap b = StrainMap::Zero();
    for (std::size_t a = 0; a < 4; ++a) {
      const double nx = j11 * dxi[a] + j12 * deta[a], ny = j21 * dxi[a] + j22 * deta[a];
      const auto i = static_cast<Eigen::Index>(5 * a);
      b(0, i) = nx;
      b(1, i + 1) = ny;
      b(2, i) = ny;
      b(2, i + 1) = nx;
      b(3, i + 4) = nx;
      b(4, i + 3) = -ny;
      b(5, i + 3) = -nx;
      b(5, i + 4) = ny;
    }
    const ShearRow g_xi = 0.5 * (1 - eta) * xi_low + 0.5 * (1 + eta) * xi_high;
    const ShearRow g_eta = 0.5 * (1 - xi) * eta_low + 0.5 * (1 + xi) * eta_high;
    b.row(6) = j11 * g_xi + j12 * g_eta;
    b.row(7) = j21 * g_xi + j22 * g_eta;
    maps[g] = b;
    jacobian[g] = det;
  }
  NodalRates nodal = NodalRates::Zero();
  double work = 0, plastic_work = 0;  // J over this step
  for (std::size_t g = 0; g < 4; ++g) {
    const StrainMap& b = maps[g];
    const double det = jacobian[g];
    auto& points = gauss.point[g];
    double& q_x = gauss.shear[2 * g];
    double& q_y = gauss.shear[2 * g + 1];
    if (dt_previous > 0) {
      const Eigen::Matrix<double, 8, 1> strain = b * rate;
      double power = 0;
      for (std::size_t k = 0; k < kThicknessPoints; ++k) {
        const double z = kZeta[k] * half, weight = kWeight[k] * half;
        const double dxx = strain(0) + z * strain(3), dyy = strain(1) + z * strain(4),
                     dxy = 0.5 * (strain(2) + z * strain(5));
        const Mat3 old = points[k].stress;
        const MaterialUpdate update = plane_stress_update(material, dxx, dyy, dxy, dt_previous, points[k]);
        const Mat3 mid = 0.5 * (old + points[k].stress);
        power += weight * (mid(0, 0) * dxx + mid(1, 1) * dyy + 2.0 * mid(0, 1) * dxy);
        plastic_work += det * weight * update.plastic_work_density;
      }
      const double old_x = q_x, old_y = q_y;
      q_x += shear_stiffness * strain(6) * dt_previous;
      q_y += shear_stiffness * strain(7) * dt_previous;
      power += 0.5 * (old_x + q_x) * strain(6) + 0.5 * (old_y + q_y) * strain(7);
      work += det * power * dt_previous;
    }
    Eigen::Matrix<double, 8, 1> resultant = Eigen::Matrix<double, 8, 1>::Zero();
    for (std::size_t k = 0; k < kThicknessPoints; ++k) {
      const double z = kZeta[k] * half, weight = kWeight[k] * half;
      const Mat3& s = points[k].stress;
      resultant(0) += weight * s(0, 0);
      resultant(1) += weight * s(1, 1);
      resultant(2) += weight * s(0, 1);
      resultant(3) += weight * z * s(0, 0);
      resultant(4) += weight * z * s(1, 1);
      resultant(5) += weight * z * s(0, 1);
    }
    resultant(6) = q_x;
    resultant(7) = q_y;
    nodal.noalias() += det * (b.transpose() * resultant);
  }
  // Drilling: moments on the nodes' rotation rates about e3 relative to the element's in-plane spin.
  double spin = 0;
  for (std::size_t a = 0; a < 4; ++a)
    spin +=
        0.5 * (f.b1[a] * rate(static_cast<Eigen::Index>(5 * a + 1)) - f.b2[a] * rate(static_cast<Eigen::Index>(5 * a)));
  if (dt_previous > 0) {
    const double stiffness = kDrillingFactor * material.shear_modulus() * thickness * f.area;
    for (std::size_t a = 0; a < 4; ++a) {
      const double relative = drilling_rate[a] - spin, old = gauss.drilling[a];
      gauss.drilling[a] += stiffness * relative * dt_previous;
      const double energy = 0.5 * (old + gauss.drilling[a]) * relative * dt_previous;
      gauss.drilling_energy += energy;
      work += energy;
    }
  }
  const double drilling_sum = gauss.drilling[0] + gauss.drilling[1] + gauss.drilling[2] + gauss.drilling[3];
  for (std::size_t a = 0; a < 4; ++a) {
    const auto i = static_cast<Eigen::Index>(5 * a);
    const Vec3 local_force(nodal(i) + 0.5 * f.b2[a] * drilling_sum, nodal(i + 1) - 0.5 * f.b1[a] * drilling_sum,
                           nodal(i + 2));
    const Vec3 local_moment(nodal(i + 3), nodal(i + 4), gauss.drilling[a]);
    force[a] = f.axes * local_force;
    moment[a] = f.axes * local_moment;
  }
  state.area = f.area;
  state.internal_energy += work;
  state.plastic_work += plastic_work;
  // Means over the Gauss points, for output and the erosion criterion.
  for (std::size_t k = 0; k < kThicknessPoints; ++k) {
    MaterialPoint mean;
    for (std::size_t g = 0; g < 4; ++g) add_weighted(mean, gauss.point[g][k], 0.25);
    state.point[k] = mean;
  }
  state.shear_x = 0.25 * (gauss.shear[0] + gauss.shear[2] + gauss.shear[4] + gauss.shear[6]);
  state.shear_y = 0.25 * (gauss.shear[1] + gauss.shear[3] + gauss.shear[5] + gauss.shear[7]);
  return true;
}

}  // namespace sabo::fem
