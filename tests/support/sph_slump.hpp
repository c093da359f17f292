#pragma once
// The slump of a Bingham column on a rigid floor (docs/physics.md, "Viscosity"), shared by the
// test (tests/sph_solver/test_sph_viscosity.cpp) and bench_sph_slump (bench/sph_slump.cpp).
//
// A square column, `side` wide and `height` H tall, of Bingham slurry (Papanastasiou), rho 1000,
// at rest with its hydrostatic pressure, released on a no-slip floor of three layers of wall
// particles, Wendland C2 at h = 1.5 dx, c = 10 sqrt(g H), artificial viscosity 0.1. Stopped when
// the fastest particle has stayed below `rest_speed` for `rest_time` (the end of the collapse; a
// regularised law creeps on at about yield_shear_rate times the stress over tau_y) or at t_end.
#include <algorithm>
#include <cmath>
#include <functional>

#include "tests/support/sph_scenes.hpp"

namespace sabo::sph::testing {

struct SlumpCase {
  double dx = 0.01;              // m
  double height = 0.1;           // m, H
  double side = 0.1;             // m
  double yield_number = 0.25;    // x = sqrt(3) tau_y / (rho g H): the uniaxial (von Mises) yield over rho g H
  double plastic_viscosity = 5;  // Pa s
  double yield_shear_rate = 1;   // 1/s
  double t_end = 0.6;            // s, at most
  double rest_speed = 0.05;      // m/s ...
  double rest_time = 0.02;       // s
  double cfl = 0.25;             // sph.cfl; the step is the viscous one, cfl rho h^2 / (8 eta), eta about
                                 // tau_y / yield_shear_rate where the column is unyielded
  scene::SphSettings::ViscousOperator op = scene::SphSettings::ViscousOperator::strain_rate;
};

struct SlumpRun {
  double final_height = 0;  // m: the top of the column on its axis (the highest particle within dx of it, + dx/2)
  double spread = 0;        // m: the largest |x| or |y| of a particle, + dx/2
  double time = 0;          // s
  int steps = 0;
  bool stopped = false;  // reached rest_speed (false: t_end)
};

// The final height over H of the slump analysis (Murata 1984; Schowalter & Christensen 1998; Pashias
// et al. 1996 for a cylinder; the section's shape does not enter): the top x H of the column, where
// the weight above is below the uniaxial yield stress sigma_y = x rho g H, stays rigid; below it every
// level shortens until the weight above over its widened section is sigma_y, which puts the
// yielded part's final height at x H ln(1/x). h_f / H = x (1 - ln x). With the Tresca yield of
// those papers sigma_y = 2 tau_y; the Bingham law here is von Mises (gamma_dot = sqrt(2 D':D')), so
// sigma_y = sqrt(3) tau_y.
double slump_analysis(double yield_number);

// on_report(t, top / H, fastest particle m/s) every 0.05 s when given.
SlumpRun run_slump(const SlumpCase& c, const std::function<void(double, double, double)>& on_report = nullptr);

}  // namespace sabo::sph::testing
