#pragma once
// Boundary particles for SPH walls (Adami, Hu & Adams 2012): a SurfaceMesh
// sampled into layers of particles behind its faces, each anchored to one
// triangle so that it moves with the FEM nodes and gives its force back to
// them (docs/physics.md, "SPH walls").
//
// Sampling. Faces in the same plane (same outward normal and offset, same
// thickness) form a patch with one square lattice of spacing dx in the plane,
// aligned with the patch's bounds along the global axis closest to the plane
// (an axis-aligned box face of n dx gets exactly n x n points). Lattice point
// q of a patch gives `layers` particles at depths (k + 1/2) dx behind the
// face the fluid wets, k = 0 .. layers - 1, when q lies on a face of the patch
// ("inside"), or within layers * dx of the patch's edge ("extension"). That
// face is the plane itself for a solid's face and a shell's front face, t/2 in
// front of its mid-surface (t: the thickness): Adami's wall lies half a
// spacing in front of the first layer, so the fluid stands on the shell's
// face, and the shell's own volume holds the first layers.
// Where the layers of several patches meet:
//  * convex edges and corners (box edges): the layers of both faces overlap
//    inside the solid; a particle is kept only by the patch it is nearest to
//    (smallest depth; ties to the lower patch index): the overlap is split
//    along the bisector, no double layers;
//  * concave edges and corners (floor meets wall): the extensions of the two
//    faces fill the wedge behind the corner that neither face's layers cover;
//    an extension particle is kept only where a patch that meets this one at
//    the particle's anchor (and is not its opposite face) also has it behind
//    its plane, so a free edge (the rim of a plane) or a thin solid's edge
//    grows no extension; it is split between the patches as above: no gap
//    within layers * dx of the corner;
//  * a particle that would lie in front of another face of the mesh, closer
//    to it than its own depth (the layers of a solid thinner than the layers
//    come out of its far side) is dropped.
// Particles on two different lattices meet along a bisector, where one of
// two particles closer than dx/2 is dropped (the later in sampling order): the
// local spacing there lies between dx/2 and about 1.5 dx; the kernel sums
// tolerate that (the error is confined to one support around the edge).
//
// Motion. Each particle keeps its triangle, the barycentric weights of its
// anchor point on it, and its offset from the anchor in the triangle's frame
// (e1 along the first edge, e2 = n x e1, n the outward normal). Its position
// follows the triangle rigidly; its velocity and acceleration are the anchor's
// (barycentric interpolation of the nodes'); its normal is the face's.
// Forces. A force on a particle goes to its triangle's three nodes with the
// anchor's weights, the third node taking the remainder, so that the node
// forces sum to the particle forces to round-off. A corner fill shares its
// force with the face it fills the corner with, each face taking the part
// along its own normal (the fluid pushing into a floor-wall corner loads the
// floor with the vertical part and the wall with the horizontal part, not
// whichever face's lattice the particle came from).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "libsabo/core/types.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/physics/boundary_particles.hpp"

namespace sabo::geometry {

inline constexpr std::uint32_t kNoFace = UINT32_MAX;

struct SurfaceSampling {
  double spacing = 0;                         // m, dx
  std::size_t layers = 0;                     // particles per lattice point, into the solid
  std::vector<std::uint32_t> face;            // triangle each particle is anchored to
  std::vector<std::array<double, 3>> weight;  // barycentric weights of the anchor on the face (sum 1, each >= 0)
  std::vector<Vec3> offset;                   // particle - anchor in the face frame (e1, e2, n), m
  std::vector<double> depth;                  // m behind the wetted face at sampling time
  std::vector<char> extension;                // 1: anchored beyond the patch's edge (concave corner fill)
  // Corner fills only (else kNoFace): the face of the patch it fills the
  // corner with, and the weights of the particle's nearest point on it.
  std::vector<std::uint32_t> partner_face;
  std::vector<std::array<double, 3>> partner_weight;
  [[nodiscard]] std::size_t size() const { return face.size(); }
  [[nodiscard]] double particle_volume() const { return spacing * spacing * spacing; }  // m^3
};

// Samples `mesh` (at its current node positions) at spacing dx (m, > 0) in
// `layers` (>= 1) layers. Throws sabo::Error on a non-positive spacing, no
// layers, or a mesh that fails SurfaceMesh::validate.
[[nodiscard]] SurfaceSampling sample_surface(const SurfaceMesh& mesh, double spacing, std::size_t layers);

// Keeps the particles k with keep[k] != 0 (one flag per particle), in their order.
void keep_particles(SurfaceSampling& sampling, const std::vector<char>& keep);

// Position (m) of particle k for the mesh's current node positions.
[[nodiscard]] Vec3 boundary_particle_position(const SurfaceMesh& mesh, const SurfaceSampling& sampling, std::size_t k);

// Fills `out` with the particles listed in `selection` (indices into the
// sampling, in that order) for the mesh's current node positions.
// node_velocity and node_acceleration: one per node, or empty (at rest).
void place_boundary_particles(const SurfaceMesh& mesh, const SurfaceSampling& sampling,
                              std::span<const Vec3> node_velocity, std::span<const Vec3> node_acceleration,
                              std::span<const std::uint32_t> selection, physics::BoundaryParticles& out);

// The share of `force` (N, on particle k) that goes to its own face [0] and
// to its corner partner's face [1]: each face takes the part along its normal
// (force = alpha n_a + beta n_b + a part along the corner's edge, which is
// halved); everything to [0] for particles that are no corner fill. The two
// sum to `force` exactly.
[[nodiscard]] std::array<Vec3, 2> split_boundary_force(const SurfaceMesh& mesh, const SurfaceSampling& sampling,
                                                       std::size_t k, const Vec3& force);

// Adds force k (N, 3 doubles each, in `selection` order) of each selected
// particle onto its triangle's nodes (split with its corner partner's, see
// split_boundary_force): node_force has 3 doubles per node.
void spread_boundary_forces(const SurfaceMesh& mesh, const SurfaceSampling& sampling,
                            std::span<const std::uint32_t> selection, std::span<const double> boundary_force,
                            std::span<double> node_force);

}  // namespace sabo::geometry
