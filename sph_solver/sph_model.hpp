#pragma once
// The physics of sph_solver: weakly compressible SPH of the debris slurry
// (docs/physics.md, "SPH"). No protocol here.
//
// Step contract (central difference, docs/design.md, "An explicit, lock-step step"). The state at step n is
// positions x_n, densities rho_n, deviatoric stresses S_n and half-step
// velocities v_{n-1/2} (at step 0 the initial v_0). One step, in this order:
//   set_boundary(...)                  wall particles at x_n (boundary-particle walls);
//                                      kept until replaced
//   compute_internal_forces(dt_{n-1})  pressure, viscous, stress and gravity
//                                      accelerations and drho/dt at x_n with v_{n-1/2};
//                                      the force on every wall particle
//   add_external_forces(...)           coupler forces (penalty walls), any number of calls
//   integrate(dt_{n-1}, dt_n)          v_{n+1/2} = v_{n-1/2} + dt_avg a_n,
//                                      x_{n+1} = x_n + dt_n v_{n+1/2},
//                                      rho_{n+1} = rho_n + dt_n drho/dt(x_n, v_{n+1/2}, rho_n)
//                                      (continuity with the new velocities: a second,
//                                      cheaper neighbour pass; with v_{n-1/2} the
//                                      acoustic modes would grow),
//                                      S_{n+1} = return(S_n + dt_n dS/dt(x_n, v_{n+1/2}, S_n))
//                                      (a velocity-gradient pass with the new velocities:
//                                      with v_{n-1/2} the elastic modes would grow);
//                                      dt_avg = (dt_{n-1} + dt_n)/2, or dt_n/2 at step 0.
//
// Ids: a particle's index is its global id, stable for the whole run: fluid
// bodies in scene order, within a body lattice order (z, then y, then x).
// Internally the particles are gathered into cell order every step (a
// counting sort on a uniform grid of cell size 2h) as single-precision
// structure-of-arrays copies: each neighbour search visits 9 rows of 3 cells of
// contiguous memory in blocks of kLanes slots (vectorised), and the cost is
// linear in the count. Pair terms are single precision; the accelerations and
// the wall forces are summed in double, and a fluid-wall pair term is the same
// float on both sides, so that action equals reaction to double rounding.
//
// Inside a cell the particles are sorted by x (ties by id), so that a row of 3
// cells is x-sorted and the blocks outside a particle's x window are skipped.
//
// Periodic boundaries (scene sph.periodic_x / periodic_y, docs/physics.md): a particle
// leaving the span is wrapped back (position -= period, the shift kept in wrap_offsets());
// every step the fluid and wall particles within one support of a seam get read-only
// image slots, shifted by the period, among the cell-ordered slots. An image carries its
// source's state (copied after each pass whose per-slot results neighbours read) and is
// neither integrated nor output: ids >= size() in the sorted order are images. The wall
// forces count the real fluid only, and a wall image's force goes back to its source, so
// that every fluid-wall pair is counted once with the same float on both sides.
//
// Determinism: every particle sums its own neighbours in a fixed order (rows
// in grid order, lane k of a block summing slots begin + k + kLanes m, lanes
// added in lane order); the per-particle results are written back by id;
// every floating-point reduction over particles is serial, a max, or exact (the energies).
// Same input, same bits, for any number of threads.
//
// Ranks (docs/architecture.md, "The slurry on several processes"): a model built with
// parallel::Ranks shares the particles with the other ranks' models. Every step it owns the
// particles in its slab of grid layers along the longest axis of the grid (parallel/slabs.hpp,
// rebalanced every step by the particles per layer) and reads the layer either side of it as a
// halo: the particles there arrive from their owners at the start of the step, and the per-slot
// results that neighbours read (wall state, viscosities, new velocities) after the pass that
// makes them. A rank's grid holds every particle of the cells its own particles search, in the
// same slots order as one model alone, so each particle sums the same neighbours in the same
// order: the same bits on any number of ranks. Between steps, positions(), velocities() and the
// other per-id arrays are current for the particles this rank owns (active() != 0 here) only;
// gather_state() brings the whole state to every rank, collect_state() to rank 0. With periodic
// boundaries the slabs cut a non-periodic axis and each rank makes the images of its window's
// particles. The energies are exact sums (exact_sum.hpp): the same bits too.
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/physics/boundary_particles.hpp"
#include "libsabo/scene/scene.hpp"
#include "sph_solver/eos.hpp"
#include "sph_solver/exact_sum.hpp"
#include "sph_solver/inflow.hpp"
#include "sph_solver/parallel/ranks.hpp"
#include "sph_solver/parallel/slabs.hpp"
#include "sph_solver/sph_kernel.hpp"

namespace sabo::sph {

struct Energies {
  double kinetic = 0;    // J, 1/2 m v_{n-1/2}.v_{n+1/2} at the last integrate()
  double potential = 0;  // J, -m g.x_n
  double elastic = 0;    // J, compression: sum m e(rho), e = integral of p / rho^2 drho from rho0
  // J, >= 0: the walls' work held back by sph.wall_work = "bounded" (0 otherwise). The fluid's
  // total() plus this is what the walls' pressure conserves.
  double wall_held = 0;
  // J, accumulated over the run: what the inflows brought in (inflow.hpp): the energy of each particle
  // as it entered their buffers, the work that kept the buffers at the section's velocity and density,
  // less the energy of the buffers taken out when their hydrographs ended. 0 without inflows.
  double inflow = 0;
  [[nodiscard]] double total() const { return kinetic + potential + elastic; }
};

// Epsilon of Monaghan's artificial stress for elastic-plastic materials without the key: off.
// Measured (docs/notes/sph.md, "Artificial stress"): with the stress updated from the new
// velocities, columns at rest come out the same with epsilon 0.3 as without.
inline constexpr double kDefaultArtificialStress = 0.0;

// Material constants a particle needs in the inner loops.
struct FluidMaterial {
  EquationOfState eos;
  scene::Material::Rheology rheology = scene::Material::Rheology::inviscid;
  double viscosity = 0;          // Pa s
  double yield_stress = 0;       // Pa
  double yield_shear_rate = 1;   // 1/s
  double consistency_index = 0;  // Pa s^n (herschel_bulkley)
  double flow_index = 1;         // herschel_bulkley
  double shear_modulus = 0;      // Pa
  double artificial_stress = 0;  // epsilon of Monaghan's artificial stress (elastic_plastic; 0: off)
  [[nodiscard]] bool needs_velocity_gradient() const { return rheology != scene::Material::Rheology::inviscid; }
  // Effective viscosity eta(gamma_dot) of the viscous stress 2 eta D (docs/scene.md, rheology), Pa s;
  // shear_rate = sqrt(2 D':D') >= 0, 1/s. 0 for inviscid.
  [[nodiscard]] double viscosity_at(double shear_rate) const;
  // Effective viscosity at rest, the largest but for a shear-thickening herschel_bulkley fluid
  // (the initial viscous dt condition; later steps take the particles' own), Pa s.
  [[nodiscard]] double max_viscosity() const;
};

// Particles of the scene's fluid bodies on a cubic lattice of spacing dx, with
// the hydrostatic initial state (docs/scene.md, [[fluids]]). Exposed for tests.
struct FluidFill {
  std::vector<Vec3> position, velocity;
  std::vector<double> density, pressure, mass;
  std::vector<double>
      stress;  // Pa, deviatoric, 6 per particle (xx yy zz xy yz zx); empty without elastic-plastic bodies
  std::vector<std::uint32_t> material, body;
  std::vector<InflowState> inflows;  // per [[inflows]] body: its pool's place, lattice and buffer densities
};
[[nodiscard]] FluidFill fill_fluids(const scene::Scene& scene, std::span<const FluidMaterial> materials,
                                    const std::vector<std::uint32_t>& body_material);

// The fluid at one point, interpolated from the particles within the kernel support (sph_sample.cpp,
// docs/scene.md [[gauges]]).
struct FluidSample {
  double kernel_sum = 0;         // sum V_j W(x - x_j): about 1 inside the fluid, 1/2 at its surface, 0 in the air
  double pressure = 0;           // Pa; 0 when dry
  Vec3 velocity = Vec3::Zero();  // m/s, v_{n-1/2}; 0 when dry
  bool linear_fit = false;       // the first-order fit (else the Shepard mean, or dry)
};
// Below this kernel sum a point is dry: it reads 0 (a lone particle at the point gives about 0.15).
inline constexpr double kDryKernelSum = 0.1;
// The free surface is where the kernel sum falls through this value.
inline constexpr double kSurfaceKernelSum = 0.5;

class SphModel {
 public:
  // Builds the particles of every fluid body. Throws SceneError when a body
  // holds no particle at the scene's spacing. With ranks: one of the ranks' models (above);
  // every rank builds it from the same scene.
  explicit SphModel(const scene::Scene& scene, std::shared_ptr<parallel::Ranks> ranks = nullptr);

  [[nodiscard]] std::size_t size() const { return position_.size(); }
  [[nodiscard]] const scene::SphSettings& settings() const { return settings_; }
  [[nodiscard]] const Kernel& kernel() const { return kernel_; }

  // Structure-of-arrays state, indexed by particle id.
  [[nodiscard]] std::span<const Vec3> positions() const { return position_; }   // m, x_n
  [[nodiscard]] std::span<const Vec3> velocities() const { return velocity_; }  // m/s, v_{n-1/2}
  [[nodiscard]] std::span<Vec3> positions() { return position_; }
  [[nodiscard]] std::span<Vec3> velocities() { return velocity_; }
  [[nodiscard]] std::span<const double> densities() const { return density_; }   // kg/m^3, rho_n
  [[nodiscard]] std::span<const double> pressures() const { return pressure_; }  // Pa, p(rho_n)
  [[nodiscard]] std::span<const double> masses() const { return mass_; }         // kg
  [[nodiscard]] std::span<const std::uint32_t> material_index() const { return material_; }
  [[nodiscard]] std::span<const std::uint32_t> body_index() const { return body_; }
  [[nodiscard]] std::span<const Vec3> accelerations() const { return acceleration_; }  // m/s^2, a_n
  // Deviatoric stress (Pa), xx yy zz xy yz zx per particle; empty unless has_stress().
  [[nodiscard]] std::span<const double> deviatoric_stress() const { return stress_; }
  [[nodiscard]] bool has_stress() const { return has_stress_; }
  // ParticleState per particle: 0 for those out of the simulation (taken out on leaving the domain, or an
  // inflow's that have not entered or were taken out with its buffer), else in it (1 free, 2 and 3 in an
  // inflow's buffer).
  // On ranks: this rank's particles only (the others read 0), but on rank 0 (collect_state()):
  // every particle's.
  [[nodiscard]] std::span<const std::uint8_t> active() const {
    return collected_active_.empty() ? std::span<const std::uint8_t>(active_) : collected_active_;
  }
  // Nonzero for the particles this model steps: all active ones alone, this rank's on ranks.
  [[nodiscard]] std::span<const std::uint8_t> owned() const { return active_; }
  // The inflows' emission, one per [[inflows]] body in scene order.
  [[nodiscard]] std::span<const InflowState> inflows() const { return inflows_; }
  [[nodiscard]] std::size_t lost_count() const { return lost_; }
  // m, per particle: what the periodic wrapping added to its position so far (zero without
  // periodic boundaries, then empty); x - offset is the unwrapped position.
  [[nodiscard]] std::span<const Vec3> wrap_offsets() const { return wrap_offset_; }
  // Number of image slots (fluid, wall) in the last compute_internal_forces().
  [[nodiscard]] std::size_t fluid_image_count() const { return f_image_source_.size(); }
  [[nodiscard]] std::size_t wall_image_count() const { return b_image_source_.size(); }

  // Wall particles for the next compute_internal_forces() (Adami et al. 2012).
  // Taken by value: a caller that no longer needs its copy moves it in.
  void set_boundary(physics::BoundaryParticles boundary);
  [[nodiscard]] const physics::BoundaryParticles& boundary() const { return boundary_; }
  // Force (N) the fluid exerted on each boundary particle in the last
  // compute_internal_forces(); their sum is minus the wall force on the fluid.
  [[nodiscard]] std::span<const Vec3> boundary_forces() const { return boundary_force_; }
  // Deviatoric stress (Pa, xx yy zz xy yz zx) extrapolated onto each boundary particle in the
  // last compute; empty without elastic-plastic fluids.
  [[nodiscard]] std::span<const double> boundary_stresses() const { return boundary_stress_; }

  void compute_internal_forces(double dt_previous);
  // force: 3 doubles per listed id, N. Throws ModelInputError on a size mismatch or an unknown id.
  void add_external_forces(std::span<const std::uint32_t> index, std::span<const double> force);
  // Advances to t_{n+1} = t_n + dt: v_{n+1/2} from the accelerations of the last compute
  // (and the external forces added since), x_{n+1}, rho_{n+1} and S_{n+1} from v_{n+1/2}.
  // A body in its settling phase (FluidBody::settle_time) has v_{n+1/2} damped by
  // exp(-dt / tau) while t_{n+1} < settle_time (tau from h / c at t = 0 to
  // scene::kSettleDampingGrowth h / c at its end), and zeroed at the step that reaches it.
  void integrate(double dt_previous, double dt);

  // cfl * min(h / (c + h max|v_ij.r_ij|/(r^2 + eta^2)), sqrt(h / max|a|), rho0 h^2 / (8 eta_max)), s.
  // Before the first compute: the sound-speed and viscous conditions and sqrt(h / |g|).
  [[nodiscard]] double stable_dt() const { return stable_dt_; }

  [[nodiscard]] Energies energies() const { return energies_; }
  // J per particle, >= 0: the walls' work it holds back (sph.wall_work = "bounded"); empty otherwise.
  [[nodiscard]] std::span<const float> wall_work_held() const { return wall_work_held_; }
  // s, the simulated time t_n: the sum of the steps integrated.
  [[nodiscard]] double time() const { return time_; }
  // The fluid at `point` (m) at t_n: the moving-least-squares fit of first order of the particles within
  // 2h, weighted by V_j W; the Shepard mean where their moment matrix is singular (they do not span 3-D);
  // zero below kDryKernelSum. Uses the neighbour grid of the last compute_internal_forces(): call it
  // after that and before integrate(). kernel_sum() is the same sum alone.
  // On ranks, rank 0's calls go through the remote sampler (set_remote_sampler()), which asks every rank.
  [[nodiscard]] FluidSample sample(const Vec3& point) const;
  [[nodiscard]] double kernel_sum(const Vec3& point) const;
  // On ranks: the sample (or only its kernel sum) at `point`, taken by the rank whose slab holds the
  // point's layer (its grid holds every particle within the support there) and summed over the ranks
  // (the others add zeros), returned on every rank. Collective. Alone: sample() / kernel_sum().
  [[nodiscard]] FluidSample sample_on_ranks(const Vec3& point, bool kernel_sum_only) const;
  // Rank 0 of the sph_solver: what sample() and kernel_sum() call instead of sampling here (it tells
  // the other ranks to join sample_on_ranks(), then joins it).
  using RemoteSampler = std::function<FluidSample(const Vec3& point, bool kernel_sum_only)>;
  void set_remote_sampler(RemoteSampler sampler) { remote_sampler_ = std::move(sampler); }
  // Mean number of neighbours (fluid and wall, inside the support, self excluded) in the last compute.
  [[nodiscard]] double mean_neighbours() const { return mean_neighbours_; }
  // Box around all active particles; empty when there are none.
  [[nodiscard]] Aabb bounds() const;

  // Decomposed over ranks (parallel::Ranks): the slabs and their axis (0 x, 1 y, 2 z) of the
  // last compute_internal_forces(), the particles this rank owned there and read as its halo.
  [[nodiscard]] bool decomposed() const { return ranks_ != nullptr; }
  [[nodiscard]] const parallel::Slabs& slabs() const { return slabs_; }
  [[nodiscard]] int slab_axis() const { return slab_axis_; }
  [[nodiscard]] std::size_t owned_count() const { return owned_count_; }
  [[nodiscard]] std::size_t halo_count() const { return halo_count_; }
  // The whole state by particle id, as one model alone holds it in positions() and the rest.
  struct ParticleState {
    std::vector<Vec3> position, velocity;
    std::vector<double> density, pressure, stress;  // stress: 6 per particle, only with has_stress()
    std::vector<float> wall_work_held;              // only with wall_work_held()
    std::vector<std::int32_t> support_neighbours;   // fluid neighbours in the last compute (once one ran)
    std::vector<std::uint8_t> active;
    std::vector<Vec3> wrap_offset;  // only with periodic boundaries
  };
  // Collective: every rank's owned particles' state on rank `root` (on every rank: root < 0);
  // empty on the others. Without ranks: a copy.
  [[nodiscard]] ParticleState gather_state(int root = -1) const;
  // Collective: gather_state(0) into rank 0's own per-id arrays and active(), so that its
  // accessors read the whole state as one model's would (the sph_solver's rank 0 after each
  // step: the coupler's states, the output and the checks read it). The ownership stays.
  void collect_state();

  // The whole state integrate() leaves for the next step, for checkpoints (sph_checkpoint.cpp): a model built
  // from the same scene that loads it continues with the same bits. FileError for a checkpoint of another scene.
  // On ranks: rank 0 writes, after collect_state() (the whole state; what only a particle's
  // owner holds, its last acceleration and stress rate, is not read by the next step); rank 0
  // loads, and share_loaded_state() (collective) then gives every rank the state and its share
  // of the particles: a checkpoint of any rank count continues on any other with the same bits.
  void save_state(io::hdf5::Group& group) const;
  void load_state(const io::hdf5::Group& group);
  void share_loaded_state();

 private:
  // The particle (wall particle) id whose state a sorted slot's id carries: itself, or an
  // image's source.
  [[nodiscard]] std::uint32_t fluid_source(std::uint32_t slot_id) const {
    return slot_id < position_.size() ? slot_id : f_image_source_[slot_id - position_.size()];
  }
  [[nodiscard]] std::uint32_t wall_source(std::uint32_t slot_id) const {
    return slot_id < boundary_.size() ? slot_id : b_image_source_[slot_id - boundary_.size()];
  }
  // Boundary-particle walls whose work wall_compression() credits (sph.wall_work).
  [[nodiscard]] bool credits_wall_work() const {
    return settings_.wall_model == scene::SphSettings::WallModel::boundary_particles &&
           settings_.wall_work != scene::SphSettings::WallWork::unstored;
  }
  // Calls visit(id, position) for every fluid particle within the support of `point` (images: their
  // source's id, their own position), from the grid of the last compute.
  template <class Visit>
  void for_fluid_within_support(const Vec3& point, Visit&& visit) const;
  [[nodiscard]] FluidSample sample_here(const Vec3& point) const;
  [[nodiscard]] double kernel_sum_here(const Vec3& point) const;
  void wrap_positions();
  // Decomposed (above): the global grid, the slabs, and the particles of this rank's window
  // from their owners; then, after build_grid(), which slots this rank computes and the halo
  // lists; and the halo exchange of per-slot results (component q of slot s at
  // data[q * stride + s]).
  void distribute();
  void mark_slots();
  struct HaloField {
    float* data;
    std::size_t stride;
    int components;
  };
  void exchange_halo(std::initializer_list<HaloField> fluid, std::initializer_list<HaloField> wall);
  // A particle's state between ranks (distribute(), gather_state()), as doubles (ids, flags and
  // counts are exact in one): its size, appending particle `id`'s, and reading one back.
  struct Record {
    std::size_t id;
    std::uint8_t active;
    Vec3 position, velocity;
    double density, pressure;
    std::int32_t support_neighbours;
    const double* stress;  // 6 values, only with has_stress_
    float wall_work_held;  // only with wall_work_held_
    Vec3 wrap_offset;      // only with periodic boundaries
  };
  [[nodiscard]] std::size_t record_size() const;
  void append_record(std::size_t id, std::vector<double>& out) const;
  [[nodiscard]] Record read_record(const double* values) const;
  void exchange_wall_state();   // compute_boundary_state()'s
  void exchange_viscosities();  // compute_velocity_gradients()' effective viscosities and eta L~^T
  void exchange_velocities();   // the new velocities compute_velocity_divergence() gathered
  void exchange_wall_credit();  // compute_wall_compression()'s
  // The stable step's maxima, the neighbour count and the wall forces over all ranks.
  void reduce_step_maxima();
  // Whether this model computes sorted fluid (wall) slot s: a particle, not an image nor a halo slot.
  [[nodiscard]] bool computes_fluid_slot(std::size_t s) const {
    return f_order_[s] < position_.size() && (fmine_.empty() || fmine_[s] != 0);
  }
  [[nodiscard]] bool computes_wall_slot(std::size_t s) const {
    return b_order_[s] < boundary_.size() && (bmine_.empty() || bmine_[s] != 0);
  }
  // The grid's origin and cell counts for the particles (and walls) inside `box`.
  void set_grid_geometry(Aabb box);
  // Decomposed: the grid's layers along the slab axis, and the layer of a point (clamped to them:
  // a point outside the grid, or not finite, belongs to an end layer).
  [[nodiscard]] std::int64_t slab_layers() const { return slab_axis_ == 0 ? nx_ : (slab_axis_ == 1 ? ny_ : nz_); }
  [[nodiscard]] std::int64_t layer_of(const Vec3& point) const;
  // Decomposed: until the first step's slabs (at construction, after a checkpoint is loaded), rank
  // r owns the r-th of R equal runs of ids.
  void keep_initial_share();
  // Whether particle i is in this rank's share of ids (keep_initial_share; always alone).
  [[nodiscard]] bool in_initial_share(std::size_t i) const;
  // Inflows (passes/inflow.cpp): the pools and the first buffer layers, at construction; each buffer's
  // velocity for the step to time_ + dt; after the position update, the buffers advanced (positions,
  // densities), their front layers released and new layers added behind, and a buffer whose hydrograph
  // has ended taken out.
  void start_inflows(std::size_t bodies);
  void set_inflow_velocities(double dt);
  void advance_inflows(double dt, ExactSum& pending);
  void advance_inflows_to(InflowState& inflow);
  // What moves on with each inflow between steps (advance, speeds, layer counts, ended), kInflowValues doubles
  // an inflow (counts are exact in one): for checkpoints and for the ranks a loaded checkpoint is shared with.
  static constexpr std::size_t kInflowValues = 6;
  [[nodiscard]] std::vector<double> inflow_values() const;
  void set_inflow_values(std::span<const double> values);
  // settle_factor_ for the step from time_ to time_ + dt.
  void update_settle_factors(double dt);
  void make_images();
  void copy_wall_image_state();
  void build_grid();
  void gather();
  void compute_boundary_state();
  void extrapolate_wall_stress();
  // L = dv/dx (and the effective viscosity) of the particles whose material needs it, or of
  // the elastic-plastic ones only (integrate()'s pass with the new velocities).
  void compute_velocity_gradients(bool elastic_plastic_only);
  void compute_fluid_forces();
  void compute_boundary_forces();
  void compute_velocity_divergence(double dt);
  // With credits_wall_work(): each wall slot's credit (bcredit_) for velocity_divergence().
  void compute_wall_compression();
  void stress_rates();
  template <class Terms>
  void fluid_forces(Terms terms);
  template <class Terms>
  void boundary_forces(Terms terms);
  template <class Terms>
  void boundary_state(Terms terms);
  template <class Terms>
  void velocity_divergence(Terms terms, double dt);
  template <class Terms>
  void wall_compression(Terms terms);
  [[nodiscard]] double initial_stable_dt() const;
  // stable_dt() from the maxima of the last compute_fluid_forces() and compute_velocity_gradients().
  [[nodiscard]] double forces_stable_dt() const;
  // The neighbour search on the grid of the last build_grid(), defined in
  // sph_solver/passes/neighbours.hpp (included by the files that search).
  // Calls visit(begin, end) for each of the 9 rows of 3 cells around the cell of (x, y, z)
  // (m, absolute): [begin, end) are slots of the cell-ordered particles of `start` (fluid
  // or boundary), rows in grid order.
  template <class Visit>
  void for_neighbour_rows(double x, double y, double z, const std::vector<std::uint32_t>& start, Visit&& visit) const;
  // One row of 3 cells for a particle: slots [begin, end), x-sorted, and the x window
  // (m, relative to grid_origin_) outside which no slot of the row is within 2h.
  struct NeighbourRow {
    std::uint32_t begin, end;
    float x_min, x_max;
  };
  // The rows of for_neighbour_rows() that can hold a neighbour of (x, y, z); returns how many.
  int neighbour_rows(double x, double y, double z, const std::vector<std::uint32_t>& start,
                     NeighbourRow (&rows)[9]) const;
  // Calls block(j0, valid) for each block of kLanes slots [j0, j0 + kLanes) of the rows of
  // neighbour_rows() around `position` (m) that meets the row's x window; sorted_x: the
  // slots' x as in the window. The first `valid` slots of the block lie in the row, the rest
  // are the next row's or padding.
  template <class Block>
  void for_neighbour_blocks(const Vec3& position, const std::vector<std::uint32_t>& start, const float* sorted_x,
                            Block&& block) const;
  // Calls visit(slot) for every slot in the 27 cells around (x, y, z), cells in grid order.
  template <class Visit>
  void for_neighbours(double x, double y, double z, const std::vector<std::uint32_t>& start, Visit&& visit) const;

  scene::SphSettings settings_;
  Kernel kernel_;
  Vec3 gravity_;
  double sound_speed_ = 0;
  double eta_squared_ = 0;  // 0.01 h^2, m^2
  // Smallest h / c_eff over the elastic-plastic materials (infinity if none), s.
  double elastic_wave_dt_ = std::numeric_limits<double>::infinity();
  std::vector<FluidMaterial> materials_;
  bool any_gradient_ = false, has_stress_ = false, any_artificial_stress_ = false;

  // Per particle, by id: the state in double precision.
  std::vector<Vec3> position_, velocity_, acceleration_;
  std::vector<Vec3> external_force_;  // N; empty until add_external_forces() is first called
  std::vector<double> density_, pressure_, mass_;
  std::vector<double> stress_, stress_rate_;  // 6 per particle; empty unless has_stress_
  std::vector<std::uint32_t> material_, body_;
  std::vector<std::uint8_t> active_;  // ParticleState
  std::size_t lost_ = 0;
  std::vector<InflowState> inflows_;
  std::vector<Vec3> buffer_velocity_;  // m/s, per body: an inflow buffer's v_{n+1/2} in integrate() (else zero)
  // J: what the next integrate() adds to the inflows' account (Energies::inflow, in energies_): the energy of
  // buffer densities reset and of buffers taken out, which the energies of the next step show.
  double inflow_pending_ = 0;
  double time_ = 0;                  // s, t_n: the sum of the steps integrated
  std::vector<double> settle_time_;  // s, per body: its damped settling phase ends there (0: none)
  // Per body, this step's factor on v_{n+1/2}: exp(-dt / tau) while settling, 0 at the step
  // that ends the phase, 1 after it (or without one).
  std::vector<double> settle_factor_;

  // Periodic axes (0 = x, 1 = y) and the image slots of the last compute.
  struct PeriodicAxis {
    int axis;
    double min, max;  // m, the span [min, max)
  };
  std::vector<PeriodicAxis> periodic_;
  std::vector<Vec3> wrap_offset_;                               // m, per particle (only periodic)
  std::vector<std::uint32_t> f_image_source_, b_image_source_;  // image k (id size() + k) -> source id
  std::vector<Vec3> f_sort_position_, b_sort_position_;         // m, by id, images after the particles (only periodic)
  std::vector<std::uint32_t> f_slot_of_, b_slot_of_;            // sorted slot of each particle id (only periodic)
  std::vector<double> fm_wall_;  // kg, fm_ with the image slots 0: the wall forces count real fluid only

  // Boundary particles and their per-step state.
  physics::BoundaryParticles boundary_;
  std::vector<Vec3> boundary_force_;
  std::vector<double> boundary_stress_;  // Pa, 6 per boundary particle by id (only with stress)

  // Uniform grid (cell size 2h) and the cell-ordered working copies, single precision,
  // structure of arrays (fluid f*, boundary b*), padded by kLanes entries so that the
  // inner loops read whole blocks of kLanes slots. Positions are relative to grid_origin_.
  Vec3 grid_origin_ = Vec3::Zero();
  double inverse_cell_ = 1;
  std::int64_t nx_ = 0, ny_ = 0, nz_ = 0;
  std::vector<std::uint32_t> f_cell_start_, b_cell_start_;  // per cell + 1
  std::vector<std::uint32_t> f_order_, b_order_;            // sorted slot -> id
  std::vector<std::uint32_t> cell_next_;                    // build_grid() scratch: next free slot per cell
  std::vector<float> fx_, fy_, fz_, fvx_, fvy_, fvz_, frho_;
  std::vector<double> fm_;  // kg: the wall forces use the exact masses (action = reaction)
  // With boundary-particle walls, density diffusion acts between particles whose kernel held
  // at least kFullSupportFraction of a lattice's neighbours in fluid (walls not counted: the
  // diffusion sums fluid pairs only) in the last compute (at the first compute, every
  // particle): not across a free surface or beside a wall, where the cut-off sum is a one-sided
  // difference that drives the rows there (docs/physics.md, "Continuity").
  // Elastic-plastic particles always count as full: their top rows need the diffusion (a stiff
  // column at rest reached 0.32 sqrt(gH) and a 30 % pressure error without it).
  static constexpr double kFullSupportFraction = 0.9;
  std::vector<float> ffull_;                      // per sorted fluid slot: 1 if full, else 0
  std::vector<std::int32_t> support_neighbours_;  // per particle id: fluid neighbours in the last compute
  std::int32_t full_support_neighbours_ = 0;      // 0 (every particle full) with penalty walls
  std::vector<float> fpr_;                        // p / rho^2, Pa m^6/kg^2
  std::vector<std::uint32_t> fmat_;
  std::vector<float> bx_, by_, bz_, bwx_, bwy_, bwz_, bvol_, bpr_, brho_;  // bw: prescribed wall velocity
  // A free-slip wall particle's unit normal, zero for a no-slip one; empty, and the wall loops on the
  // plain approach (v_i - v_w).r, when no wall particle is free-slip (any_free_slip_).
  std::vector<float> bsx_, bsy_, bsz_;
  bool any_free_slip_ = false;
  std::vector<float> bvx_, bvy_, bvz_;  // wall velocity for the viscous terms (only with gradients)
  // Per sorted wall slot, only with credits_wall_work(): 1 / sum W (0: no credit) from
  // boundary_state(), then wall_compression()'s credit (one array: 4 bytes a wall slot).
  std::vector<float> bcredit_;
  std::vector<float> wall_work_held_;  // J per particle id (only with wall_work = "bounded"): bounded_credit()
  std::vector<double> fgrad_;          // 9 per sorted fluid particle: L = dv/dx (only with gradients)
  std::vector<float> fstress_;         // Pa, component q of slot s at q (n + kLanes) + s (only with stress)
  std::vector<float> fartificial_;     // artificial stress R / rho^2 per sorted slot like fstress_, Pa m^6/kg^2
  std::vector<float> bstress_;         // Pa, per sorted wall slot like fstress_: the fluid's stress extrapolated
  std::vector<double> bmoment_;        // kernel moments per sorted wall slot (only with stress; passes/walls.cpp)
  std::vector<float> feta_;            // effective viscosity per sorted fluid particle, Pa s (only with gradients)
  std::vector<double> out_drho_;       // drho/dt per sorted fluid particle, kg/m^3/s
  double max_mu_ = 0;                  // largest |h v_ij.r_ij / (r^2 + eta^2)| in the last compute, m/s
  double max_acceleration_ = 0;        // m/s^2, largest |a| in the last compute
  double min_viscous_dt_ = std::numeric_limits<double>::infinity();  // s
  // sph.viscous_operator = "strain_rate" with a viscous material: eta L~^T per sorted slot, component
  // ab (row-major) of slot s at (3 a + b) (n + kLanes) + s, L~ = L M^-1 the kernel-gradient-corrected
  // velocity gradient (compute_velocity_gradients), Pa. Empty otherwise.
  bool strain_rate_viscosity_ = false;
  std::vector<float> ftranspose_;

  double stable_dt_ = 0;
  double mean_neighbours_ = 0;
  std::int64_t neighbour_pairs_ = 0;  // pairs inside the support counted by mean_neighbours_
  bool forces_ready_ = false;
  Energies energies_;

  // Decomposition (only with ranks_).
  std::shared_ptr<parallel::Ranks> ranks_;
  parallel::Slabs slabs_;
  int slab_axis_ = 0;
  std::int64_t global_particles_ = 0;   // active fluid particles over all ranks at the last compute
  std::int64_t uniform_material_ = -1;  // the fluid's one material over all ranks, or -1
  std::size_t owned_count_ = 0, halo_count_ = 0;
  std::vector<std::uint8_t> fmine_, bmine_;  // per sorted slot: 1 where this rank computes it
  struct HaloSide {
    int rank;
    std::vector<std::uint32_t> fluid_send, fluid_receive, wall_send, wall_receive;  // sorted slots
  };
  std::vector<HaloSide> halo_;  // the lower and upper neighbour ranks that exist
  RemoteSampler remote_sampler_;
  std::vector<std::uint8_t> collected_active_;  // every particle's flag (only on rank 0 of ranks, see active())
};

}  // namespace sabo::sph
