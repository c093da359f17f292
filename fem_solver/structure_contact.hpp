#pragma once
// Contact between structures (FEM-FEM), inside the fem_solver, which owns
// both sides (docs/physics.md "Structure against structure"): node-to-segment
// penalty contact with the law of the particle-surface contact (paper eqs.
// 3-6, contact::SurfaceContact): every surface node of a part in a contact
// pair is a point against the faces of the other part, both ways, with the
// face's eq. 6 stiffness (solid: k1 K s^2 / V; shell and rigid: k1 K s / L),
// Coulomb friction with a tangential spring, and dashpots with the reduced
// mass of the node and the face's lightest node. A node is a point of radius
// half its shell thickness (0 on solids and rigid parts) that a one-sided
// face still pushes out down to a depth of half the shortest undeformed edge
// around the node (contact::ParticleView::depth). A part never meets its own faces (no
// self-contact); two rigid parts never meet.
//
// Step n (FemModel's contract): compute() from the surface at x_n and the
// node velocities v_{n-1/2}, dt_{n-1} growing the tangential springs; the
// forces act on the nodes at integrate(). Erosion: set_surface() with the new
// combined surface (the springs are keyed by node ids and carry over).
// Deterministic: the kernel's sums run in node order.
#include <memory>
#include <span>
#include <vector>

#include "libsabo/contact/surface_contact.hpp"
#include "libsabo/core/types.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/scene/scene.hpp"

namespace sabo::fem {

class StructureContact {
 public:
  // The contact pairs of the scene (Scene::fem_fem_contact of its structures, in file order).
  explicit StructureContact(const scene::Scene& scene);
  // Whether any pair of structures is in contact (else nothing needs computing).
  [[nodiscard]] static bool any_pair(const scene::Scene& scene);

  // The combined surface of FemModel (face_part = structure index), at registration and after every
  // topology change, at its undeformed geometry (node positions and element volumes): the eq. 6
  // stiffnesses and the points' depths come from it, so that they do not depend on when the topology last
  // changed (a restart rebuilds the surface of a deformed body); compute() moves the nodes.
  void set_surface(const geometry::SurfaceMesh& undeformed);
  // Contact forces at the nodes' positions (m) and velocities (m/s), per surface node; dt_previous
  // (s) is the step that led here.
  void compute(std::span<const Vec3> position, std::span<const Vec3> velocity, double dt_previous);

  // N, per surface node: as a point against the other part's faces plus the reactions of its faces.
  [[nodiscard]] std::span<const Vec3> node_force() const { return node_force_; }
  [[nodiscard]] double elastic_energy() const { return out_.elastic_energy; }      // J, in the springs now
  [[nodiscard]] double dissipated_power() const { return out_.dissipated_power; }  // W, dashpots and slip now
  // s: 0.2 pi sqrt(m / k) over every node within reach of a face of the other part (infinity: none).
  [[nodiscard]] double stable_dt() const { return kernel_->stable_dt(); }
  [[nodiscard]] std::size_t contact_count() const { return out_.contact_count; }
  [[nodiscard]] const contact::SurfaceContact& kernel() const { return *kernel_; }
  // The springs carried to the next step, for checkpoints (contact::SurfaceContact::History).
  [[nodiscard]] contact::SurfaceContact::History history() const { return kernel_->history(); }
  void restore(contact::SurfaceContact::History history) { kernel_->restore(std::move(history)); }

 private:
  std::unique_ptr<contact::SurfaceContact> kernel_;
  std::vector<char> source_;         // per part: its nodes meet another part's faces
  std::vector<std::uint32_t> node_;  // surface node of each point
  std::vector<std::uint64_t> id_;    // per point
  std::vector<double> radius_, depth_, mass_;
  std::vector<std::uint32_t> part_;                      // per point
  std::vector<double> point_position_, point_velocity_;  // 3 per point
  std::vector<double> node_position_, node_velocity_;    // 3 per surface node
  contact::ContactOutput out_;
  std::vector<Vec3> node_force_;
};

}  // namespace sabo::fem
