// The SPH-DEM pairs on their own, driven by hand-made registrations and
// states: the penalty law of paper eqs. 1-2 (force, reaction, damping,
// friction, stable step, derived stiffness), the boulders' boundary particles
// (sampling, selection near the fluid, rigid motion, the returned forces summed
// into force and torque and delivered as the fluid's impulse), the boundary
// list shared with other pairs, histories that restore to the same bits, and
// the same bits on 1 and 2 threads.
#include <gtest/gtest.h>
#include <omp.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <numbers>
#include <random>

#include "coupler/contact/sph_dem_boundary_pair.hpp"
#include "coupler/contact/sph_dem_penalty_pair.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/sphere_sampling.hpp"

using namespace sabo;
using namespace sabo::coupler;

namespace {

constexpr double kDx = 0.01;          // m
constexpr double kSoundSpeed = 10.0;  // m/s
constexpr double kRadius = 0.05;      // m, the boulder

scene::Scene two_body_scene(scene::SphDemContact::Model model) {
  scene::Scene scene;
  for (auto [name, density] : {std::pair{"granite", 2650.0}, std::pair{"water", 1000.0}}) {
    scene::Material m;
    m.name = name;
    m.density = density;
    m.youngs_modulus = 30e9;
    m.poisson_ratio = 0.3;
    scene.materials.push_back(m);
  }
  scene::FluidBody water;
  water.name = "water";
  water.material = "water";
  scene.fluids.push_back(water);
  scene::ParticleSet boulders;
  boulders.name = "boulders";
  boulders.material = "granite";
  boulders.spheres.push_back({Vec3::Zero(), kRadius, Vec3::Zero(), Vec3::Zero()});
  scene.particle_sets.push_back(boulders);
  scene.sph.particle_spacing = kDx;
  scene.sph.sound_speed = kSoundSpeed;
  scene.sph_dem_default.model = model;
  for (auto role : {sabo::Role::sph, sabo::Role::dem}) scene.solvers.emplace_back().role = role;
  return scene;
}

// Registrations and states of a fluid and a DEM solver, made by hand.
struct TwoSolvers {
  sabo::v1::Register fluid_registration, sphere_registration;
  sabo::v1::StepState fluid, spheres;
  Solvers solvers;

  TwoSolvers(std::size_t fluid_particles, std::vector<double> sphere_radii, double fluid_beta = 1.0) {
    auto* ft = fluid_registration.mutable_particles();
    for (std::size_t i = 0; i < fluid_particles; ++i) {
      ft->add_id(i), ft->add_radius(0.5 * kDx), ft->add_mass(1000 * kDx * kDx * kDx), ft->add_material(1);
      ft->add_body(0);
    }
    sphere_registration.set_exposes_angular_velocity(true);
    auto* st = sphere_registration.mutable_particles();
    for (std::size_t j = 0; j < sphere_radii.size(); ++j) {
      const double r = sphere_radii[j];
      st->add_id(j), st->add_radius(r), st->add_mass(2650 * 4.0 / 3.0 * std::numbers::pi * r * r * r);
      st->add_material(0), st->add_body(0);
    }
    solvers.set({sabo::Role::sph, fluid_beta, &fluid_registration, &fluid});
    solvers.set({sabo::Role::dem, 1.0, &sphere_registration, &spheres});
  }
  void set_fluid(const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::uint64_t step) {
    fluid.Clear();
    fluid.set_step(step);
    for (std::size_t i = 0; i < x.size(); ++i) {
      fluid.add_index(static_cast<std::uint32_t>(i));
      for (int c = 0; c < 3; ++c) fluid.add_position(x[i][c]), fluid.add_velocity(v[i][c]);
    }
  }
  void set_spheres(const std::vector<Vec3>& x, const std::vector<Vec3>& v, const std::vector<Vec3>& w,
                   std::uint64_t step) {
    spheres.Clear();
    spheres.set_step(step);
    for (std::size_t j = 0; j < x.size(); ++j) {
      spheres.add_index(static_cast<std::uint32_t>(j));
      for (int c = 0; c < 3; ++c) {
        spheres.add_position(x[j][c]), spheres.add_velocity(v[j][c]), spheres.add_angular_velocity(w[j][c]);
      }
    }
  }
};

Vec3 vec3(const std::vector<double>& a, std::size_t k) {
  return {a[3 * k], a[3 * k + 1], a[3 * k + 2]};
}

// ------------------------------------------------------------- sampling --

TEST(SphereSampling, ShellsHoldTheSphereVolumeWithRadialNormalsAtTheSpacing) {
  const std::size_t layers = 3;
  const auto s = geometry::sample_sphere(kRadius, kDx, layers);
  double volume = 0;
  for (std::size_t p = 0; p < s.size(); ++p) {
    volume += s.volume[p];
    EXPECT_NEAR(s.normal[p].norm(), 1.0, 1e-12);
    EXPECT_NEAR(s.offset[p].normalized().dot(s.normal[p]), 1.0, 1e-12);
  }
  const double expected = 4.0 / 3.0 * std::numbers::pi * (std::pow(kRadius, 3) - std::pow(kRadius - layers * kDx, 3));
  std::cout << "sampled volume " << volume << " m^3, expected " << expected << " m^3 (the three outer shells)\n";
  EXPECT_NEAR(volume, expected, 1e-12 * expected);
  // Shells at (k + 1/2) dx under the surface, about 4 pi r^2 / dx^2 points each, neighbours about dx apart.
  for (std::size_t k = 0; k < layers; ++k) {
    const double r = kRadius - (static_cast<double>(k) + 0.5) * kDx;
    std::vector<Vec3> shell;
    for (const Vec3& x : s.offset) {
      if (std::abs(x.norm() - r) < 1e-9) shell.push_back(x);
    }
    EXPECT_EQ(static_cast<double>(shell.size()), std::round(4 * std::numbers::pi * r * r / (kDx * kDx)));
    double mean_nearest = 0;
    for (const Vec3& a : shell) {
      double nearest = INFINITY;
      for (const Vec3& b : shell) {
        if (&a != &b) nearest = std::min(nearest, (a - b).norm());
      }
      mean_nearest += nearest / static_cast<double>(shell.size());
    }
    std::cout << "shell " << k << ": " << shell.size() << " points, mean nearest neighbour " << mean_nearest / kDx
              << " dx (expected about 1)\n";
    EXPECT_GT(mean_nearest, 0.8 * kDx);
    EXPECT_LT(mean_nearest, 1.2 * kDx);
  }
  // A small sphere keeps the shells that fit.
  EXPECT_EQ(geometry::sample_sphere(kDx, kDx, 3).size(), 3u);  // one shell at dx/2: round(pi) points
  EXPECT_THROW((void)geometry::sample_sphere(0.0, kDx, 3), Error);
}

// ---------------------------------------------------- boundary channel --

TEST(BoundaryChannel, EachSlotReadsItsOwnPartOfTheForcesOfTheListSentThen) {
  BoundaryChannel channel;
  const std::size_t walls = channel.join(), boulders = channel.join();
  physics::BoundaryParticles two, three, one;
  two.resize(2), three.resize(3), one.resize(1);
  channel.begin_step();  // step 0 sends 2 + 3
  channel.append(walls, two);
  channel.append(boulders, three);
  EXPECT_EQ(channel.size(), 5u);
  channel.begin_step();  // step 1 sends 1 + 2
  channel.append(walls, one);
  channel.append(boulders, two);
  // At step 2, before its own list: the forces of step 1's list (steps back 1) or of step 0's (2).
  std::vector<double> of_step_1(9), of_step_0(15);
  for (std::size_t k = 0; k < of_step_1.size(); ++k) of_step_1[k] = static_cast<double>(k);
  for (std::size_t k = 0; k < of_step_0.size(); ++k) of_step_0[k] = 100.0 + static_cast<double>(k);
  EXPECT_EQ(channel.sent(1), 3u);
  EXPECT_EQ(channel.sent(2), 5u);
  const auto w1 = channel.slice(walls, of_step_1, 1), b1 = channel.slice(boulders, of_step_1, 1);
  ASSERT_EQ(w1.size(), 3u);
  ASSERT_EQ(b1.size(), 6u);
  EXPECT_EQ(w1[0], 0.0);
  EXPECT_EQ(b1[0], 3.0);
  const auto w0 = channel.slice(walls, of_step_0, 2), b0 = channel.slice(boulders, of_step_0, 2);
  ASSERT_EQ(w0.size(), 6u);
  ASSERT_EQ(b0.size(), 9u);
  EXPECT_EQ(b0[0], 106.0);
  EXPECT_TRUE(channel.slice(walls, {}, 1).empty());
}

// ------------------------------------------------------------- penalty --

TEST(SphDemPenalty, OverlapGivesTheSpringDashpotAndItsExactReaction) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::penalty);
  scene.sph_dem_default.normal_damping_ratio = 0.2;
  SphDemPenaltyPair pair(scene);
  TwoSolvers s(1, {kRadius}, 0.8);
  Replies replies;
  pair.start(s.solvers, replies);
  const double overlap = 0.1 * kDx;
  const double d = 0.5 * kDx + kRadius - overlap;
  const Vec3 n = Vec3(1, 2, 2).normalized();
  const Vec3 v_fluid = -0.3 * n;  // approaching
  s.set_fluid({d * n}, {v_fluid}, 0);
  s.set_spheres({Vec3::Zero()}, {Vec3::Zero()}, {Vec3::Zero()}, 0);
  pair.compute(s.solvers, {0, 0.0, 0.0});

  const double k = scene.sph_dem_derived_stiffness(scene.fluids[0]);
  const double m_f = 1000 * kDx * kDx * kDx, m_s = 2650 * 4.0 / 3.0 * std::numbers::pi * std::pow(kRadius, 3);
  const double reduced = m_f * m_s / (m_f + m_s);
  const double c = 2 * 0.2 * std::sqrt(k * reduced);
  const Vec3 expected = (k * overlap + c * 0.3) * n;
  replies.begin_step(s.solvers, 0);
  pair.scatter(s.solvers, 1e-4, replies);
  const Vec3 on_fluid = vec3(replies.particle_force(sabo::Role::sph), 0);
  const Vec3 on_sphere = vec3(replies.particle_force(sabo::Role::dem), 0);
  std::cout << "force on the fluid particle " << on_fluid.transpose() << " N, expected " << expected.transpose()
            << " N (K = " << k << " N/m, K delta + eta v)\n";
  EXPECT_NEAR((on_fluid - expected).norm(), 0.0, 1e-12 * expected.norm());
  EXPECT_EQ((on_fluid + on_sphere).norm(), 0.0);
  EXPECT_LT(vec3(replies.particle_torque(sabo::Role::dem), 0).norm(), 1e-15);  // normal force: no torque
  EXPECT_EQ(pair.contact_count(), 1u);
  EXPECT_NEAR(pair.energy().elastic, 0.5 * k * overlap * overlap, 1e-15);
  EXPECT_NEAR(pair.energy().dissipated_power, c * 0.09, 1e-12);
  EXPECT_EQ(pair.newton_balance().sum.norm(), 0.0);
  EXPECT_NEAR(pair.stable_dt(), 0.8 * 0.2 * std::numbers::pi * std::sqrt(reduced / k), 1e-18);
  EXPECT_TRUE(pair.interest(sabo::Role::dem).all);
  ASSERT_FALSE(pair.interest(sabo::Role::sph).boxes.empty());
  EXPECT_TRUE(pair.interest(sabo::Role::sph).boxes[0].contains(d * n));

  // Apart: no force, but the step is limited one contact radius before contact.
  s.set_fluid({(d + 0.3 * kDx) * n}, {v_fluid}, 1);
  pair.compute(s.solvers, {1, 1e-4, 1e-4});
  EXPECT_EQ(pair.contact_count(), 0u);
  EXPECT_TRUE(std::isfinite(pair.stable_dt()));
  s.set_fluid({(d + 1.2 * kDx) * n}, {v_fluid}, 2);
  pair.compute(s.solvers, {2, 2e-4, 1e-4});
  EXPECT_TRUE(std::isinf(pair.stable_dt()));
}

TEST(SphDemPenalty, FrictionCapsTheTangentialForceAndTurnsTheSphere) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::penalty);
  scene.sph_dem_default.friction = 0.4;
  SphDemPenaltyPair pair(scene);
  TwoSolvers s(1, {kRadius});
  Replies replies;
  pair.start(s.solvers, replies);
  const double overlap = 0.2 * kDx, d = 0.5 * kDx + kRadius - overlap;
  const double k = scene.sph_dem_derived_stiffness(scene.fluids[0]);
  // The particle slides over the sphere's top along x for several steps: the spring grows to the cap.
  const double dt = 1e-4;
  Vec3 on_fluid, torque;
  for (std::uint64_t step = 0; step < 40; ++step) {
    s.set_fluid({Vec3(0, 0, d)}, {Vec3(1.0, 0, 0)}, step);
    s.set_spheres({Vec3::Zero()}, {Vec3::Zero()}, {Vec3::Zero()}, step);
    pair.compute(s.solvers, {step, dt * static_cast<double>(step), step == 0 ? 0.0 : dt});
    replies.begin_step(s.solvers, 0);
    pair.scatter(s.solvers, dt, replies);
    on_fluid = vec3(replies.particle_force(sabo::Role::sph), 0);
    torque = vec3(replies.particle_torque(sabo::Role::dem), 0);
  }
  const double normal = k * overlap;
  std::cout << "sliding: tangential " << -on_fluid.x() << " N, expected mu K delta = " << 0.4 * normal
            << " N; torque on the sphere " << torque.y() << " N m, expected " << 0.4 * normal * kRadius << "\n";
  EXPECT_NEAR(on_fluid.z(), normal, 1e-12 * normal);
  EXPECT_NEAR(-on_fluid.x(), 0.4 * normal, 1e-9 * normal);
  // The sphere takes +mu F_n along x at its top (r = R ez): torque R ez x (mu F_n ex) = mu F_n R ey.
  EXPECT_NEAR(torque.y(), 0.4 * normal * kRadius, 1e-9 * normal * kRadius);
}

TEST(SphDemPenalty, DerivedStiffnessIsTheFluidsOwnUnlessItsStepWouldFallBelowTheSphStep) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::penalty);
  const double own = 1000 * kSoundSpeed * kSoundSpeed * kDx;
  EXPECT_DOUBLE_EQ(scene.sph_dem_derived_stiffness(scene.fluids[0]), own);
  EXPECT_GE(scene.sph_dem_pair_dt(scene.fluids[0], own), scene.sph_acoustic_dt());
  scene.sph.cfl = 0.5;
  scene.sph.smoothing_ratio = 2.0;  // cfl h / dx = 1 > 0.2 pi: the fluid's own stiffness would be too stiff
  const double capped = scene.sph_dem_derived_stiffness(scene.fluids[0]);
  std::cout << "derived stiffness " << own << " N/m, capped at cfl h/dx = 1: " << capped << " N/m\n";
  EXPECT_LT(capped, own);
  EXPECT_NEAR(scene.sph_dem_pair_dt(scene.fluids[0], capped), scene.sph_acoustic_dt(), 1e-15);
}

TEST(SphDemPenalty, SameBitsOnOneAndTwoThreads) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::penalty);
  scene.sph_dem_default.friction = 0.3;
  scene.sph_dem_default.normal_damping_ratio = 0.1;
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::size_t nf = 4000;
  std::vector<Vec3> xf, vf, xs, vs, ws;
  std::vector<double> radii;
  for (int j = 0; j < 12; ++j) {
    xs.emplace_back(0.3 * u(random), 0.3 * u(random), 0.3 * u(random));
    vs.emplace_back(u(random), u(random), u(random));
    ws.emplace_back(10 * u(random), 10 * u(random), 10 * u(random));
    radii.push_back(0.03 + 0.02 * std::abs(u(random)));
  }
  for (std::size_t i = 0; i < nf; ++i) {
    xf.emplace_back(0.35 * u(random), 0.35 * u(random), 0.35 * u(random));
    vf.emplace_back(u(random), u(random), u(random));
  }
  const auto run = [&](int threads) {
    omp_set_num_threads(threads);
    SphDemPenaltyPair pair(scene);
    TwoSolvers s(nf, radii);
    Replies replies;
    pair.start(s.solvers, replies);
    std::vector<double> out;
    for (std::uint64_t step = 0; step < 3; ++step) {
      s.set_fluid(xf, vf, step);
      s.set_spheres(xs, vs, ws, step);
      pair.compute(s.solvers, {step, 1e-4 * static_cast<double>(step), step == 0 ? 0.0 : 1e-4});
      replies.begin_step(s.solvers, 0);
      pair.scatter(s.solvers, 1e-4, replies);
      for (auto role : {sabo::Role::sph, sabo::Role::dem}) {
        const auto& f = replies.particle_force(role);
        out.insert(out.end(), f.begin(), f.end());
      }
      const auto& t = replies.particle_torque(sabo::Role::dem);
      out.insert(out.end(), t.begin(), t.end());
      out.push_back(pair.energy().elastic);
      out.push_back(pair.stable_dt());
    }
    std::cout << threads << " thread(s): " << pair.contact_count() << " contacts\n";
    return out;
  };
  const auto one = run(1), two = run(2);
  omp_set_num_threads(2);
  ASSERT_EQ(one.size(), two.size());
  for (std::size_t k = 0; k < one.size(); ++k) ASSERT_EQ(one[k], two[k]) << k;
}

// -------------------------------------------------- boundary particles --

TEST(SphDemBoundary, SendsTheBoulderParticlesNearTheFluidMovingRigidly) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::boundary_particles);
  scene.sph.smoothing_ratio = 1.5;
  SphDemBoundaryPair pair(scene);
  TwoSolvers s(1, {kRadius});
  Replies replies;
  pair.start(s.solvers, replies);
  ASSERT_TRUE(replies.boundary().active());
  const Vec3 centre(0.1, 0.2, 0.3), v(0.5, -0.2, 0.1), w(0, 0, 20);
  // One fluid particle just outside the boulder along +x: only the particles within the support (3 dx) and the
  // margin of a placement ahead (a quarter of it), every one within the support among them.
  const Vec3 fluid = centre + Vec3(kRadius + 0.5 * kDx, 0, 0);
  s.set_fluid({fluid}, {Vec3::Zero()}, 0);
  s.set_spheres({centre}, {v}, {w}, 0);
  pair.compute(s.solvers, {0, 0.0, 0.0});
  const auto& b = pair.selected();
  const auto all = geometry::sample_sphere(kRadius, kDx, 3);
  std::cout << b.size() << " of " << all.size() << " boundary particles sent\n";
  ASSERT_GT(b.size(), 10u);
  ASSERT_LT(b.size(), all.size() / 4);
  const double support = scene.sph.kernel_support();
  std::size_t within_support = 0;
  for (std::size_t p = 0; p < all.size(); ++p) within_support += (centre + all.offset[p] - fluid).norm() <= support;
  std::size_t sent_within_support = 0;
  for (std::size_t k = 0; k < b.size(); ++k) sent_within_support += (b.position[k] - fluid).norm() <= support;
  std::cout << within_support << " within the support, all sent\n";
  EXPECT_EQ(sent_within_support, within_support);
  EXPECT_LT(within_support, b.size());
  for (std::size_t k = 0; k < b.size(); ++k) {
    const Vec3 r = b.position[k] - centre;
    EXPECT_LE((b.position[k] - fluid).norm(), 1.25 * support * (1 + 1e-12));
    EXPECT_NEAR((b.velocity[k] - (v + w.cross(r))).norm(), 0.0, 1e-12);
    EXPECT_NEAR(b.normal[k].dot(r.normalized()), 1.0, 1e-12);
    // At step 0 the acceleration is unknown (zero): only the centripetal part of the spin.
    EXPECT_NEAR((b.acceleration[k] - w.cross(w.cross(r))).norm(), 0.0, 1e-9);
  }
  EXPECT_TRUE(pair.interest(sabo::Role::sph).boxes[0].contains(fluid));
  EXPECT_TRUE(pair.interest(sabo::Role::dem).all);
}

TEST(SphDemBoundary, ReturnedForcesBecomeTheBouldersImpulseWithItsTorque) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::boundary_particles);
  SphDemBoundaryPair pair(scene);
  TwoSolvers s(2, {kRadius, kRadius});
  Replies replies;
  pair.start(s.solvers, replies);
  const Vec3 a(0, 0, 0), b(0.3, 0, 0);  // the second boulder is far from the fluid
  const std::vector<Vec3> fluid{Vec3(0, 0, -kRadius - 0.5 * kDx), Vec3(0.5 * kDx, 0, -kRadius - 0.5 * kDx)};
  const double dt0 = 1e-4, dt1 = 1.5e-4, dt2 = 0.8e-4;
  s.set_fluid(fluid, {Vec3::Zero(), Vec3::Zero()}, 0);
  s.set_spheres({a, b}, {Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}, 0);
  pair.compute(s.solvers, {0, 0.0, 0.0});
  replies.begin_step(s.solvers, 0);
  pair.scatter(s.solvers, dt0, replies);
  const physics::BoundaryParticles sent = pair.selected();
  ASSERT_GT(sent.size(), 0u);

  // Step 1: the fluid returns a force on each particle of step 0's list (here: along its normal and
  // sideways, so that the sum has a torque).
  std::vector<double> returned;
  Vec3 total = Vec3::Zero(), moment = Vec3::Zero();
  for (std::size_t k = 0; k < sent.size(); ++k) {
    const Vec3 f = 0.01 * sent.normal[k] + Vec3(0.002 * static_cast<double>(k % 3), 0, 0);
    returned.insert(returned.end(), {f.x(), f.y(), f.z()});
    total += f;
    moment += (sent.position[k] - a).cross(f);
  }
  s.set_fluid(fluid, {Vec3::Zero(), Vec3::Zero()}, 1);
  s.fluid.mutable_boundary_force()->Assign(returned.begin(), returned.end());
  s.set_spheres({a, b}, {Vec3::Zero(), Vec3::Zero()}, {Vec3::Zero(), Vec3::Zero()}, 1);
  pair.compute(s.solvers, {1, dt0, dt0});
  EXPECT_EQ(pair.contact_count(), 1u);
  EXPECT_LT(pair.newton_balance().sum.norm(), 1e-15);
  replies.begin_step(s.solvers, 0);
  pair.scatter(s.solvers, dt1, replies);
  const Vec3 force = vec3(replies.particle_force(sabo::Role::dem), 0);
  const Vec3 torque = vec3(replies.particle_torque(sabo::Role::dem), 0);
  // The fluid felt them over dt0 / 2 (its step 0); the boulder integrates over (dt0 + dt1) / 2.
  const double scale = (0.5 * dt0) / (0.5 * (dt0 + dt1));
  std::cout << "impulse on the boulder " << (force * 0.5 * (dt0 + dt1)).transpose() << " N s, the fluid's "
            << (total * 0.5 * dt0).transpose() << " N s\n";
  EXPECT_NEAR((force - scale * total).norm(), 0.0, 1e-15);
  EXPECT_NEAR((torque - scale * moment).norm(), 0.0, 1e-15);
  EXPECT_EQ(vec3(replies.particle_force(sabo::Role::dem), 1).norm(), 0.0);
  (void)dt2;
}

// Walls ahead of the fluid's state: step 1's particles placed from the fluid kept at step 0 are the same
// whether the coupler has them placed before the fluid's state 1 is in (place_ahead) or in compute(), and they
// hold every boulder particle within the support of the fluid at step 1.
TEST(SphDemBoundary, PlacedAheadFromTheKeptFluidHoldTheParticlesWithinTheSupportOfTheFluidNow) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::boundary_particles);
  const double support = scene.sph.kernel_support();
  const std::vector<Vec3> fluid0{Vec3(kRadius + 0.5 * kDx, 0, 0), Vec3(0, kRadius + 0.8 * kDx, 0)};
  // Each moves a fifth of the support (the margin is a quarter), the first towards the boulder.
  const std::vector<Vec3> fluid1{fluid0[0] - Vec3(0.2 * support, 0, 0), fluid0[1] + Vec3(0, 0, 0.2 * support)};
  std::vector<physics::BoundaryParticles> placed;
  for (const bool ahead : {true, false}) {
    SphDemBoundaryPair pair(scene);
    TwoSolvers s(2, {kRadius});
    Replies replies;
    pair.start(s.solvers, replies);
    EXPECT_FALSE(pair.can_place_ahead()) << "no fluid kept before the first step";
    s.set_fluid(fluid0, {Vec3::Zero(), Vec3::Zero()}, 0);
    s.set_spheres({Vec3::Zero()}, {Vec3(0.1, 0, 0)}, {Vec3::Zero()}, 0);
    pair.compute(s.solvers, {0, 0.0, 0.0});
    ASSERT_TRUE(pair.can_place_ahead());
    s.set_spheres({Vec3(1e-3, 0, 0)}, {Vec3(0.1, 0, 0)}, {Vec3::Zero()}, 1);
    if (ahead) pair.place_ahead(s.solvers, {1, 1e-2, 1e-2});  // the fluid's state 1 is not in yet
    s.set_fluid(fluid1, {Vec3::Zero(), Vec3::Zero()}, 1);
    pair.compute(s.solvers, {1, 1e-2, 1e-2});
    placed.push_back(pair.selected());
  }
  ASSERT_EQ(placed[0].position, placed[1].position);
  ASSERT_EQ(placed[0].acceleration, placed[1].acceleration);
  const auto all = geometry::sample_sphere(kRadius, kDx, 3);
  std::size_t needed = 0, found = 0;
  for (std::size_t p = 0; p < all.size(); ++p) {
    const Vec3 x = Vec3(1e-3, 0, 0) + all.offset[p];
    if ((x - fluid1[0]).norm() > support && (x - fluid1[1]).norm() > support) continue;
    ++needed;
    for (const Vec3& y : placed[0].position) found += (y - x).norm() < 1e-15;
  }
  std::cout << needed << " boulder particles within the support of the fluid at step 1, " << found
            << " of them placed ahead; " << placed[0].size() << " placed in all\n";
  EXPECT_GT(needed, 10u);
  EXPECT_EQ(found, needed);
}

// The check of the fluid's state against the fluid the particles were placed from: a particle that moved more
// than the margin, or one new to the state near a boulder, stops the run naming it.
TEST(SphDemBoundary, AFluidParticleBeyondTheMarginOfThePlacementAheadIsAnError) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::boundary_particles);
  const double support = scene.sph.kernel_support();
  const auto two_steps = [&](const std::vector<Vec3>& fluid0, const std::vector<Vec3>& fluid1) {
    SphDemBoundaryPair pair(scene);
    TwoSolvers s(3, {kRadius});
    Replies replies;
    pair.start(s.solvers, replies);
    s.set_fluid(fluid0, std::vector<Vec3>(fluid0.size(), Vec3::Zero()), 0);
    s.set_spheres({Vec3::Zero()}, {Vec3::Zero()}, {Vec3::Zero()}, 0);
    pair.compute(s.solvers, {0, 0.0, 0.0});
    s.set_spheres({Vec3::Zero()}, {Vec3::Zero()}, {Vec3::Zero()}, 1);
    pair.place_ahead(s.solvers, {1, 1e-4, 1e-4});
    s.set_fluid(fluid1, std::vector<Vec3>(fluid1.size(), Vec3::Zero()), 1);
    pair.compute(s.solvers, {1, 1e-4, 1e-4});
  };
  const Vec3 near(kRadius + 0.5 * kDx, 0, 0), far(1.0, 0, 0);
  EXPECT_NO_THROW(two_steps({near, far}, {near - Vec3(0.24 * support, 0, 0), far}));
  try {
    two_steps({near, far}, {near - Vec3(0.26 * support, 0, 0), far});
    ADD_FAILURE() << "a particle that moved 0.26 supports was taken";
  } catch (const ProtocolError& error) {
    std::cout << error.what() << "\n";
    EXPECT_NE(std::string(error.what()).find("fluid particle 0 moved"), std::string::npos);
  }
  // A third particle, absent at step 0, appears at step 1 within the support of the boulder's particles.
  EXPECT_NO_THROW(two_steps({near, far}, {near, far, Vec3(0.5, 0, 0)}));
  try {
    two_steps({near, far}, {near, far, Vec3(0, 0, -kRadius - 0.5 * kDx)});
    ADD_FAILURE() << "a new particle next to the boulder was taken";
  } catch (const ProtocolError& error) {
    EXPECT_NE(std::string(error.what()).find("fluid particle 2, absent from the state of the exchange before"),
              std::string::npos)
        << error.what();
  }
}

TEST(SphDemBoundary, HistoryRestoresToTheSameNextStep) {
  scene::Scene scene = two_body_scene(scene::SphDemContact::Model::boundary_particles);
  const auto path =
      std::filesystem::temp_directory_path() / ("sabo-sph-dem-history-" + std::to_string(::getpid()) + ".h5");
  const std::vector<Vec3> fluid{Vec3(0, 0, -kRadius - 0.5 * kDx)};
  const auto step = [&](SphDemBoundaryPair& pair, TwoSolvers& s, Replies& replies, std::uint64_t n,
                        const std::vector<double>& returned, const Vec3& v) {
    s.set_fluid(fluid, {Vec3::Zero()}, n);
    s.fluid.mutable_boundary_force()->Assign(returned.begin(), returned.end());
    s.set_spheres({Vec3::Zero()}, {v}, {Vec3(0, 1, 0)}, n);
    pair.compute(s.solvers, {n, 1e-4 * static_cast<double>(n), n == 0 ? 0.0 : 1e-4});
    replies.begin_step(s.solvers, 0);
    pair.scatter(s.solvers, 1e-4, replies);
  };
  SphDemBoundaryPair first(scene);
  TwoSolvers s1(1, {kRadius});
  Replies r1;
  first.start(s1.solvers, r1);
  step(first, s1, r1, 0, {}, Vec3(0, 0, -1));
  const physics::BoundaryParticles sent0 = first.selected();
  std::vector<double> returned(3 * first.selected().size(), 0.01);
  {
    auto file = io::hdf5::File::create(path);
    auto group = file.create_group("sph_dem");
    first.save_history(group);
  }
  step(first, s1, r1, 1, returned, Vec3(0, 0, -1.1));

  SphDemBoundaryPair second(scene);
  TwoSolvers s2(1, {kRadius});
  Replies r2;
  second.start(s2.solvers, r2);
  r2.boundary().begin_step();  // the channel's own layout of step 0, as the coupler's checkpoint will hold it
  r2.boundary().append(0, sent0);
  {
    const auto file = io::hdf5::File::open(path);
    second.restore_history(file.group("sph_dem"));
  }
  ASSERT_TRUE(second.can_place_ahead()) << "the checkpoint keeps the fluid that step 1's particles are placed from";
  step(second, s2, r2, 1, returned, Vec3(0, 0, -1.1));
  ASSERT_EQ(first.selected().position, second.selected().position);
  ASSERT_EQ(r1.particle_force(sabo::Role::dem), r2.particle_force(sabo::Role::dem));
  ASSERT_EQ(r1.particle_torque(sabo::Role::dem), r2.particle_torque(sabo::Role::dem));
  ASSERT_EQ(first.selected().acceleration, second.selected().acceleration);
  std::filesystem::remove(path);

  auto file = io::hdf5::File::create(path);
  auto wrong = file.create_group("wrong");
  wrong.set_attribute("pair", std::string("dem_fem"));
  SphDemBoundaryPair third(scene);
  EXPECT_THROW(third.restore_history(wrong), FileError);
  std::filesystem::remove(path);
}

}  // namespace
