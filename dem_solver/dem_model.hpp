#pragma once
// The physics of dem_solver: DEM spheres with DEM-DEM contacts (docs/model.md
// "DEM-DEM"), gravity and forces received from the coupler. No protocol here.
//
// Step contract (central difference, docs/design.md, "An explicit, lock-step step"). The state at step n is
// positions x_n and half-step velocities v_{n-1/2}, w_{n-1/2} (at step 0 the
// initial v_0, w_0). One step, in this order:
//   compute_internal_forces(dt_{n-1})   contact forces and torques at x_n, using
//                                       v_{n-1/2}; gravity; contact histories
//                                       advanced by v_t * dt_{n-1} (0 at step 0)
//   add_external_forces(...)            coupler forces/torques, any number of calls
//                                       (before or after the internal forces)
//   integrate(dt_{n-1}, dt_n)           v_{n+1/2} = v_{n-1/2} + dt_avg F/m,
//                                       w_{n+1/2} = w_{n-1/2} + dt_avg T/I (I = 2/5 m r^2),
//                                       x_{n+1} = x_n + dt_n v_{n+1/2},
//                                       dt_avg = (dt_{n-1} + dt_n)/2, or dt_n/2 at step 0;
//                                       then forces and torques are cleared.
// Angular positions are not tracked (spheres). Fixed spheres (set_fixed) take
// part in contacts with infinite mass and never move.
//
// Ids: a sphere's index is its global id, stable for the whole run: particle
// sets in scene order, within a set the listed order (list) or, for a fill,
// the order of the cells (z, then y, then x; cells 2 r_max wide) of the initial
// (placed, then settled) positions, so that neighbours in space are neighbours
// in memory.
//
// Contact laws, per pair of materials (scene::DemContact::law): linear
// spring-dashpot (physics::spring_dashpot_force) or Hertz-Mindlin no-slip
// (physics::hertz_mindlin_force); the pair kernel here computes the same forces
// (a test compares them) with the parameters precomputed per material pair. The
// force loop is instantiated per law and rolling model: a scene with one law pays
// no per-pair branch on it, and one without rolling resistance pays nothing for it.
//
// Neighbours: a Verlet list (half list: each pair once, at the sphere with the
// lower id, neighbours in id order) of the pairs within r_a + r_b + skin (skin =
// kSkinFraction r_max), rebuilt from a cell list only when a sphere has moved
// more than skin/2 since the last build. Contact histories live in the list's
// slots and move with their pair across rebuilds (keyed by the pair).
//
// Walls (add_wall): planes and x-z segments extruded along y, against which the
// spheres touch with the law of their material with itself (a wall of the same
// material). Used to settle fill sets inside their region and by benchmarks.
//
// Rolling resistance (constant model): the constant torque mu_r r_eff F_n of the paper, as the cap
// of an elastic-plastic rolling spring (physics::rolling_spring_torque, Ai et al.
// 2011 "model C", k_r = 2.25 k_n mu_r^2 r_eff^2, dashpot with the tangential
// damping ratio and the pair's reduced moment of inertia). While spheres roll on
// each other the torque is the constant torque against the rotation; at rest
// the spring holds, so a resting pile neither chatters (a bare constant torque
// reverses slow rotations within a step) nor creeps (a constant torque limited
// so as not to reverse them cannot hold a sphere against a driving torque).
//
// The viscous model: torque -rolling_viscosity r_eff F_n (r_eff w_rel), no spring.
//
// Determinism: each pair is computed once, by the thread of its lower-id sphere,
// which sums its own pairs in list order; the other sphere takes the pair's
// reaction in a second pass over its pairs in slot order; energies are summed per
// block of kSumBlock spheres, then the blocks in order. Same input, same bits, for
// any number of threads.
#include <algorithm>
#include <array>
#include <cassert>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/physics/cell_list.hpp"
#include "libsabo/physics/contact_law.hpp"
#include "libsabo/physics/hertz_mindlin.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::dem {

struct Energies {
  double kinetic = 0;     // J, translational + rotational, at step n: 1/2 m v_{n-1/2}.v_{n+1/2} (+ rotation)
  double potential = 0;   // J, gravitational, -m g.x_n (zero at x = 0; fixed spheres left out)
  double elastic = 0;     // J, springs of the DEM-DEM contacts at x_n
  double dissipated = 0;  // J, accumulated through step n by dashpots, sliding and rolling resistance
                          //    (impulse of their forces times the mean relative velocity over the step,
                          //    plus the spring energy released by slip and by contacts that open)
  [[nodiscard]] double total() const { return kinetic + potential + elastic; }
};

// One DEM-DEM contact's springs, for checkpoints. a < b are sphere ids.
struct ContactRecord {
  std::uint32_t a = 0, b = 0;
  Vec3 tangential_displacement = Vec3::Zero();  // m
  Vec3 rolling_torque = Vec3::Zero();           // N m, on a
  double spring_energy = 0;                     // J, tangential + rolling springs at the last evaluation
};

// A rigid boundary of the spheres (see add_wall).
struct Wall {
  enum class Kind {
    plane,       // through `point`, unit `normal` towards the spheres (one-sided)
    segment_xz,  // the segment [a, b] of the x-z plane extruded along y (two-sided)
  };
  Kind kind = Kind::plane;
  Vec3 point = Vec3::Zero();
  Vec3 normal{0, 0, 1};
  std::array<double, 2> a{0, 0}, b{0, 0};  // (x, z), m
  // The wall's elastic constants for Hertz-Mindlin contacts: 0 takes the sphere's material (a wall of
  // the same material); +infinity is rigid. The other constants of the law are the sphere material's.
  double youngs_modulus = 0;  // Pa
  double poisson_ratio = 0;
};

class DemModel {
 public:
  // Builds every particle set of the scene (fills regions with the set's seed).
  // Throws SceneError if a fill set does not fit or two spheres overlap (by more than 1e-6 of
  // their radii's sum, the round-off of touching spheres written in decimal).
  explicit DemModel(const scene::Scene& scene);

  [[nodiscard]] std::size_t size() const { return radius_.size(); }

  // Structure-of-arrays state, indexed by sphere id.
  [[nodiscard]] std::span<const Vec3> positions() const { return position_; }       // m, x_n
  [[nodiscard]] std::span<const Vec3> velocities() const { return velocity_; }      // m/s, v_{n-1/2}
  [[nodiscard]] std::span<const Vec3> angular_velocities() const { return spin_; }  // rad/s, w_{n-1/2}
  // Restarts: positions of every sphere (m); the next step measures the moves since the list was built.
  void set_positions(std::span<const Vec3> positions) {
    assert(positions.size() == position_.size());
    std::copy(positions.begin(), positions.end(), position_.begin());
    displacement_known_ = false;
  }
  [[nodiscard]] std::span<Vec3> velocities() { return velocity_; }
  [[nodiscard]] std::span<Vec3> angular_velocities() { return spin_; }
  [[nodiscard]] std::span<const double> radii() const { return radius_; }                    // m
  [[nodiscard]] std::span<const double> masses() const { return mass_; }                     // kg
  [[nodiscard]] std::span<const std::uint32_t> material_index() const { return material_; }  // into Scene::materials
  [[nodiscard]] std::span<const std::uint32_t> body_index() const { return body_; }  // into Scene::particle_sets
  [[nodiscard]] const std::vector<std::string>& body_names() const { return body_names_; }
  // Force (N) and torque (N m) accumulated since the last integrate(); fixed spheres get no
  // gravity (their force is the load on them).
  [[nodiscard]] std::span<const Vec3> forces() const { return force_; }
  [[nodiscard]] std::span<const Vec3> torques() const { return torque_; }

  // A fixed sphere keeps its position, has zero velocity and infinite mass in contacts.
  void set_fixed(std::uint32_t id, bool fixed);
  [[nodiscard]] bool is_fixed(std::uint32_t id) const { return fixed_[id] != 0; }

  // See the step contract above.
  void compute_internal_forces(double dt_previous);
  // force and torque: 3 doubles (x, y, z) per listed id; torque may be empty (no torques).
  // Forces on fixed spheres are ignored. Throws ModelInputError on a size mismatch or an unknown id.
  void add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force,
                           std::span<const double> torque);
  void integrate(double dt_previous, double dt);

  // Paper eq. 7's DEM term without beta: 0.2 pi sqrt(m_min / k_max), s; m_min the
  // lightest free sphere, k_max the stiffest pair the sphere sizes allow, in which
  // the tangential spring counts as 3.5 k_t (its contact point also turns the spheres) and
  // the rolling spring as 5.625 mu_r^2 k_n (the largest k_r / I relative to k_n / m).
  // With Hertz-Mindlin pairs also at most a fifth of the Rayleigh time of the smallest free
  // sphere, pi r sqrt(rho / G) / (0.1631 nu + 0.8766), divided by sqrt(5.625 mu_r^2) when that
  // exceeds 1. Infinity when no sphere is free. Computed once, again after set_fixed().
  [[nodiscard]] double stable_dt() const;

  // Energies at the step of the last integrate() (before any: the initial state).
  [[nodiscard]] Energies energies() const { return energies_; }

  // Box around all spheres (centres inflated by their radii); empty when there are none.
  [[nodiscard]] Aabb bounds() const;

  // DEM-DEM contacts found by the last compute_internal_forces().
  [[nodiscard]] std::size_t contact_count() const { return contact_count_; }
  // Sphere-wall contacts found by the last compute_internal_forces().
  [[nodiscard]] std::size_t wall_contact_count() const { return wall_contact_count_; }
  // Pairs in the Verlet list (within r_a + r_b + skin at its last build), and builds so far.
  [[nodiscard]] std::size_t neighbour_pair_count() const { return neighbour_.size(); }
  [[nodiscard]] std::size_t neighbour_builds() const { return neighbour_builds_; }
  // Contact histories for checkpoints, ordered by (a, b); restore before the
  // next compute_internal_forces(), together with positions and velocities.
  [[nodiscard]] std::vector<ContactRecord> contact_histories() const;
  void restore(std::span<const ContactRecord> contacts, double dissipated_energy);
  // The whole state integrate() leaves for the next step, for checkpoints (dem_checkpoint.cpp): a model built
  // from the same scene that loads it continues with the same bits. FileError for a checkpoint of another scene.
  void save_state(io::hdf5::Group& group) const;
  void load_state(const io::hdf5::Group& group);

  // Adds a rigid wall (fixed, infinite mass). Its contacts use the law of the sphere's
  // material with itself; their histories are kept per sphere and wall.
  void add_wall(const Wall& wall);
  // Walls enclosing a fill set's region: 6 planes of a box, or the polygon's edges and 2 y planes.
  void add_region_walls(const scene::ParticleSet& set);
  void clear_walls();

  // The contact laws of a pair as the physics functions take them. contact_law and rolling_law:
  // the linear law (stiffness from the scene, damping from the ratios); hertz_law: Hertz-Mindlin.
  [[nodiscard]] physics::SpringDashpot contact_law(std::uint32_t a, std::uint32_t b) const;
  [[nodiscard]] physics::RollingSpring rolling_law(std::uint32_t a, std::uint32_t b) const;
  [[nodiscard]] physics::HertzMindlin hertz_law(std::uint32_t a, std::uint32_t b) const;
  [[nodiscard]] const scene::DemContactLaw& law(std::uint32_t a, std::uint32_t b) const;

  // Verlet skin as a fraction of the largest radius.
  static constexpr double kSkinFraction = 0.25;

  // One pair's precomputed law (per pair of materials), public for the kernel.
  struct PairLaw {
    bool hertz = false;
    double friction = 0;
    double normal_damping_ratio = 0, tangential_damping_ratio = 0;  // linear
    double effective_modulus = 0, effective_shear_modulus = 0;      // Pa, hertz
    double damping = 0;               // hertz: 2 sqrt(5/6) |beta| (dashpot c = damping sqrt(S m*))
    double stiffness_ratio_root = 0;  // hertz: sqrt(S_t / S_n) = sqrt(4 G* / E*)
    int rolling = 0;                  // 0 none, 1 constant (spring capped), 2 viscous
    double rolling_friction = 0, rolling_viscosity = 0;
    double rolling_damping_ratio = 0;  // the rolling spring's dashpot
  };

 private:
  template <int kLaw, int kRolling>
  void pair_forces(double dt_previous);
  [[nodiscard]] static std::pair<std::int64_t, std::int64_t> thread_spheres(
      const std::vector<std::uint32_t>& slot_start);
  void settle(const scene::Scene& scene, const scene::ParticleSet& set, std::vector<scene::Sphere>& spheres,
              std::span<const scene::Sphere> obstacles);
  void build_neighbours();
  // Orders filled spheres by cell (z, y, x; cells 2 r_max wide), stable.
  static void sort_by_cell(std::vector<scene::Sphere>& spheres);
  void build_law_table(const scene::Scene& scene);
  [[nodiscard]] double compute_stable_dt() const;
  [[nodiscard]] double normal_stiffness(std::uint32_t a, std::uint32_t b) const;
  void update_inverse_mass(std::uint32_t id);

  scene::DemContact settings_;
  Vec3 gravity_;
  std::vector<std::string> body_names_;
  std::vector<std::string> material_names_;
  std::vector<double> material_bulk_modulus_;  // Pa, per material
  std::vector<double> material_youngs_, material_poisson_;
  std::size_t material_count_ = 0;
  std::vector<PairLaw> pair_law_;  // [material_a * count + material_b]
  int law_kind_ = 0;               // 0 all linear, 1 all hertz, 2 mixed
  int rolling_kind_ = 0;           // 0 none, 1 all constant, 2 all viscous, 3 mixed

  // Per sphere.
  std::vector<Vec3> position_, velocity_, spin_, force_, torque_;
  std::vector<double> radius_, mass_, inverse_mass_, inverse_inertia_, stiffness_term_;  // K r for the linear law
  std::vector<std::uint32_t> material_, body_;
  std::vector<std::uint8_t> fixed_;
  double largest_radius_ = 0;
  mutable std::optional<double> stable_dt_;  // s, stable_dt() once computed; cleared by set_fixed()

  // Verlet half list: the neighbours of sphere i are neighbour_[start_[i] .. start_[i+1]), ascending.
  physics::CellList cells_;
  double skin_ = 0;
  bool rebuild_ = true;
  std::size_t neighbour_builds_ = 0;
  std::vector<Vec3> build_position_;  // positions at the last build
  // Largest squared move since the last build (m^2), measured by integrate(); unknown after set_positions().
  double largest_displacement_squared_ = 0;
  bool displacement_known_ = false;
  std::vector<std::uint32_t> start_, neighbour_, count_scratch_;
  std::vector<std::vector<std::uint32_t>> thread_neighbours_;  // per thread, while building
  // Per slot: contact histories.
  std::vector<Vec3> tangential_, rolling_;
  std::vector<std::uint8_t> in_contact_;
  std::vector<double> spring_energy_;  // J, tangential + rolling springs after the last evaluation
  // What a pair puts on its higher-id sphere b, stored in reverse-list order (the slots where b is the
  // neighbour, in slot order): the force loop writes each slot's at reaction_index_[slot], the gather reads
  // them sequentially. Zero while the pair is not in contact. One cache line a slot: b's torque is arm x force,
  // and the dissipative force (energy bookkeeping only) is kept in single precision. The rolling resistance's
  // torques, where a scene has it, in rolling_reaction_ (same order).
  struct alignas(64) Reaction {
    Vec3 force = Vec3::Zero();                        // N, on b
    Vec3 arm = Vec3::Zero();                          // m, from b's centre to the contact point
    std::array<float, 3> dissipative_force{0, 0, 0};  // N, on b
  };
  static_assert(sizeof(Reaction) == 64);
  struct RollingReaction {
    Vec3 torque = Vec3::Zero();                        // N m, on b
    std::array<float, 3> dissipative_torque{0, 0, 0};  // N m, on b
  };
  std::vector<Reaction> reaction_;
  std::vector<RollingReaction> rolling_reaction_;  // empty without rolling resistance
  std::vector<std::uint32_t> reverse_start_, reaction_index_;
  // Restored histories waiting for the next build, sorted by key.
  std::vector<std::pair<std::uint64_t, ContactRecord>> pending_;

  // Walls and their per-sphere histories ([sphere * walls + wall]).
  std::vector<Wall> walls_;
  std::vector<PairLaw> wall_law_;  // [wall * materials + sphere material]
  std::vector<Vec3> wall_tangential_, wall_rolling_;
  // The walls within r + skin of each sphere at the last list build: wall_near_[wall_near_start_[i] ..
  // wall_near_start_[i+1]), ascending.
  std::vector<std::uint32_t> wall_near_start_, wall_near_;
  std::vector<std::uint8_t> wall_in_contact_;
  std::vector<double> wall_spring_energy_;

  // Below this many spheres the loops run serially: a parallel region costs more than the work.
  static constexpr std::size_t kParallelThreshold = 256;
  bool parallel_ = false;

  // Step bookkeeping, per sphere then summed serially.
  bool forces_ready_ = false;
  std::size_t contact_count_ = 0, wall_contact_count_ = 0;
  std::vector<Vec3> dissipative_force_, dissipative_torque_;  // N, N m: on each sphere, this step
  std::vector<double> sphere_elastic_, sphere_released_;      // J
  // Energies summed per block of kSumBlock spheres (the block sums then added in order).
  static constexpr std::size_t kSumBlock = 512;
  struct BlockSums {
    double kinetic = 0, potential = 0, dissipated_power = 0, elastic = 0, released = 0;
  };
  std::vector<BlockSums> block_sums_;
  std::vector<std::uint32_t> sphere_contacts_, sphere_wall_contacts_;
  double dropped_released_ = 0;  // J, springs of contacts dropped by a rebuild
  Energies energies_;
};

}  // namespace sabo::dem
