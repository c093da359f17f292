#include "libsabo/geometry/hexahedron.hpp"

#include <Eigen/Dense>

namespace sabo::geometry {

double hexahedron_volume(const std::array<Vec3, 8>& x) {
  static constexpr std::array<std::array<double, 3>, 8> kNatural{
      {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, {-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}}};
  // The half-length Jacobian at the centre, column j = d x / d xi_j, summed node by node.
  Mat3 jacobian = Mat3::Zero();
  for (std::size_t a = 0; a < 8; ++a) {
    for (int j = 0; j < 3; ++j) jacobian.col(j) += x[a] * (kNatural[a][static_cast<std::size_t>(j)] / 8.0);
  }
  return 8.0 * jacobian.determinant();
}

}  // namespace sabo::geometry
