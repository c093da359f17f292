#pragma once
// A sphere settling in a closed square tank of Newtonian fluid through the
// boundary_particles SPH-DEM pair, fluid and sphere coupled in one process
// (sph_dem_harness.hpp): its terminal speed and drag coefficient against
// Schiller-Naumann, Cd = 24 / Re (1 + 0.15 Re^0.687), corrected for the tank's
// walls by Di Felice's factor. Used by bench/sph_dem_drag.cpp and
// tests/coupler/test_sph_dem_drag.cpp.
//
// The fluid carries no gravity: the sphere is pushed down by its submerged
// weight (m - m_f) g, and a background pressure p0 keeps the fluid's pressure
// positive behind it. For an incompressible fluid that is the settling sphere
// exactly (the hydrostatic pressure only adds the buoyancy m_f g); it spares the
// weakly compressible fluid the sound speed c >= 10 sqrt(g H) a hydrostatic
// column needs (at Re = 1 that is 14 times the flow's own 10 v) and the tank's
// compression along its height, and keeps the wall pressure's clamp at 0 from
// cutting the suction behind the sphere.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "tests/support/sph_dem_harness.hpp"
#include "tests/support/sph_scenes.hpp"

namespace sabo::testing {

// Schiller-Naumann (1933), 0 < Re < 800.
double schiller_naumann(double re);

// Di Felice (1996), Int. J. Multiphase Flow 22, 527-533: the terminal speed of a sphere on the axis of a
// cylinder over the unbounded one, ((1 - l) / (1 - 0.33 l))^a, a = (3.3 + 0.085 Re) / (1 + 0.1 Re),
// l = D / D_cylinder (fitted for 0.08 < l < 0.7, 0.1 < Re < 1000 against Haberman-Sayre's creeping flow and
// experiments). The square tank of side W is taken as the cylinder of its area, D_cylinder = 2 W / sqrt(pi).
double di_felice(double lambda, double re);
double equivalent_lambda(double diameter, double width);

struct DragCase {
  double reynolds = 10;          // target Re = rho_f v D / mu of the sphere in unbounded fluid (Schiller-Naumann)
  double diameter_spacings = 8;  // D / dx
  double tank_diameters = 4;     // tank width / D (square section)
  double tank_height = 8;        // tank height / D
  double start_depth = 1.5;      // the sphere's centre below the lid at the start, D
  double floor_clearance = 2.0;  // the run stops once the centre is this close to the floor, D
  double density_ratio = 2.0;    // rho_s / rho_f
  double mach = 0.1;             // c >= v_inf / mach (and not below what makes the acoustic step the viscous one)
  double background = 0.05;      // background pressure / (rho_f c^2)
  double cfl = 0.25;
  double window = 1.0;      // the steadiness window, in D / v_pred (the time to fall a diameter)
  double tolerance = 0.01;  // steady: the mean speed of the last window within this of the window before
  double max_time = 40.0;   // D / v_pred
  double smoothing_ratio = 1.5;
  double artificial_viscosity = 0.0;
  scene::SphSettings::ViscousOperator viscous_operator = scene::SphSettings::ViscousOperator::strain_rate;
  scene::SphSettings::DensityDiffusion density_diffusion = scene::SphSettings::DensityDiffusion::fourtakas;
};

struct DragResult {
  // Set-up.
  double dx = 0, diameter = 0, width = 0, height = 0, viscosity = 0, sound_speed = 0, background = 0;
  double rho_f = 1000, rho_s = 0, g = 9.81;
  std::size_t fluid_particles = 0, wall_particles = 0, sphere_particles = 0;
  // Prediction: unbounded Schiller-Naumann speed, wall factor, and in the tank.
  double v_inf = 0, wall_factor = 0, v_pred = 0, lambda = 0;
  // Measured over the last window.
  bool steady = false;
  std::string stop;  // why the run ended
  double time = 0, travel = 0, v = 0, drift = 0, force = 0, submerged_weight = 0;
  std::uint64_t steps = 0;
  double re = 0, cd_balance = 0, cd_force = 0;
  // The measured Cd brought to the unbounded sphere: Re / f and Cd f^2, f at that Re; against SN there.
  double re_unbounded = 0, f_measured = 0, cd_unbounded = 0, cd_sn = 0;
  double wall_seconds = 0, sph_seconds = 0, pair_seconds = 0, dem_seconds = 0;
  [[nodiscard]] double cd_error() const { return cd_unbounded / cd_sn - 1.0; }
  [[nodiscard]] double speed_error() const { return v / v_pred - 1.0; }
};

struct DragSample {
  double t, z, v, force;
};

// Runs the case; on_sample(sample) every `report` D / v_pred (0: never).
DragResult run_drag(const DragCase& c, double report = 0, const std::function<void(const DragSample&)>& on_sample = {});

// The no-slip of the sphere's curved surface alone: the sphere held in place at the centre of a closed cube of
// fluid at rest and spun at a fixed rate Omega about z, at a rotational Reynolds number Omega R^2 / nu. Its
// creeping-flow torque is Stokes' rotlet 8 pi mu R^3 Omega, here for the sphere inside a fixed concentric
// sphere of the cube's volume (R_o), 8 pi mu R^3 Omega / (1 - (R / R_o)^3). The torque is averaged over the
// last quarter of the run (`end_time` viscous times R^2 / nu; after one the torque is steady to 1 %).
struct SpinCase {
  double diameter_spacings = 10;  // D / dx
  double box_diameters = 4;       // cube side / D
  double reynolds = 0.1;          // Omega R^2 / nu
  double end_time = 1.0;          // R^2 / nu
  double cfl = 0.5;
  scene::SphSettings::ViscousOperator viscous_operator = scene::SphSettings::ViscousOperator::strain_rate;
};

struct SpinResult {
  double torque = 0, expected = 0, time = 0, wall_seconds = 0;
  std::size_t fluid_particles = 0;
  std::uint64_t steps = 0;
  [[nodiscard]] double error() const { return torque / expected - 1.0; }
};

SpinResult run_spin(const SpinCase& c);

}  // namespace sabo::testing
