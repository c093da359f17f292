#pragma once
// The structures of a scene as the FEM solver simulates them: the physics of
// fem_solver, without the protocol.
//
// Step contract (explicit central difference, docs/design.md, "An explicit, lock-step step"). At the start of
// step n the model holds, for every part, node positions x_n and half-step
// velocities v_{n-1/2} (rigid parts: fixed in space, x_n = x_0, v = 0).
//   1. The solver sends StepState{n, t_n, stable_dt(), energies()} with the
//      surface node positions and velocities when moved() is true (rigid
//      parts never move: nothing is sent for them after registration).
//   2. It receives StepForces{n, dt_n, node_force f_n: 3 per surface node, N}.
//   3. apply_node_forces(f_n) stores f_n and the resultant force and moment
//      (about the part's centroid) on every part.
//   4. step(dt_n) advances to t_{n+1} = t_n + dt_n. Deformable parts
//      integrate v_{n+1/2} = v_{n-1/2} + dt_avg M^-1 (f_n + f_ext -
//      f_int(x_n)), x_{n+1} = x_n + dt_n v_{n+1/2}; rigid parts do nothing.
//   5. When StepForces.output is set, write_output() writes the surface at
//      t_n with the forces f_n (call it before step()).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "fem_solver/shell_body.hpp"
#include "fem_solver/solid_body.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/io/hdf5.hpp"
#include "libsabo/io/vtk.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::fem {

class StructureContact;

// A scene material as the structures' elements take it: elastic constants, MAT_PLASTIC_KINEMATIC's plasticity
// and its failure strain under the scene's failure_measure.
[[nodiscard]] MaterialParameters material_parameters(const scene::Material& material);

struct Energies {
  double kinetic = 0;     // J
  double potential = 0;   // J, gravity relative to z = 0
  double elastic = 0;     // J, strain energy
  double dissipated = 0;  // J, accumulated
};

// One structure of the scene. Its surface nodes and faces are a contiguous
// range of the model's combined surface.
class Part {
 public:
  virtual ~Part() = default;
  [[nodiscard]] virtual bool rigid() const = 0;
  [[nodiscard]] virtual double stable_dt() const = 0;  // s; +infinity when the part sets no limit
  [[nodiscard]] virtual Energies energies() const = 0;
  [[nodiscard]] virtual bool moved() const = 0;  // whether the surface left its registered place
  // Advances by dt (s) under the contact forces on its surface nodes (N, the
  // part's range of the combined surface).
  virtual void step(double dt, std::span<const Vec3> node_force) = 0;
  // Deformable parts: stresses and internal forces at x_n (see SolidBody).
  virtual void compute_internal_forces(double /*dt_previous*/) {}
};

// A deformable structure (rigid = false): a SolidBody of hexahedra (a box)
// whose exterior faces (two triangles per quad) are its contact surface, or a
// ShellBody (a wall panel, or a thin-walled building: a box with a
// thickness) whose active shells are two-sided faces with their thickness.
class DeformablePart final : public Part {
 public:
  DeformablePart(const scene::Structure& structure, const scene::Scene& scene);
  [[nodiscard]] bool rigid() const override { return false; }
  [[nodiscard]] double stable_dt() const override;
  [[nodiscard]] Energies energies() const override;
  [[nodiscard]] SolidEnergies solid_energies() const;
  [[nodiscard]] bool moved() const override { return true; }
  void step(double dt, std::span<const Vec3> node_force) override;
  void compute_internal_forces(double dt_previous) override;

  // The contact surface of the active elements now: nodes in surface_nodes() order. reference: at the
  // undeformed node positions, with the elements' undeformed volumes (the structure contact's eq. 6
  // stiffness and depths, independent of when the topology last changed).
  [[nodiscard]] geometry::SurfaceMesh surface(bool reference = false) const;
  [[nodiscard]] std::span<const std::uint32_t> surface_nodes() const { return surface_nodes_; }
  // Recomputes the surface after erosion; returns whether it changed.
  bool refresh_surface();
  [[nodiscard]] Vec3 position(std::size_t node) const;
  [[nodiscard]] Vec3 velocity(std::size_t node) const;
  [[nodiscard]] std::size_t node_count() const;
  void take_node(std::size_t node, const Vec3* position, const Vec3* velocity);
  [[nodiscard]] bool is_shell() const { return shell_ != nullptr; }
  [[nodiscard]] const SolidBody* solid() const { return solid_.get(); }
  [[nodiscard]] const ShellBody* shell() const { return shell_.get(); }
  [[nodiscard]] std::size_t eroded_count() const;
  // The stress that reports an element, with its von Mises stress (Pa): a solid's one point, a shell's outer
  // fibre (the larger von Mises stress of its two surfaces).
  struct ReportedStress {
    const MaterialPoint* point;
    double von_mises;
  };
  [[nodiscard]] ReportedStress reported_stress(std::size_t element) const;
  // The largest von Mises stress (Pa) of an active element so far, when and where: updated by
  // note_peak_stress() after every step (summary.json results.fem_solver; a checkpoint keeps it).
  struct StressPeak {
    double von_mises = 0;  // Pa
    double time = 0;       // s
    std::uint64_t element = 0;
  };
  void note_peak_stress(double time);
  [[nodiscard]] const StressPeak& peak_stress() const { return peak_stress_; }
  void set_peak_stress(const StressPeak& peak) { peak_stress_ = peak; }
  // Checkpoint and restart: the body's evolving state with the part's last
  // step dt appended; restore_state also rebuilds the surface of the active elements.
  [[nodiscard]] BodyState save_state() const;
  void restore_state(const BodyState& state, const std::string& what);
  // The volume mesh (.vtu): hexahedra or quads with displacement, velocity,
  // stress, von Mises stress, plastic strain, eroded.
  void write_volume(const std::filesystem::path& file, const io::vtk::Options& options) const;

 private:
  // f(body) on the solid or the shell body: the members both share.
  template <class F>
  decltype(auto) with_body(F&& f) const {
    if (solid_) return f(std::as_const(*solid_));
    return f(std::as_const(*shell_));
  }
  template <class F>
  decltype(auto) with_body(F&& f) {
    if (solid_) return f(*solid_);
    return f(*shell_);
  }

  std::unique_ptr<SolidBody> solid_;
  std::unique_ptr<ShellBody> shell_;
  std::vector<double> bulk_modulus_;           // per material of the shell mesh (solids: one)
  std::vector<std::uint32_t> scene_material_;  // scene material index per body material
  std::vector<BoundaryFace> faces_;            // solids: exterior faces; shells: node = the quad
  std::vector<std::uint32_t> surface_nodes_;   // body node of each surface node
  std::vector<std::uint32_t> body_to_surface_;
  std::uint64_t surface_revision_ = 0;
  bool surface_built_ = false;
  double dt_previous_ = 0;
  std::vector<Vec3> external_;
  StressPeak peak_stress_;
};

// A structure fixed in space (the paper's MAT_RIGID channel, all DOFs fixed).
class RigidPart final : public Part {
 public:
  [[nodiscard]] bool rigid() const override { return true; }
  [[nodiscard]] double stable_dt() const override;
  [[nodiscard]] Energies energies() const override { return {}; }
  [[nodiscard]] bool moved() const override { return false; }
  void step(double dt, std::span<const Vec3> node_force) override;
};

// Where a part lies in the combined surface, and the load on it.
struct PartInfo {
  std::string name;                          // the structure's name
  std::size_t material = 0;                  // scene material index
  std::size_t node_begin = 0, node_end = 0;  // its nodes in the combined surface
  std::size_t face_begin = 0, face_end = 0;  // its faces
  Vec3 centroid = Vec3::Zero();              // m, area-weighted centroid of its surface
  double area = 0;                           // m^2
  Vec3 force = Vec3::Zero();                 // N, resultant of the last applied node forces
  Vec3 moment = Vec3::Zero();                // N m, about `centroid`
};

class FemModel {
 public:
  // One part per scene structure, in file order (part index = structure index).
  // Throws SceneError for structures it cannot build, FileError for
  // unreadable mesh files.
  explicit FemModel(const scene::Scene& scene);
  ~FemModel();
  FemModel(const FemModel&) = delete;
  FemModel& operator=(const FemModel&) = delete;

  // The combined surface of every part: node ids 0..n-1, face_part = part
  // index, face_material, face_thickness (structure thickness),
  // face_bulk_modulus (material K), face_element_volume (0: rigid parts are
  // shells for eq. 6).
  [[nodiscard]] const geometry::SurfaceMesh& surface() const { return surface_; }
  [[nodiscard]] std::size_t part_count() const { return parts_.size(); }
  [[nodiscard]] const PartInfo& part(std::size_t index) const { return info_.at(index); }
  [[nodiscard]] const Part& part_model(std::size_t index) const { return *parts_.at(index); }

  // Stresses and internal forces of the deformable parts at x_n, from
  // v_{n-1/2} over dt_previous (s); erodes failed elements (the surface
  // changes at the next update_surface()).
  void compute_internal_forces(double dt_previous);
  // Brings the combined surface to x_n: node positions and velocities, and a
  // new topology when elements eroded since the last call (returns true then;
  // the revision increases).
  bool update_surface();
  [[nodiscard]] std::uint64_t surface_revision() const { return surface_revision_; }
  [[nodiscard]] std::span<const Vec3> node_velocities() const { return node_velocity_; }  // m/s, surface nodes
  [[nodiscard]] const DeformablePart* deformable(std::size_t index) const {
    return dynamic_cast<const DeformablePart*>(parts_.at(index).get());
  }

  // s; minimum over parts and the structure contact (rigid only: +infinity)
  [[nodiscard]] double stable_dt() const;
  // Sum over parts (rigid: zero) and the structure contact: its springs' energy is elastic, the work of
  // its dashpots and friction dissipated.
  [[nodiscard]] Energies energies() const;
  [[nodiscard]] bool moved() const;                    // whether any surface node moved since registration
  [[nodiscard]] double time() const { return time_; }  // s

  // node_force: 3 per surface node (N, x0 y0 z0 x1 ...); empty means zero.
  // Throws ModelInputError for a wrong size or a non-finite value.
  void apply_node_forces(std::span<const double> node_force);
  // Replay (--take): recorded positions and/or velocities (3 per id; either may be empty) of the surface nodes
  // `node_id` in place of the deformable parts' own (rigid parts' nodes never move and are skipped);
  // ProtocolError for an array of another size or an id that is no node of this model.
  void take_node_states(std::span<const std::uint64_t> node_id, std::span<const double> position,
                        std::span<const double> velocity);
  [[nodiscard]] std::span<const Vec3> node_forces() const { return node_force_; }  // last applied, N

  void step(double dt);  // s; see the step contract above

  // Contact between structures ([contact.fem_fem], [[interactions]] of two structures; nullptr when the
  // scene has none): computed in compute_internal_forces() at x_n from the surface of the last
  // update_surface(), applied with the coupler's forces in step().
  [[nodiscard]] const StructureContact* structure_contact() const { return structure_contact_.get(); }
  // N, per surface node: the structure contact's forces of the last compute_internal_forces() (empty: none).
  [[nodiscard]] std::span<const Vec3> structure_contact_forces() const { return contact_force_; }

  // Checkpoint (docs/restart.md) after step(): every deformable part's state
  // (node positions and velocities, stresses, back stresses, plastic strains,
  // hourglass forces, eroded flags, energy accounts) and the model's time
  // (attributes time, surface_revision; a group parts/<name> per deformable
  // part with datasets real, active, counters).
  void save_state(io::hdf5::Group& group) const;
  // Restores a state saved by a model of the same scene, so that the next
  // steps give the same bits as the run that saved it. Throws FileError for a
  // state that does not fit the scene.
  void load_state(const io::hdf5::Group& group);
  // What write_output() carries from frame to frame: the .pvd series and the
  // length of fem_energy.csv, which load cuts back to.
  void save_output_state(io::hdf5::Group& group, const std::filesystem::path& run_folder) const;
  void load_output_state(const io::hdf5::Group& group, const std::filesystem::path& run_folder);

  // Writes <run_folder>/fem/fem_<step>.vtp (the surface with node_force,
  // node_id, and per face part, material, thickness) and adds it to
  // <run_folder>/fem.pvd at `time` (s). Each deformable part also writes
  // <run_folder>/fem/<name>_<step>.vtu (hexahedra with displacement, velocity,
  // stress, von Mises stress, plastic strain, eroded) in <run_folder>/fem_<name>.pvd,
  // and the deformable parts' energy history goes to <run_folder>/fem_energy.csv
  // (time, kinetic, internal, plastic work, hourglass, eroded, external work
  // in J, eroded elements).
  void write_output(const std::filesystem::path& run_folder, std::uint64_t step, double time,
                    const io::vtk::Options& options = {});

 private:
  void rebuild_surface();
  // Surface node positions and velocities from the parts (x_n, v_{n-1/2}), topology unchanged.
  void sync_surface_nodes();
  // Appends the deformable parts' energies at `time` to <run_folder>/fem_energy.csv.
  void write_energy_history(const std::filesystem::path& run_folder, double time);

  geometry::SurfaceMesh surface_;
  std::vector<geometry::SurfaceMesh> rigid_surface_;  // per part (empty for deformable parts)
  std::vector<Vec3> node_velocity_;
  std::uint64_t surface_revision_ = 0;
  std::vector<std::optional<io::vtk::TimeSeries>> part_series_;
  bool energy_history_started_ = false;
  std::vector<std::unique_ptr<Part>> parts_;
  std::vector<PartInfo> info_;
  std::vector<Vec3> node_force_;
  std::unique_ptr<StructureContact> structure_contact_;
  std::vector<Vec3> contact_force_, total_force_;  // per surface node, N
  double contact_elastic_ = 0;                     // J, the springs at the last compute
  double contact_power_ = 0;                       // W, dissipated at the last compute
  double contact_dissipated_ = 0;                  // J, accumulated
  double time_ = 0;
  std::optional<io::vtk::TimeSeries> series_;
};

}  // namespace sabo::fem
