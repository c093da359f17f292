#pragma once
// Penalty contact of particles (DEM spheres, SPH particles) against the
// triangulated surface of the FEM solver (docs/physics.md "Particle-surface
// contact", paper eqs. 3-6). Computed by the coupler once per step (DEM-FEM,
// penalty SPH-FEM), and by the fem_solver for the nodes of one structure
// against the faces of another (fem_solver/structure_contact.hpp).
//
// Search: triangle bounds are binned in a physics::CellList whose cell is the
// larger of the median triangle size and the largest particle's reach; it is
// rebuilt only when the nodes move, the topology changes or a larger particle
// comes. Each particle queries the box of its reach (radius * (1 +
// potential_margin) + largest thickness / 2): cost linear in particles.
// The faces that never move (grid_) are looked up once for a box a skin
// (kCandidateSkin of the reach) larger, kept per particle id, and filtered by
// the query box each step until the particle leaves that box or the grid is
// rebuilt: the same candidates, without walking the grid every step (a large
// face is binned in every cell it covers and was visited once per cell).
// Faces with a thickness are two-sided, faces without are one-sided (see
// sphere_triangle.hpp).
//
// Per particle: the triangles near it come from the grid; each gives its
// closest point and the feature it lies on (face, edge, vertex). A surface
// made of many triangles must give one contact where it is one surface, so:
//  1. an edge or vertex contact counts only if every triangle around that
//     edge or vertex has its closest point on it (the feature is a local
//     minimum of the distance: the convex edge of a box counts, the shared
//     edge of a flat floor does not, because the neighbour's face is closer);
//  2. the same edge or vertex reached from several triangles counts once;
//  3. contacts on triangles that share a node and whose normals differ by
//     less than SurfaceContactOptions::smooth_angle_deg are one contact, the
//     deepest (a flat floor crossed on a shared edge, a shallow fold); a
//     concave corner (floor meets wall) keeps both contacts; a merged
//     feature stays merged while a contact on a triangle sharing a node with
//     it lasts, even once the angle has grown (a dent under the particle):
//     otherwise a second full-stiffness contact would join with its whole
//     overlap at once, a jump of force and energy;
//  4. a face contact with the centre behind a one-sided face counts only if
//     that face is the particle's nearest triangle (a particle on top of a
//     thin solid is not pulled through by its bottom face), or if the
//     particle went through that face: it held a contact on it in the
//     previous step, or its centre was in front of the face's plane one step
//     ago (meshes aligned across a contact put a rim node that crossed a top
//     face on the side face below it, at distance 0: by the distance alone it
//     would pass in).
// Nodes at exactly the same position are merged for this bookkeeping (STL
// meshes arrive unwelded).
//
// Force (on the particle) per contact, for a pair with model = "hertz_mindlin":
// physics::hertz_mindlin_force against a flat face (R* = the sphere's radius,
// m* = its mass), E* and G* from the sphere's and the part's materials (a rigid
// part is rigid: E = infinity), dashpots from the pair's restitution; for the
// paper's penalty law (the default): physics::spring_dashpot_force with
// k_n from eq. 6 per face (shell: k1 K s / longest edge; solid: k1 K s^2 / V,
// with the face as set by set_surface(), not as it deforms)
// or the pair's explicit stiffness, k_t = k_n, c = 2 zeta sqrt(k m) with m the
// particle's mass (the wall is taken as infinitely heavy), Coulomb friction mu.
//
// Rolling resistance (spheres, the pair's `rolling` settings): the models of the
// DEM-DEM contact against a face that does not turn, r_eff = the sphere's radius:
// the elastic-plastic rolling spring capped at mu_r r F_n (physics::rolling_spring_torque,
// k_r from k_n, its dashpot with the tangential damping ratio and the sphere's
// moment of inertia 2/5 m r^2), or the viscous torque -eta_r r F_n (r w). The
// torque acts on the sphere only (the face takes no moment: forces, not moments,
// balance across the coupler); its springs are kept with the tangential ones.
//
// Stable step (eq. 7's contact term, 0.2 pi sqrt(m / k)) with m the reduced
// mass of the particle and the face: m_p M / (m_p + M), M the lightest node
// mass of the face's triangle (SurfaceMesh::node_mass; rigid nodes are
// infinitely heavy, M = infinity gives m_p). The spring acts on the
// particle and on the face's nodes alike: a heavy boulder against light
// nodes of a fine deformable mesh is limited by the nodes. The
// relative velocity is that of the particle's contact point (v + w x (-r n))
// minus the surface's (barycentric interpolation of the node velocities; zero
// until update_nodes gives them). Torque on the particle: (-r n) x F. The
// reaction -F goes to the triangle's three nodes by the barycentric weights of
// the closest point; the third node takes the remainder so that the three sum
// to -F.
//
// Normal offset: a contact that appears while the particle already touches
// the surface (a dent turning concave under it: the faces around the first
// contact become contacts of their own) arrives with an overlap it never
// built up; a full spring there would add 0.5 k overlap^2 at once and push the
// particle out with energy it never had (+50 % of the impact energy for a
// sphere on 0.0625 m hexahedra). Such a contact's normal spring starts from its
// overlap at birth (offset = overlap: zero force), or, when it replaces a
// vanished contact (the closest normal within history_transfer_angle_deg), at
// that contact's spring overlap; the offset then only shrinks (offset =
// min(offset, overlap): it changes only while the spring is slack), so the
// spring energy never jumps. A particle's first contact has no offset.
//
// Tangential springs are kept per (particle id, feature), the feature named by
// its node ids, across steps while the contact lasts. A contact that moves to
// a neighbouring feature (rolling over a shared edge) takes over the spring of
// the contact it replaces (the previous contact of the same particle with the
// closest normal, within 30 degrees).
//
// Deterministic: the particles are processed in parallel (OpenMP), each on its
// own, and everything summed over particles (node forces, part totals,
// energies) is summed afterwards in particle order.
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "libsabo/contact/sphere_triangle.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/physics/cell_list.hpp"
#include "libsabo/physics/contact_law.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::contact {

// The particles of one solver this step, structure of arrays. 3-vectors are
// 3 doubles per particle (x0, y0, z0, x1, ...).
struct ParticleView {
  std::span<const std::uint64_t> id;         // stable id (keys the tangential springs)
  std::span<const double> position;          // m
  std::span<const double> velocity;          // m/s
  std::span<const double> angular_velocity;  // rad/s; empty: none (SPH)
  std::span<const double> radius;            // m: sphere radius, or SPH contact radius h
  std::span<const double> mass;              // kg
  std::span<const std::uint32_t> body;       // index into the source names; empty: all 0
  // m: points instead of spheres (the nodes of a structure against another's faces): how far behind a
  // one-sided face a point is still pushed out, and the scale of its potential zone (potential_margin *
  // depth beyond its radius counts for stable_dt()); radius may then be 0, depth >= radius, > 0. Empty:
  // spheres, depth = radius.
  std::span<const double> depth;
  [[nodiscard]] std::size_t size() const { return id.size(); }
};

struct ContactOutput {
  std::vector<double> particle_force;   // 3 per particle of the view, N
  std::vector<double> particle_torque;  // 3 per particle, N m
  std::vector<double> node_force;       // 3 per surface node, N (the reactions)
  std::vector<Vec3> part_force;         // [part]: force on the part from all sources, N
  std::vector<Vec3> part_source_force;  // [part * source_count + source]: force on the part from one source, N
  std::size_t source_count = 0;
  std::size_t contact_count = 0;
  double elastic_energy = 0;         // J in the penalty springs
  double dissipated_power = 0;       // W dissipated now by the dashpots and by Coulomb slip
  double max_contact_stiffness = 0;  // N/m, stiffest active contact (0: none)
  double min_contact_mass = std::numeric_limits<double>::infinity();  // kg, lightest particle in contact
  // Deepest contact relative to its face: overlap / the face triangle's
  // shortest edge (a quad face's side). Beyond about 0.5 the particle sinks
  // through the element scale: the penalty spring is too soft for the mesh
  // (the coupler warns; docs/physics.md).
  double deepest_overlap_ratio = 0;
  double deepest_overlap = 0;    // m, of that contact
  double deepest_face_edge = 0;  // m, its face's shortest edge
  [[nodiscard]] Vec3 force_on_part(std::size_t part, std::size_t source) const {
    return part_source_force[part * source_count + source];
  }
};

// One active contact of the last compute(), for tests, diagnostics and output.
struct ContactRecord {
  std::uint32_t particle = 0;  // index in the view
  std::uint32_t face = 0;      // triangle index in the surface
  Feature feature = Feature::face;
  Vec3 point = Vec3::Zero();    // closest point on the surface, m
  Vec3 normal = Vec3::UnitZ();  // unit, from the surface to the particle
  double overlap = 0;           // m
  double normal_stiffness = 0;  // N/m
  Vec3 force = Vec3::Zero();    // on the particle, N
  double normal_force = 0;      // N, along normal
  bool sliding = false;
};

struct SurfaceContactOptions {
  // Pairs closer than (radius + thickness / 2 + potential_margin * radius)
  // count for stable_dt(): a particle is limited one radius before it touches.
  double potential_margin = 1.0;
  // Contacts on triangles sharing a node with normals closer than this are one contact (degrees).
  double smooth_angle_deg = 10.0;
  // A new contact takes over the tangential spring of a vanished contact of the
  // same particle whose normal is within this angle (degrees).
  double history_transfer_angle_deg = 30.0;
  // Test every triangle against every particle instead of using the grid (tests and debugging only: O(N F)).
  bool brute_force_search = false;
  // The mass of the penalty law's dashpots, c = 2 zeta sqrt(k m): the particle's (the coupler: the wall is
  // taken as infinitely heavy), or the reduced mass m M / (m + M) of the particle and the face's lightest
  // node (the fem_solver, which knows both sides; a particle may then be infinitely heavy, mass = +inf:
  // a rigid structure's node).
  enum class DampingMass { particle, reduced };
  DampingMass damping_mass = DampingMass::particle;
};

class SurfaceContact {
 public:
  // Contact settings of (source name, structure part name).
  using PairSettings = std::function<scene::SurfaceContact(const std::string& source, const std::string& part)>;

  // DEM against FEM: sources are scene.particle_sets (ParticleView::body is
  // the set's index), settings from scene.surface_contact(set, structure).
  explicit SurfaceContact(const scene::Scene& scene, SurfaceContactOptions options = {});
  // Elastic constants of (source, part) for Hertz-Mindlin pairs: {E, nu} of the particle's
  // material, then of the part's (E = +infinity: rigid), Pa.
  using PairMaterials = std::function<std::array<double, 4>(const std::string& source, const std::string& part)>;
  // Any particle solver: source_names[body] names each body (forces.csv). Without `materials`,
  // a pair asking for hertz_mindlin is refused (ProtocolError from set_surface).
  SurfaceContact(std::vector<std::string> source_names, PairSettings settings, SurfaceContactOptions options = {},
                 PairMaterials materials = {});

  // (Re)sets the surface: topology, reference positions, thickness, bulk
  // modulus and volumes per face. Node velocities restart at zero. Keeps the
  // tangential springs (they are keyed by node ids). Throws ProtocolError if
  // the mesh is inconsistent or a face cannot be given a stiffness.
  void set_surface(const geometry::SurfaceMesh& surface);
  // Moves the nodes: 3 positions (m) and 3 velocities (m/s) per node, in the
  // surface's node order. velocity may be empty (nodes at rest). Throws
  // ProtocolError on a size mismatch.
  void update_nodes(std::span<const double> position, std::span<const double> velocity);

  // Contact forces for the particles' current state. dt_previous (s) is the
  // step that led from the previous positions to these (tangential springs
  // grow by v_t * dt_previous). Throws ProtocolError on inconsistent arrays.
  void compute(const ParticleView& particles, double dt_previous, ContactOutput& out);

  // The contact's own stable step after the last compute(), s: the smallest
  // 0.2 pi sqrt(m / k_n) over every particle-face pair within reach of
  // contact (see SurfaceContactOptions::potential_margin), infinity if none.
  [[nodiscard]] double stable_dt() const { return stable_dt_; }
  // Where particles must be sent from: at most kMaxInterestBoxes boxes covering the
  // faces (geometry::covering_boxes), each inflated by the reach of the largest particle
  // seen so far plus one such radius of motion margin and half the largest thickness.
  // Every particle that can touch a face before the next step lies in one of them.
  [[nodiscard]] std::vector<Aabb> interest_regions() const { return interest_regions(max_radius_seen_); }
  [[nodiscard]] std::vector<Aabb> interest_regions(double max_radius) const;

  [[nodiscard]] const std::vector<ContactRecord>& contacts() const { return records_; }
  [[nodiscard]] const geometry::SurfaceMesh& surface() const { return surface_; }
  [[nodiscard]] const std::vector<std::string>& source_names() const { return source_names_; }
  [[nodiscard]] std::size_t part_count() const { return surface_.part_name.size(); }
  // Tangential springs carried to the next step.
  [[nodiscard]] std::size_t history_size() const { return history_.size(); }
  // Normal stiffness of `face` against particles of `source`, N/m (eq. 6 or explicit).
  [[nodiscard]] double face_stiffness(std::size_t face, std::size_t source) const;

  // Implementation types, public for the .cpp's helpers only.
  struct FeatureKey {
    Feature kind = Feature::face;
    std::array<std::uint64_t, 3> node{0, 0, 0};  // sorted node ids; unused = max
    bool operator==(const FeatureKey&) const = default;
  };
  struct HistoryEntry {
    std::uint64_t particle = 0;
    FeatureKey key;
    Vec3 displacement = Vec3::Zero();
    Vec3 normal = Vec3::UnitZ();
    double normal_offset = 0;            // m, see "Normal offset" in the class comment
    double spring_overlap = 0;           // m, overlap - normal_offset of the last step
    Vec3 rolling_torque = Vec3::Zero();  // N m, the rolling spring (constant rolling resistance)
  };
  // A feature merged into a neighbouring contact (rule 3) in the last step.
  struct MergedEntry {
    std::uint64_t particle = 0;
    FeatureKey key;
  };
  // Everything compute() carries to the next compute(), for checkpoints: the springs (sorted by
  // particle id), the merged features, and the largest radius seen (it sizes the interest regions).
  struct History {
    std::vector<HistoryEntry> springs;
    std::vector<MergedEntry> merged;
    double max_radius_seen = 0;
  };
  [[nodiscard]] History history() const { return {history_, merged_, max_radius_seen_}; }
  // Replaces the carried state (after set_surface, before the next compute).
  void restore(History history);
  // One triangle's closest point to a particle.
  struct Hit {
    std::uint32_t face = 0;
    TrianglePoint closest;
    SphereTriangleGap gap;
  };
  struct ActiveContact {
    Hit hit;
    FeatureKey key;
    double normal_stiffness = 0;
    physics::ContactForce law;
    Vec3 displacement = Vec3::Zero();    // tangential spring after this step
    Vec3 rolling_torque = Vec3::Zero();  // rolling spring after this step, N m
    double normal_offset = 0;            // m, overlap the normal spring does not see
    double dissipated_power = 0;         // W
  };
  struct Scratch;

 private:
  struct Pair {
    bool enabled = true;
    double friction = 0;
    double penalty_scale = 0;
    double explicit_stiffness = 0;  // > 0: replaces eq. 6
    double normal_damping_ratio = 0;
    double tangential_damping_ratio = 0;
    bool hertz = false;                  // Hertz-Mindlin instead of the penalty spring
    double restitution = 1;              // hertz
    double effective_modulus = 0;        // E*, Pa (a flat face: the sphere's and the part's compliances)
    double effective_shear_modulus = 0;  // G*, Pa
    double rayleigh_factor = 0;          // sqrt(rho / G) / (0.1631 nu + 0.8766) of the particle, s/m per unit density
    int rolling = 0;                     // rolling resistance: 0 none, 1 constant (spring capped), 2 viscous
    double rolling_friction = 0, rolling_viscosity = 0;
  };
  struct ParticleResult {
    std::vector<ActiveContact> contacts;
    std::vector<FeatureKey> merged;  // features merged into a neighbouring contact (rule 3)
    double stable_dt = std::numeric_limits<double>::infinity();
  };

  // keep_stiffness: the faces keep the eq. 6 stiffness they were set with (a degenerate face's is 0).
  void refresh_geometry(bool keep_stiffness);
  // Normal, stiffness factor (kept, with keep_stiffness, when it is > 0), shortest edge, degeneracy and box of
  // face f from its nodes; returns the size of its box (0 for a degenerate face).
  double refresh_face(std::size_t f, bool keep_stiffness);
  // After only `faces` moved: their geometry, the moving faces' grid, and the static grid when a face moved
  // for the first time (the rigid parts' faces never do).
  void refresh_moved_faces(const std::vector<std::uint32_t>& faces);
  void resolve_pairs();
  void build_grid(double query_reach, bool points);
  [[nodiscard]] const Pair& pair(std::uint32_t source, std::size_t face) const {
    return pairs_[source * surface_.part_name.size() + surface_.face_part[face]];
  }
  [[nodiscard]] bool usable(std::uint32_t source, std::size_t face) const {
    return !degenerate_[face] && pair(source, face).enabled;
  }
  // depth: ParticleView::depth (spheres: their radius); point: a point of ParticleView::depth.
  Hit evaluate(std::size_t face, const Vec3& centre, double radius, double depth, bool point) const;
  [[nodiscard]] const Hit* find_hit(const Scratch& scratch, std::uint32_t face) const;
  [[nodiscard]] bool feature_is_local_minimum(const Hit& hit, std::uint32_t source, const Vec3& centre, double radius,
                                              double depth, bool point, Scratch& scratch) const;
  [[nodiscard]] bool shares_node(std::uint32_t face_a, std::uint32_t face_b) const;
  [[nodiscard]] FeatureKey feature_key(const Hit& hit) const;
  // The surface's velocity at a hit's closest point (its nodes' velocities, weighted barycentrically), m/s.
  [[nodiscard]] Vec3 surface_velocity_at(const Hit& hit) const;
  void process_particle(std::size_t i, const ParticleView& particles, double dt_previous, Scratch& scratch,
                        ParticleResult& result, ContactOutput& out) const;

  std::vector<std::string> source_names_;
  PairSettings settings_;
  PairMaterials materials_;
  SurfaceContactOptions options_;
  double cos_smooth_ = 1;
  double cos_transfer_ = 1;

  geometry::SurfaceMesh surface_;
  std::vector<Vec3> node_velocity_;
  std::vector<std::uint32_t> canonical_;        // node -> lowest-index node at the same position
  std::vector<std::uint32_t> node_face_start_;  // canonical node -> faces (CSR)
  std::vector<std::uint32_t> node_faces_;
  std::vector<Vec3> face_normal_;              // unit, outward
  std::vector<double> face_stiffness_factor_;  // eq. 6 without k1: K s / L_max or K s^2 / V, N/m
  std::vector<double> face_shortest_edge_;     // m
  std::vector<double> face_mass_;              // kg: lightest node of the face (infinity: rigid)
  std::vector<char> degenerate_;               // zero-area faces take no part
  std::vector<Aabb> face_box_;
  mutable std::optional<std::vector<Aabb>> cover_;  // of face_box_, uninflated; reset with the geometry
  double median_face_size_ = 0;
  double max_thickness_ = 0;
  std::vector<Pair> pairs_;  // [source * parts + part]

  // The faces' grid, in two: the faces that never moved since the surface was set or last refreshed whole
  // (grid_), and those that did (moving_grid_, over moving_faces_: a deformable part's, rebuilt each step it
  // moves, while the rigid parts' stay binned). Queries visit both; their candidates are sorted, so which
  // grid holds a face changes no result.
  physics::CellList grid_;
  physics::CellList moving_grid_;
  std::vector<std::uint32_t> moving_faces_;  // sorted; moving_grid_'s item k is face moving_faces_[k]
  std::vector<char> moving_;                 // per face
  bool grid_valid_ = false;
  bool moving_grid_valid_ = false;
  double grid_reach_ = 0;  // the per-particle query reach the grid was sized for, m

  // Per particle of the last view (by index, with its id): the static faces whose box overlaps `box`, sorted,
  // from grid_ as built at `generation`. A particle whose query box lies inside `box` takes its candidates
  // from `faces`.
  struct StaticCandidates {
    std::uint64_t id = 0;
    std::uint64_t generation = 0;  // 0: none
    Aabb box;
    std::vector<std::uint32_t> faces;
  };
  // The cached candidates of the view's particles, moved to their new indices by id.
  void match_static_candidates(std::span<const std::uint64_t> ids);
  mutable std::vector<StaticCandidates> static_candidates_;  // written per particle by its own thread
  std::vector<StaticCandidates> static_candidates_spare_;
  std::uint64_t static_generation_ = 0;  // grid_'s builds

  std::vector<HistoryEntry> history_;  // sorted by particle id; per particle in contact order
  std::vector<HistoryEntry> next_history_;
  std::vector<MergedEntry> merged_;  // sorted by particle id
  std::vector<MergedEntry> next_merged_;
  std::vector<ParticleResult> results_;
  std::vector<ContactRecord> records_;
  double stable_dt_ = std::numeric_limits<double>::infinity();
  double max_radius_seen_ = 0;
};

}  // namespace sabo::contact
