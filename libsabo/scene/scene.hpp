#pragma once
// The scene model: what a validated scene file says. Every process builds its
// part of the simulation from this, and nothing else. The loader
// (scene/loader.hpp) guarantees every invariant documented here; values are SI.
// The TOML reference is docs/scene.md, generated from the schema (scene/schema.hpp).
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "libsabo/core/role.hpp"
#include "libsabo/core/types.hpp"

namespace sabo::scene {

// Where a value came from, for error messages raised after loading.
struct Origin {
  std::filesystem::path file;
  int line = 0;
  std::string key;  // dotted key, e.g. "particles[0].radius"
};

struct Material {
  std::string name;
  Origin origin;
  double density = 0;         // kg/m^3, > 0
  double youngs_modulus = 0;  // Pa, > 0
  double poisson_ratio = 0;   // in [0, 0.5)
  // Plasticity and failure of deformable structures (LS-DYNA MAT_PLASTIC_KINEMATIC);
  // absent: elastic, no failure.
  std::optional<double> yield_stress;      // Pa, > 0 (fluids: bingham tau_y, elastic_plastic von Mises sigma_y)
  double tangent_modulus = 0;              // Pa, in [0, E)
  double hardening = 0;                    // beta in [0, 1]: 0 kinematic, 1 isotropic
  std::optional<double> cowper_symonds_c;  // 1/s, > 0: strain-rate factor 1 + (rate / C)^(1/p)
  double cowper_symonds_p = 1;             // > 0
  std::optional<double> failure_strain;    // > 0: elements erode when failure_measure reaches it
  // What failure_strain bounds: the maximum principal (total) strain, or the effective plastic strain
  // (LS-DYNA MAT_PLASTIC_KINEMATIC's FS).
  enum class FailureMeasure { principal_strain, plastic_strain };
  FailureMeasure failure_measure = FailureMeasure::principal_strain;
  [[nodiscard]] double bulk_modulus() const { return youngs_modulus / (3.0 * (1.0 - 2.0 * poisson_ratio)); }
  [[nodiscard]] double shear_modulus() const { return youngs_modulus / (2.0 * (1.0 + poisson_ratio)); }

  // Keys read by the sph_solver when a fluid body uses this material (ignored otherwise).
  // Equation of state, mu = rho/rho0 - 1, B = rho0 c^2 / gamma with c = SphSettings::sound_speed:
  //   tait:       p = B ((rho/rho0)^gamma - 1)
  //   polynomial: p = C0 + s (C1 mu + C2 mu^2 + C3 mu^3), s = rho0 c^2 / C1, so the initial
  //               stiffness is the artificial sound speed's while the shape of the curve is kept.
  enum class Eos { tait, polynomial };
  Eos eos = Eos::tait;
  double tait_exponent = 7.0;                             // gamma, >= 1
  double eos_c0 = 0, eos_c1 = 0, eos_c2 = 0, eos_c3 = 0;  // Pa (polynomial; C1 > 0)
  // Rheology: only the terms a material asks for are computed. The viscous stress is
  // 2 eta(gamma_dot) D (SphSettings::viscous_operator), gamma_dot = sqrt(2 D':D').
  //   inviscid:         no physical viscosity (artificial viscosity only)
  //   newtonian:        dynamic viscosity `viscosity`
  //   bingham:          regularised: eta = viscosity + yield_stress (1 - exp(-gamma_dot/yield_shear_rate)) / gamma_dot
  //                     (Papanastasiou), plastic viscosity `viscosity`
  //   herschel_bulkley: eta = consistency_index max(gamma_dot, yield_shear_rate)^(flow_index - 1)
  //                     + yield_stress (1 - exp(-gamma_dot/yield_shear_rate)) / gamma_dot: the yield term
  //                     regularised as bingham's, the power law held at its value at yield_shear_rate below it
  //   elastic_plastic:  deviatoric stress with Jaumann rate, shear modulus `fluid_shear_modulus`,
  //                     von Mises yield `yield_stress`, radial return (LS-DYNA MAT_ELASTIC_PLASTIC_HYDRO)
  enum class Rheology { inviscid, newtonian, bingham, herschel_bulkley, elastic_plastic };
  Rheology rheology = Rheology::inviscid;
  double viscosity = 0;            // Pa s (newtonian: dynamic; bingham: plastic)
  double yield_shear_rate = 1.0;   // 1/s (bingham and herschel_bulkley regularisation)
  double consistency_index = 0;    // Pa s^n (herschel_bulkley: K, > 0)
  double flow_index = 1.0;         // herschel_bulkley: n, > 0 (< 1 shear-thinning)
  double fluid_shear_modulus = 0;  // Pa (elastic_plastic; 0: shear_modulus() from E and nu)
  // Monaghan's artificial stress against the tensile instability (elastic_plastic only): its
  // epsilon (0: off); absent: sph::kDefaultArtificialStress for elastic_plastic, none otherwise.
  std::optional<double> artificial_stress;
};

struct RunSettings {
  double end_time = 0;         // s, > 0
  double output_interval = 0;  // s, > 0
  // "ipc" (socket in the run folder), "tcp" (this machine only, a free port) or "tcp://HOST:PORT" (PORT "*":
  // a free one)
  std::string endpoint = "ipc";
  // tcp: CURVE (docs/security.md) or, only when asked for, nothing at all.
  enum class TcpSecurity { curve, none };
  TcpSecurity tcp_security = TcpSecurity::curve;
  // Whether a coupler at `endpoint` (the scene's, or the one it reported: tcp://HOST:PORT) takes no keys.
  [[nodiscard]] bool tcp_in_clear(const std::string& at) const {
    return at.starts_with("tcp") && tcp_security == TcpSecurity::none;
  }
  // s: a connection silent this long (ZMTP heartbeats) is closed, and a solver on it declared lost
  double heartbeat_timeout = 5.0;
  // The host solvers started through a launcher connect to; empty: the endpoint's address (the supervisor's
  // host name when that is 0.0.0.0).
  std::string connect_host;
  Origin endpoint_origin;              // where endpoint (or, when absent, [run]) is written, for warnings
  Vec3 gravity{0, 0, -9.81};           // m/s^2
  double hang_timeout = 10.0;          // s: a solver silent this long is declared hung
  double registration_timeout = 30.0;  // s: the coupler waits this long for every solver to register
  std::optional<double> max_dt;        // s: upper bound on the coupled dt
  // m/s: a particle or node faster than this is an instability (libsabo/solver/stability.hpp); absent: derived
  std::optional<double> max_speed;
  // Each solver at a power-of-two fraction of the exchange step, contact forces held between exchanges
  // (docs/architecture.md, "Multirate"); false: every solver at the smallest stable step (paper eq. 7).
  bool multirate = false;
  // With multirate: a solver may step less often than it exchanges (docs/protocol.md, "Hold exchanges").
  bool hold_exchanges = true;
  // s between checkpoints; absent: end_time / 10; 0: none (checkpoint_period() resolves it).
  std::optional<double> checkpoint_interval;
  std::size_t checkpoints_kept = 2;
  bool restart = true;                 // "auto": a solver that dies is restarted from its newest checkpoint
  std::size_t max_restarts = 3;        // per process
  double restart_journal_limit = 4.0;  // GB of forces the coupler keeps per solver since its newest checkpoint
  [[nodiscard]] double checkpoint_period() const { return checkpoint_interval.value_or(end_time / 10); }
};

// One solver process. `command` is the program and its fixed arguments; the
// supervisor appends --scene, --coupler, --out. Empty: the built executable.
struct SolverSettings {
  Role role = Role::dem;
  std::vector<std::string> command;
  double beta = 1.0;  // eq. 7 scale of this solver's stable dt, in (0, 1]
  Origin origin;
  // A command prefix that places the process (["ssh", "node2"], ["srun", "--het-group=1"]); empty: started here.
  std::vector<std::string> launcher;
  bool by_hand = false;  // the supervisor does not start it: a user does, on any host (docs/cluster.md)
};

struct Sphere {
  Vec3 center = Vec3::Zero();            // m
  double radius = 0;                     // m, > 0
  Vec3 velocity = Vec3::Zero();          // m/s
  Vec3 angular_velocity = Vec3::Zero();  // rad/s
};

// How the diameters of a fill set are drawn.
enum class SizeDistribution {
  uniform,  // uniform in [diameter_min, diameter_max]
  normal,   // normal(mean_diameter, std_diameter), redrawn until inside [diameter_min, diameter_max]
  sieve,    // grading curve: sieve rows [diameter, cumulative fraction passing], uniform within a class
};

// A set of DEM spheres: an explicit list, or a region (box, or a polygon in the x-z plane
// extruded along y) filled with a seeded random non-overlapping set of spheres whose
// diameters follow `distribution`; optionally settled under gravity inside the region
// before step 0.
struct ParticleSet {
  enum class Kind { list, fill };
  std::string name;
  std::string material;  // a key of Scene::materials (checked)
  Origin origin;
  Kind kind = Kind::list;
  std::vector<Sphere> spheres;  // kind == list (checked: no overlap)
  // kind == fill. region: the box; for a polygon, its bounding box (y from y_range).
  Aabb region;
  // Polygon (x, z) vertices in order, m: a simple polygon with positive area (checked). Empty: a box.
  std::vector<std::array<double, 2>> polygon_xz;
  std::size_t count = 0;
  SizeDistribution distribution = SizeDistribution::uniform;
  double diameter_min = 0, diameter_max = 0;   // m: range (uniform), clip range (normal), first/last sieve
  double mean_diameter = 0, std_diameter = 0;  // m, normal
  // Grading curve: rows [diameter m, fraction finer than it], diameters strictly increasing, fractions
  // non-decreasing from 0 (first row) to 1 (last row). Class k lies between rows k-1 and k.
  std::vector<std::array<double, 2>> sieve;
  bool sieve_by_mass = true;  // fractions of the mass (true) or of the count (false)
  std::uint64_t seed = 1;
  Vec3 velocity = Vec3::Zero();  // m/s, initial velocity of filled spheres
  double settle_time = 0;        // s: settle under gravity inside the region before step 0 (0: no)
  // The set's spheres never move (a glued bed of beads): they take any force, their contacts count.
  bool fixed = false;

  // Probability that a drawn sphere belongs to sieve class k (k = 1 .. rows-1; entry 0 is 0).
  [[nodiscard]] std::vector<double> sieve_class_probabilities() const;
  // Expected volume of one sphere of the distribution, m^3.
  [[nodiscard]] double mean_sphere_volume() const;
  // Volume of the fill region, m^3.
  [[nodiscard]] double region_volume() const;
  // Whether a sphere lies entirely inside the region (polygon: at least `radius` from every edge).
  [[nodiscard]] bool contains_sphere(const Vec3& center, double radius) const;
};

enum class DemLaw { linear, hertz_mindlin };
enum class RollingModel {
  constant,  // elastic-plastic rolling spring capped at mu_r r_eff F_n
  viscous,   // torque -rolling_viscosity r_eff F_n (r_eff w_rel): mu_r grows with the rolling speed
};

// The contact law of one pair of materials in the dem_solver.
struct DemContactLaw {
  DemLaw model = DemLaw::linear;
  double normal_damping_ratio = 0.7;      // zeta_n in [0, 1), linear
  double tangential_damping_ratio = 0.4;  // zeta_t in [0, 1), linear (and the rolling spring's dashpot)
  double restitution = 0.5;               // e in (0, 1], hertz_mindlin
  double friction = 1.0;                  // sliding, >= 0
  double rolling_friction = 0.1;          // >= 0, dimensionless (torque = mu_r * r_eff * |F_n|), constant
  RollingModel rolling = RollingModel::constant;
  double rolling_viscosity = 0;  // s/m, viscous
  [[nodiscard]] bool has_rolling() const {
    return rolling == RollingModel::constant ? rolling_friction > 0 : rolling_viscosity > 0;
  }
};

// A per-material-pair override of [contact.dem_dem].
struct DemPairLaw {
  std::string material_a, material_b;  // keys of Scene::materials (checked), a <= b
  Origin origin;
  DemContactLaw law;
};

// DEM-DEM contact (dem_solver): linear spring-dashpot or Hertz-Mindlin (no-slip),
// tangential spring with a Coulomb limit, rolling resistance; per pair of materials.
struct DemContact : DemContactLaw {
  // Normal stiffness of the linear law: explicit (N/m), or LS-DYNA's NormK scale:
  // k_n = scale * K1 r1 K2 r2 / (K1 r1 + K2 r2), K the bulk modulus.
  std::optional<double> normal_stiffness;
  double normal_stiffness_scale = 0.01;
  double tangential_stiffness_ratio = 2.0 / 7.0;  // k_t = ratio * k_n
  std::vector<DemPairLaw> pairs;                  // overrides

  // The law of a pair of materials: its override, or the defaults above.
  [[nodiscard]] const DemContactLaw& law(const std::string& material_a, const std::string& material_b) const;
};

// The size of a structure's mesh file as its reader reads it (io/stl.hpp, io/gmsh.hpp), before the
// scene's scale: the scene check reads every mesh file (scene/estimate.hpp uses the sizes).
struct MeshSize {
  std::size_t nodes = 0;
  std::size_t triangles = 0;  // STL
  std::size_t hexahedra = 0;  // Gmsh
  std::size_t quads = 0;      // Gmsh
  double area = 0;            // m^2, STL: of the surface
  double smallest = 0;        // m, Gmsh: the smallest element's length (cube root of a hexahedron's
                              // volume, square root of a quadrangle's area)
};

// The geometry of one structure part (FEM).
struct Shape {
  enum class Type { plane, box, chute, channel, mesh, terrain };
  Type type = Type::plane;
  // plane: a finite rectangle centred at `origin`, normal `normal`, sides
  // `length` (along `direction` projected on the plane) and `width`.
  Vec3 origin = Vec3::Zero();
  Vec3 normal{0, 0, 1};
  Vec3 direction{1, 0, 0};
  double length = 0, width = 0;
  // box: closed surface of [min, max], outward normals.
  Aabb box;
  // chute: floor starting at `origin` (centre of its upper edge), running
  // `length` along `direction` (horizontal) and down at `slope_deg`, `width`
  // wide, with side walls `wall_height` high; `end_wall_height` > 0 closes
  // the lower end with a wall normal to the floor direction.
  double slope_deg = 0;
  double wall_height = 0;
  double end_wall_height = 0;
  // channel: a floor `width` wide along the longitudinal profile (s, z), s (m) the horizontal distance
  // along `direction` from `origin` (whose z is ignored), z (m) the bed's absolute elevation; vertical
  // side walls `wall_height` above the bed, `start_wall_height` > 0 and `end_wall_height` > 0 close the
  // first and last ends. s strictly increasing (checked), at least two points.
  std::vector<std::array<double, 2>> profile;
  double start_wall_height = 0;
  bool floor = true;  // channel: false leaves the floor out (its walls as a part of their own)
  // mesh: STL file (ASCII or binary), resolved to an absolute path; scaled
  // then translated.
  std::filesystem::path file;
  double scale = 1.0;
  Vec3 translate = Vec3::Zero();
  MeshSize mesh_size;  // mesh: the file's, filled by the loader
  // terrain: the elevation raster `file` (io/raster.hpp; resolved to an absolute path), in the raster's
  // coordinates (x, y, elevation), then translated by `translate`. The ground kept is a `strip` along a
  // polyline (x, y), `strip_width` wide, or the inside of `clip_polygon` (x, y), or the whole raster.
  std::vector<std::array<double, 2>> strip;
  double strip_width = 0;
  std::vector<std::array<double, 2>> clip_polygon;
  std::string raster;       // terrain: what the loader read (io::Raster::describe()), for the logs
  double element_size = 0;  // m: target triangle edge for generated shapes (0: coarsest)
};

// Degrees of freedom held by a deformable structure's constraint on the nodes it selects (zero
// velocity along each from the start): translations along x, y, z and, for shells, rotations about
// them. Bits of Constraint::dofs.
struct Constraint {
  static constexpr unsigned x = 1, y = 2, z = 4, rx = 8, ry = 16, rz = 32;
  static constexpr unsigned translations = x | y | z, rotations = rx | ry | rz;
  enum class Selection {
    box,  // the nodes inside `box` (its faces included), in the structure's final coordinates
    tag,  // the nodes of the elements of the physical group `tag` of the structure's Gmsh mesh
  };
  Selection selection = Selection::box;
  Aabb box;         // m
  std::string tag;  // a physical group of Shape::file (checked: exists, not empty)
  // Constraint bits; "all" in the scene is every DOF the structure's nodes have (translations on solids,
  // translations and rotations on shells).
  unsigned dofs = 0;
  bool all = false;  // the scene said "all"
  Origin origin;     // the constraint's table
};

struct Structure {
  std::string name;
  std::string material;  // a key of Scene::materials (checked)
  Origin origin;
  // Rigid: fixed in space, any shape. Deformable (rigid = false): a box of
  // hexahedra (thickness 0), a thin-walled building of shells (a box with a
  // thickness: four walls, floors - 1 slabs and a roof), or a shell panel (a
  // plane with a thickness), with elements of about element_size.
  bool rigid = true;
  double roof_thickness = 0;  // m, building slabs (0: thickness)
  std::string roof_material;  // building slabs (empty: material)
  std::size_t floors = 1;     // building storeys (>= 1)
  // Deformable solid box: a slit dam, slit_count vertical slits (open at the
  // top, slit_depth deep, slit_width wide) through the box along slit_axis
  // (0: x, 1: y), spaced so that the slit_count + 1 piers are equally wide.
  std::size_t slit_count = 0;
  double slit_width = 0;  // m
  double slit_depth = 0;  // m
  int slit_axis = 1;
  // Deformable: faces "x-", "x+", "y-", "y+", "z-", "z+" of the box around the structure's nodes (a box
  // shape: its own faces) whose nodes have every DOF fixed.
  std::vector<std::string> fixed_faces;
  std::vector<Constraint> constraints;  // deformable: per-direction constraints, in file order
  Vec3 velocity = Vec3::Zero();         // m/s, deformable: initial velocity
  // Deformable solids: one-point hexahedra with hourglass control, or fully
  // integrated (2 x 2 x 2 points, mean dilatation) or enhanced-strain (2 x 2 x 2
  // points, condensed incompatible modes) without zero-energy modes.
  enum class ElementFormulation { one_point, fully_integrated, enhanced_strain };
  ElementFormulation element_formulation = ElementFormulation::one_point;
  double thickness = 0;  // m: shell thickness for the eq. 3 offset (0: solid face)
  Shape shape;
};

// Penalty contact of particles against structure surfaces, computed by the
// coupler (paper eqs. 3-6). Defaults for every pair; `pairs` override per pair.
struct SurfaceContact {
  enum class Model {
    penalty,        // paper eqs. 3-6
    hertz_mindlin,  // Hertz-Mindlin (no-slip) against a flat face, damping from the restitution
  };
  Model model = Model::penalty;
  double restitution = 0.5;                // e in (0, 1], hertz_mindlin
  double friction = 0.3;                   // mu >= 0
  double penalty_scale = 0.1;              // k1 of eq. 6
  std::optional<double> normal_stiffness;  // N/m: replaces eq. 6 when given
  double normal_damping_ratio = 0.0;       // zeta: c_n = 2 zeta sqrt(k_n m)
  double tangential_damping_ratio = 0.0;   // zeta_t (and the rolling spring's dashpot)
  // Rolling resistance of spheres against the structure (particle sets only), the models of
  // DemContactLaw with r_eff = the sphere's radius: off unless rolling_friction (constant) or
  // rolling_viscosity (viscous) is > 0.
  RollingModel rolling = RollingModel::constant;
  double rolling_friction = 0.0;   // mu_r >= 0, constant
  double rolling_viscosity = 0.0;  // s/m, viscous
  bool enabled = true;
  [[nodiscard]] bool has_rolling() const {
    return rolling == RollingModel::constant ? rolling_friction > 0 : rolling_viscosity > 0;
  }
};

// Contact between two structures (FEM-FEM), computed by the fem_solver: the nodes of each against the
// faces of the other, with the penalty law of SurfaceContact (eqs. 3-6, no Hertz-Mindlin, no rolling).
struct FemFemInteraction {
  std::string a, b;  // two structures, not both rigid (checked), in file order of the pair
  Origin origin;
  SurfaceContact contact;  // defaults filled from [contact.fem_fem]; enabled unless the pair says false
};

struct Interaction {
  std::string a, b;    // a particle set or a fluid body, and a structure (checked)
  bool fluid = false;  // a is a fluid body (defaults from [contact.sph_fem])
  Origin origin;
  SurfaceContact contact;  // defaults filled from [contact.dem_fem]
};

// Contact of fluid particles with DEM spheres (boulders), computed by the coupler: the defaults in
// [contact.sph_dem], per (fluid body, particle set) overrides in [[interactions]] (docs/physics.md,
// "SPH-DEM").
struct SphDemContact {
  enum class Model {
    // Each sphere's surface sampled as SPH wall particles moving with it (v + w x r): the fluid's
    // pressure and viscous stress act on it, so buoyancy and drag come out of the fluid's physics.
    boundary_particles,
    // Paper eqs. 1-2: a node-to-node spring-dashpot along the line of centres, overlap
    // h_i + r_j - d with h_i the SPH particle's contact radius (its particle table radius).
    penalty,
  };
  Model model = Model::boundary_particles;
  std::optional<double> normal_stiffness;  // N/m (penalty); absent: Scene::sph_dem_derived_stiffness
  double normal_damping_ratio = 0.0;       // zeta in [0, 1) (penalty): eta = 2 zeta sqrt(K m*)
  double friction = 0.0;                   // Coulomb mu >= 0 (penalty), tangential spring k_t = K
  bool enabled = true;
};

struct SphDemInteraction {
  std::string fluid, set;  // a fluid body and a particle set (checked)
  Origin origin;
  SphDemContact contact;  // defaults filled from [contact.sph_dem]
};

// A boulder for boundary particles spans at least this many SPH spacings (its diameter; checked).
inline constexpr double kMinBoundaryParticleDiameter = 2.0;

// Weakly compressible SPH (sph_solver). The loader fills these from [sph]
// and [[fluids]]; the sph_solver helper owns their keys and may add fields.
// The coupler reads particle_spacing, smoothing_ratio, kernel, wall_model and
// wall_spacing_ratio to sample FEM surfaces as boundary particles (wall_model ==
// boundary_particles: ceil(kernel_support / wall_spacing) layers behind each wall surface).
struct SphSettings {
  enum class Kernel { wendland_c2, cubic_spline };
  enum class WallModel { penalty, boundary_particles };
  double particle_spacing = 0;   // m: initial particle spacing dx, > 0
  double smoothing_ratio = 1.5;  // h / dx (Wendland C2 at 1.3 does not keep a lattice at rest)
  Kernel kernel = Kernel::wendland_c2;
  WallModel wall_model = WallModel::boundary_particles;
  // Boundary particles: what becomes of the work of the walls' extrapolated pressure
  // (SphModel::wall_compression, docs/physics.md "Energy"): unstored (Adami et al. 2012 as
  // published), stored as the fluid's compression, or stored only where leaving it would raise
  // the energy (bounded: a per-particle account of the work held back).
  enum class WallWork { bounded, stored, unstored };
  WallWork wall_work = WallWork::bounded;
  // Boundary particles: the structures whose wall particles are free-slip (the fluid keeps its tangential
  // velocity there: no shear from that wall, viscous or artificial); the others are no-slip.
  std::vector<std::string> free_slip_walls;
  // Boundary particles: the structures' wall particles sit on a lattice of this fraction of dx
  // (wall_spacing()), volume (ratio dx)^3, as many layers as fill the kernel support.
  double wall_spacing_ratio = 1.0;
  // Boundary particles (walls or boulders): the fluid computes its forces of step n while the coupler computes
  // its contacts, with the wall particles of step n - 1 moved ahead one step by their velocity and acceleration,
  // instead of waiting for those of step n (docs/protocol.md, StepState.boundary_step = n - 2).
  bool lagged_boundary_particles = false;
  double sound_speed = 0;              // m/s: artificial sound speed c of every fluid, > 0
  double cfl = 0.25;                   // stable dt = cfl * min(h / (c + h |div v|), sqrt(h / |a|), rho h^2 / (8 eta))
  double artificial_viscosity = 0.01;  // Monaghan alpha
  enum class DensityDiffusion { none, molteni, fourtakas };
  DensityDiffusion density_diffusion = DensityDiffusion::fourtakas;
  double density_diffusion_delta = 0.1;  // delta of delta-SPH
  std::optional<Aabb> domain;            // particles leaving it are taken out of the simulation (counted, logged)
  // rho / rho0 outside [min, max] is an instability (libsabo/solver/stability.hpp)
  std::array<double, 2> density_ratio_limits{0.5, 2.0};
  // Periodic boundaries, m: [min, max) along x and y; a particle leaving it re-enters at the
  // other end, and the fluid sees across the seam (docs/physics.md, "Periodic boundaries").
  std::optional<std::array<double, 2>> periodic_x, periodic_y;
  // The viscous term (docs/physics.md, "Viscosity"): strain_rate, the divergence of
  // 2 eta D = eta (L + L^T) (Morris et al.'s pair term for eta L plus the symmetric SPH
  // divergence of each particle's eta L^T); morris, Morris et al. 1997's pair term alone,
  // the divergence of eta L, which equals div(2 eta D) only where eta is uniform and the
  // flow incompressible and far from a free surface.
  enum class ViscousOperator { strain_rate, morris };
  ViscousOperator viscous_operator = ViscousOperator::strain_rate;
  [[nodiscard]] double smoothing_length() const { return smoothing_ratio * particle_spacing; }
  [[nodiscard]] double kernel_support() const { return 2.0 * smoothing_length(); }             // both kernels: 2h
  [[nodiscard]] double wall_spacing() const { return wall_spacing_ratio * particle_spacing; }  // m
  // Layers of an inflow's buffer (InflowSection): enough that the fluid just past the section sees a full
  // kernel support of them, ceil(2h / dx) + 1.
  [[nodiscard]] std::size_t inflow_buffer_layers() const {
    return static_cast<std::size_t>(std::ceil(kernel_support() / particle_spacing - 1e-9)) + 1;
  }
};

// The particles of an inflow's section on the lattice of spacing dx (InflowSection::lattice).
struct InflowLattice {
  std::size_t across = 0;         // n_w = round(width / dx), at least 1
  std::size_t up = 0;             // n_d = round(depth / dx), at least 1
  std::size_t buffer_layers = 0;  // SphSettings::inflow_buffer_layers()
  std::size_t layers = 0;         // every layer a run to its end time can need: the buffer's and those released
  double area = 0;                // m^2, n_w n_d dx^2: the section's discharge is U * area
  [[nodiscard]] std::size_t per_layer() const { return across * up; }
  [[nodiscard]] std::size_t particles() const { return per_layer() * layers; }
};

// Where an inflow ([[inflows]], docs/scene.md) brings fluid in: a rectangular cross-section and its
// hydrograph. The section's frame: `direction` (the flow, its normal), across() (horizontal) and up()
// (perpendicular to both, upwards); the section spans [-width/2, width/2] across and [0, depth] up from
// `position`. The sph_solver (sph_solver/inflow.hpp) moves a buffer of particle layers behind it at the
// section's mean velocity Q(t) / A and releases each layer into the flow as it crosses the section.
struct InflowSection {
  Vec3 position = Vec3::Zero();  // m: the middle of the section's bottom edge
  Vec3 direction{1, 0, 0};       // unit, not vertical
  double width = 0;              // m, > 0
  double depth = 0;              // m, > 0
  // (t in s, Q in m^3/s): t strictly increasing from >= 0, Q >= 0, linear between the points, 0 before the
  // first and after the last.
  std::vector<std::array<double, 2>> hydrograph;

  // z x direction, normalised (direction is not vertical).
  [[nodiscard]] Vec3 across() const { return Vec3(-direction.y(), direction.x(), 0.0).normalized(); }
  // direction x across().
  [[nodiscard]] Vec3 up() const {
    const Vec3 a = across(), d = direction;
    return {d.y() * a.z() - d.z() * a.y(), d.z() * a.x() - d.x() * a.z(), d.x() * a.y() - d.y() * a.x()};
  }
  [[nodiscard]] double discharge(double t) const;             // m^3/s
  [[nodiscard]] double volume(double from, double to) const;  // m^3: the integral of Q over [from, to]
  [[nodiscard]] double peak_discharge() const;                // m^3/s
  [[nodiscard]] double end_time() const { return hydrograph.empty() ? 0.0 : hydrograph.back()[0]; }
  // The section's lattice for `sph` and a run that ends at `run_end` (s).
  [[nodiscard]] InflowLattice lattice(const SphSettings& sph, double run_end) const;
};

// One body of slurry, filled with particles on a cubic lattice of spacing
// SphSettings::particle_spacing (particle centres dx/2 inside the shape's boundary).
//   box:              the box [box.min, box.max]
//   extruded_polygon: the polygon `profile` given in the vertical plane through
//                     `profile_origin` spanned by the horizontal `direction` (first
//                     coordinate) and z (second), extruded `width` across, centred on
//                     that plane.
// Initial state: `velocity`; with `hydrostatic`, the pressure of the fluid column
// above each particle (density from the EOS), so that a body at rest starts at rest.
struct FluidBody {
  // inflow: a body of the [[inflows]] list, which fills through `inflow` during the run instead.
  enum class Shape { box, extruded_polygon, inflow };
  std::string name;
  std::string material;  // a key of Scene::materials (checked)
  Origin origin;
  Shape shape = Shape::box;
  Aabb box;                                    // m, box
  std::vector<std::array<double, 2>> profile;  // m, extruded_polygon: (along direction, z), >= 3 points
  Vec3 profile_origin = Vec3::Zero();          // m
  Vec3 direction{1, 0, 0};                     // horizontal unit vector
  double width = 0;                            // m, > 0
  Vec3 velocity = Vec3::Zero();                // m/s
  bool hydrostatic = true;
  // s: a damped settling phase from t = 0 (0: none): the body's velocities are relaxed until
  // then and zeroed at its end, so that the body starts from the discrete equilibrium of its
  // particles and walls rather than the continuum's hydrostatic fill (docs/physics.md, "Settling").
  // A settling body starts at rest (checked).
  double settle_time = 0;
  InflowSection inflow;  // shape inflow

  // The box around the body's shape, m (an inflow: its section).
  [[nodiscard]] Aabb bounds() const;
};

// The settling phase's velocity damping v <- v exp(-dt / tau) has tau = h / c at t = 0 and
// grows linearly to kSettleDampingGrowth h / c at the phase's end.
inline constexpr double kSettleDampingGrowth = 20.0;

// A pressure gauge of the sph_solver (gauges.csv, docs/scene.md [[gauges]]): one point, or `points`
// equally spaced points from `start` to `end` (a line; its free-surface depth is measured along it).
struct Gauge {
  std::string name;
  Origin origin;
  Vec3 start = Vec3::Zero();                      // m; the point of a point gauge
  Vec3 end = Vec3::Zero();                        // m; = start for a point gauge
  std::size_t points = 1;                         // 1: a point gauge, >= 2: a line
  static constexpr std::size_t kLinePoints = 20;  // a line gauge's points when the scene does not say
  double interval = 0;                            // s between two samples; 0: the run's output_interval
  [[nodiscard]] bool line() const { return points > 1; }
  // Point k of the gauge, m.
  [[nodiscard]] Vec3 point(std::size_t k) const {
    return points > 1 ? start + (end - start) * (static_cast<double>(k) / static_cast<double>(points - 1)) : start;
  }
};

// A front tracker of the sph_solver (fronts.csv, front_stations.csv, summary.json `results.sph_solver.fronts`;
// docs/scene.md [[fronts]]): the flow's leading edge along a straight path over time, and the flow depth
// at named stations along it.
struct Front {
  enum class Kind { axis, channel, terrain };
  struct Station {
    std::string name;
    double at = 0;  // m, the distance along the path
  };
  std::string name;
  Origin origin;
  Kind kind = Kind::axis;
  // axis: distance s = (x - start) . direction (unit); the station's depth is measured vertically up from
  // start + s direction. channel: the path is the channel structure's centre line (its direction and the
  // profile's distance); the depth is measured vertically up from the bed.
  Vec3 start = Vec3::Zero();
  Vec3 direction{1, 0, 0};
  std::string channel;                     // a channel structure (checked)
  std::vector<std::array<double, 2>> bed;  // channel: its profile (s, z); empty for an axis
  // terrain: the path is the centre line of a terrain structure's strip (`structure`, checked), each point at
  // the ground's elevation (geometry::terrain_centre_line), s the horizontal distance along it from its first
  // point (path_s); a particle's s is that of its nearest point of the line seen from above.
  std::string structure;
  std::vector<Vec3> path;
  std::vector<double> path_s;
  std::size_t ahead = 0;                        // particles allowed ahead of the front (spray)
  double interval = 0;                          // s between two samples; 0: the run's output_interval
  double depth_height = 0;                      // m, the height of a station's vertical line
  static constexpr double kDepthHeight = 50.0;  // m, without a depth_height or an SPH domain
  std::vector<Station> stations;
  // The point of the path at distance s, m: on the axis, on the channel's bed, or on the terrain's ground.
  [[nodiscard]] Vec3 path_point(double s) const;
  // Where x is along the path: its distance s (m) and the path's unit direction there.
  struct Projection {
    double s = 0;
    Vec3 tangent{1, 0, 0};
  };
  [[nodiscard]] Projection project(const Vec3& x) const;
};

// A force sensor of the coupler (sensors.csv, docs/scene.md [[sensors]]): the part of structure `part`'s
// surface inside `box` (the whole part when absent), with the force each source puts on it.
struct Sensor {
  std::string name;
  Origin origin;
  std::string part;         // a structure name (checked)
  std::optional<Aabb> box;  // m
};

// What the coupler records into traffic.h5.
struct Recording {
  bool enabled = true;
  // Fields: position, velocity, angular_velocity, force, torque,
  // node_position, node_velocity, node_force, energies. Empty = all.
  std::vector<std::string> fields;
  std::uint64_t every = 1;  // record every N-th step
  std::uint64_t first_step = 0;
  std::uint64_t last_step = UINT64_MAX;
  double flush_interval = 0.2;  // s of wall time between flushes
};

struct Scene {
  std::filesystem::path file;  // absolute path of the scene file
  int format_version = 1;
  RunSettings run;
  std::vector<SolverSettings> solvers;     // only the roles the scene needs
  std::vector<Material> materials;         // sorted by name; index = material id
  std::vector<ParticleSet> particle_sets;  // DEM bodies, in file order
  std::vector<Structure> structures;       // FEM parts, in file order
  std::vector<FluidBody> fluids;           // SPH bodies, in file order: [[fluids]], then [[inflows]]
  SphSettings sph;
  DemContact dem_contact;
  SurfaceContact dem_fem_default;
  SurfaceContact sph_fem_default;                       // SPH particles against FEM surfaces (wall_model == penalty)
  std::vector<Interaction> interactions;                // explicit per-pair settings
  SphDemContact sph_dem_default;                        // fluid particles against DEM spheres
  std::vector<SphDemInteraction> sph_dem_interactions;  // per (fluid body, particle set)
  // Structure against structure ([contact.fem_fem]): off unless its `enabled` or a pair's interaction.
  SurfaceContact fem_fem_default = [] {
    SurfaceContact contact;
    contact.enabled = false;
    return contact;
  }();
  std::vector<FemFemInteraction> fem_fem_interactions;  // per pair of structures
  std::vector<Gauge> gauges;                            // the sph_solver's, in file order
  std::vector<Front> fronts;                            // the sph_solver's, in file order
  std::vector<Sensor> sensors;                          // the coupler's, in file order
  Recording recording;

  [[nodiscard]] bool needs(Role role) const;
  [[nodiscard]] const SolverSettings* solver(Role role) const;
  [[nodiscard]] std::size_t material_index(const std::string& name) const;  // asserts it exists
  // Contact settings for particle set or fluid body `set` against structure `structure`.
  [[nodiscard]] SurfaceContact surface_contact(const std::string& set, const std::string& structure) const;
  // Contact settings of the nodes of structure `a` against the faces of structure `b`: the pair's
  // interaction (either order), else [contact.fem_fem]; disabled for a structure with itself, two rigid
  // structures or names that are not structures.
  [[nodiscard]] SurfaceContact fem_fem_contact(const std::string& a, const std::string& b) const;
  // Contact settings of fluid body `fluid` against particle set `set`: its interaction, else [contact.sph_dem].
  [[nodiscard]] SphDemContact sph_dem_contact(const std::string& fluid, const std::string& set) const;
  // Whether particle set `set` meets the fluid as boundary particles (every fluid pair of a set agrees; checked).
  [[nodiscard]] bool boundary_particle_set(const std::string& set) const;
  // Whether the sph_solver receives boundary particles (structure walls or boulder surfaces): it then
  // computes its forces once the coupler's StepForces has brought them.
  [[nodiscard]] bool sph_receives_boundary_particles() const;
  // The penalty stiffness of fluid body `fluid` against spheres when normal_stiffness is absent, N/m:
  // the fluid's own stiffness rho0 c^2 dx (bulk modulus rho0 c^2 over a particle's face dx^2, across
  // its spacing dx), lowered where needed so that the pair's stable step 0.2 pi sqrt(m / K), m = rho0
  // dx^3, is not below the SPH's acoustic step cfl h / c.
  [[nodiscard]] double sph_dem_derived_stiffness(const FluidBody& fluid) const;
  // The SPH's acoustic step cfl h / c (s), and the stable step 0.2 pi sqrt(m / K) of a fluid particle
  // of body `fluid` (m = rho0 dx^3) on a penalty spring of stiffness K (N/m).
  [[nodiscard]] double sph_acoustic_dt() const;
  [[nodiscard]] double sph_dem_pair_dt(const FluidBody& fluid, double stiffness) const;
};

}  // namespace sabo::scene
