#pragma once
// Material shared by the FEM tests.
#include "fem_solver/materials/plastic_kinematic.hpp"

namespace sabo::fem::test {

// Elastic structural steel.
inline MaterialParameters steel() {
  MaterialParameters m;
  m.density = 7850;
  m.youngs_modulus = 210e9;
  m.poisson_ratio = 0.3;
  return m;
}

}  // namespace sabo::fem::test
