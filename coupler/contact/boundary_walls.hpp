#pragma once
// SPH walls as boundary particles (scene sph.wall_model = boundary_particles;
// docs/physics.md "SPH walls", docs/protocol.md "SPH walls"). The coupler
// samples the FEM surface once per topology (geometry/surface_sampling.hpp),
// moves the particles with the nodes every step, sends the sph_solver those
// within the kernel support of a fluid particle, and spreads the forces the
// fluid put on them back onto the FEM nodes (action = reaction, exactly).
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "coupler/contact/point_load.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/geometry/surface_sampling.hpp"
#include "libsabo/physics/boundary_particles.hpp"
#include "libsabo/physics/cell_list.hpp"

namespace sabo::coupler {

class BoundaryWalls {
 public:
  // A periodic axis of the fluid (0: x, 1: y) and its span [min, max), m.
  struct PeriodicSpan {
    int axis = 0;
    double min = 0, max = 0;
  };
  // spacing: the wall particles' spacing (m; scene sph.wall_spacing()); support: the SPH kernel's
  // support radius (m); the walls get ceil(support / spacing) layers. Along a periodic axis the walls keep only the
  // particles inside the span: beyond a seam, the fluid sees the images of the
  // particles of the other end (a corner fill that spilled past it would double them).
  // free_slip_parts: the structure parts whose particles are free-slip for the fluid (scene
  // sph.free_slip_walls); the others are no-slip.
  BoundaryWalls(double spacing, double support, std::vector<PeriodicSpan> periodic = {},
                std::vector<std::string> free_slip_parts = {});

  // (Re)samples the surface at its current node positions.
  void set_surface(const geometry::SurfaceMesh& surface);
  // New node positions and velocities (3 doubles per node; velocity may be
  // empty: at rest). The wall acceleration is the change of the node
  // velocities over dt_previous (s; 0: none).
  void update_nodes(std::span<const double> position, std::span<const double> velocity, double dt_previous);

  // Spreads the forces the fluid put on the particles of a past selection
  // (3 doubles each, in its order; steps_back 1: the last selection, 2: the
  // one before) onto the nodes: node_force gets 3 doubles per node
  // (overwritten), part_force the sum per structure part (N), and
  // point_loads, when given, the same forces one share at a time at the
  // point of the face the particle is anchored to (a corner fill's partner
  // share: its nearest point on the partner face), overwritten. Throws
  // ProtocolError when the count does not match that selection.
  void spread(std::span<const double> boundary_force, std::size_t steps_back, std::vector<double>& node_force,
              std::vector<Vec3>& part_force, std::vector<PointLoad>* point_loads = nullptr) const;
  // Selects the particles within the kernel support of any fluid particle
  // (positions: 3 doubles each) and places them; becomes the last selection.
  void select_near(std::span<const double> fluid_position);

  [[nodiscard]] const physics::BoundaryParticles& selected() const { return selected_; }
  // The last selection (steps_back 1) or the one before (2), as sample indices.
  [[nodiscard]] const std::vector<std::uint32_t>& selection(std::size_t steps_back = 1) const {
    return steps_back == 2 ? previous_selection_ : selection_;
  }
  [[nodiscard]] const geometry::SurfaceSampling& sampling() const { return sampling_; }
  [[nodiscard]] const geometry::SurfaceMesh& surface() const { return surface_; }
  [[nodiscard]] std::size_t layers() const { return layers_; }
  [[nodiscard]] double spacing() const { return spacing_; }  // m
  // What carries over from one step to the next, for checkpoints: the selections of the last two
  // steps (the returned forces refer to them) and the node velocities (the next acceleration).
  struct History {
    std::vector<std::uint32_t> selection, previous_selection;
    std::vector<Vec3> node_velocity;
  };
  [[nodiscard]] History history() const { return {selection_, previous_selection_, node_velocity_}; }
  // After set_surface() (and update_nodes() to the positions of the step the history was taken at):
  // throws ProtocolError when the history does not fit the sampled surface.
  void restore(History history);
  // Where fluid particles must be sent from: at most geometry::kMaxInterestBoxes
  // boxes covering the boundary particles (geometry::covering_boxes), inflated by
  // the support, plus one support of wall motion.
  [[nodiscard]] std::vector<Aabb> interest_regions() const;

 private:
  void place_all();
  // Places the particles of selection_ into selected_, their free-slip flags included.
  void place_selected();

  double spacing_;
  double support_;
  std::size_t layers_;
  std::vector<PeriodicSpan> periodic_;
  std::vector<std::string> free_slip_parts_;
  std::vector<std::uint8_t> free_slip_;  // per sampled particle: 1 when its part is free-slip; empty: none is
  geometry::SurfaceMesh surface_;
  geometry::SurfaceSampling sampling_;
  std::vector<Vec3> node_velocity_, previous_node_velocity_, node_acceleration_;
  std::vector<Vec3> all_position_;                  // every sampled particle, m
  mutable std::optional<std::vector<Aabb>> cover_;  // of all_position_, uninflated; reset when they move
  std::vector<std::uint32_t> selection_, previous_selection_;
  physics::BoundaryParticles selected_;
  std::vector<char> near_;  // per sampled particle: within the support of a fluid particle
  physics::CellList grid_;  // of all_position_, cell = support
  bool grid_valid_ = false;
};

}  // namespace sabo::coupler
