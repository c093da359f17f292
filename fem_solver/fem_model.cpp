// The FEM model (fem_model.hpp): the parts (rigid, solid, shell), their combined contact surface and its
// topology revisions, the node forces, the step, checkpoints and output. Over 800 lines as one concept,
// the model's assembly of its parts; the kernels are in elements/, materials/, solid_body and shell_body.
#include "fem_solver/fem_model.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>

#include "fem_solver/elements/hex8.hpp"
#include "fem_solver/mesh/gmsh.hpp"
#include "fem_solver/structure_contact.hpp"
#include "libsabo/contact/surface_contact_history.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "libsabo/io/checkpoint.hpp"
#include "libsabo/io/gmsh_groups.hpp"
#include "libsabo/io/hdf5.hpp"

namespace sabo::fem {

double RigidPart::stable_dt() const {
  return std::numeric_limits<double>::infinity();
}

void RigidPart::step(double /*dt*/, std::span<const Vec3> /*node_force*/) {
  // Fixed in space: the contact forces are reactions of the supports.
}

MaterialParameters material_parameters(const scene::Material& m) {
  MaterialParameters p;
  p.density = m.density;
  p.youngs_modulus = m.youngs_modulus;
  p.poisson_ratio = m.poisson_ratio;
  if (m.yield_stress) {
    p.yield_stress = *m.yield_stress;
    p.tangent_modulus = m.tangent_modulus;
    p.hardening = m.hardening;
    if (m.cowper_symonds_c) {
      p.cowper_symonds_c = *m.cowper_symonds_c;
      p.cowper_symonds_p = m.cowper_symonds_p;
    }
  }
  if (m.failure_strain) {
    if (m.failure_measure == scene::Material::FailureMeasure::plastic_strain) {
      p.failure_plastic_strain = *m.failure_strain;
    } else {
      p.failure_principal_strain = *m.failure_strain;
    }
  }
  return p;
}

namespace {

HexMesh structure_mesh(const scene::Structure& structure) {
  const Aabb& box = structure.shape.box;
  if (structure.slit_count > 0) {
    return slit_dam(box, structure.slit_count, structure.slit_width, structure.slit_depth, structure.slit_axis,
                    structure.shape.element_size);
  }
  std::array<std::size_t, 3> divisions{};
  for (int d = 0; d < 3; ++d) {
    divisions[static_cast<std::size_t>(d)] = element_divisions(box.max(d) - box.min(d), structure.shape.element_size);
  }
  return structured_box(box, divisions);
}

constexpr std::uint64_t kDeformableIdBase = std::uint64_t{1} << 40;

// Shell meshes of a deformable structure with a thickness: a plane panel, or
// a thin-walled building (the four walls of the box, the roof and floors - 1
// intermediate slabs; body material 0 the walls, 1 the slabs).
ShellMesh structure_shells(const scene::Structure& structure) {
  const scene::Shape& shape = structure.shape;
  const auto divisions = [&](double length) { return element_divisions(length, shape.element_size); };
  ShellMesh mesh;
  if (shape.type == scene::Shape::Type::plane) {
    const Vec3 side = shape.normal.cross(shape.direction).normalized();
    const Vec3 corner = shape.origin - 0.5 * shape.length * shape.direction - 0.5 * shape.width * side;
    add_panel(mesh, corner, shape.length * shape.direction, shape.width * side, divisions(shape.length),
              divisions(shape.width), structure.thickness, 0);
    return mesh;
  }
  const Vec3 lo = shape.box.min, hi = shape.box.max;
  const Vec3 extent = hi - lo;
  const double slab = structure.roof_thickness > 0 ? structure.roof_thickness : structure.thickness;
  // Whole elements per storey: every slab meets a row of the walls' nodes, to which it is welded.
  const std::size_t floors = std::max<std::size_t>(structure.floors, 1);
  const std::size_t nz = floors * divisions(extent.z() / static_cast<double>(floors));
  add_panel(mesh, lo, Vec3(extent.x(), 0, 0), Vec3(0, 0, extent.z()), divisions(extent.x()), nz, structure.thickness,
            0);
  add_panel(mesh, Vec3(hi.x(), lo.y(), lo.z()), Vec3(0, extent.y(), 0), Vec3(0, 0, extent.z()), divisions(extent.y()),
            nz, structure.thickness, 0);
  add_panel(mesh, Vec3(hi.x(), hi.y(), lo.z()), Vec3(-extent.x(), 0, 0), Vec3(0, 0, extent.z()), divisions(extent.x()),
            nz, structure.thickness, 0);
  add_panel(mesh, Vec3(lo.x(), hi.y(), lo.z()), Vec3(0, -extent.y(), 0), Vec3(0, 0, extent.z()), divisions(extent.y()),
            nz, structure.thickness, 0);
  for (std::size_t floor = 1; floor <= structure.floors; ++floor) {
    const double z = lo.z() + extent.z() * static_cast<double>(floor) / static_cast<double>(structure.floors);
    add_panel(mesh, Vec3(lo.x(), lo.y(), z), Vec3(extent.x(), 0, 0), Vec3(0, extent.y(), 0), divisions(extent.x()),
              divisions(extent.y()), slab, 1);
  }
  weld(mesh, 1e-6 * extent.norm());
  return mesh;
}

Aabb bounds_of(std::span<const Vec3> points) {
  Aabb box;
  for (const Vec3& p : points) box.extend(p);
  return box;
}

// The nodes on the faces of the structure's bounding box named in `fixed` ("z-", ...).
template <class Body>
void fix_faces(Body& body, const std::vector<std::string>& fixed, unsigned dofs) {
  const Aabb box = bounds_of(body.reference_positions());
  const double tolerance = 1e-9 * std::max(1.0, (box.max - box.min).norm());
  for (const std::string& face : fixed) {
    const int axis = face[0] - 'x';
    Aabb slab{Vec3::Constant(-std::numeric_limits<double>::infinity()),
              Vec3::Constant(std::numeric_limits<double>::infinity())};
    const double at = face[1] == '-' ? box.min(axis) : box.max(axis);
    slab.min(axis) = at - tolerance;
    slab.max(axis) = at + tolerance;
    body.fix_in_box(slab, dofs);
  }
}

HexFormulation hex_formulation(const scene::Structure& structure) {
  switch (structure.element_formulation) {
    case scene::Structure::ElementFormulation::fully_integrated: return HexFormulation::fully_integrated;
    case scene::Structure::ElementFormulation::enhanced_strain: return HexFormulation::enhanced_strain;
    case scene::Structure::ElementFormulation::one_point: break;
  }
  return HexFormulation::one_point;
}

ShellFormulation shell_formulation(const scene::Structure& structure) {
  return structure.element_formulation == scene::Structure::ElementFormulation::fully_integrated
             ? ShellFormulation::fully_integrated
             : ShellFormulation::one_point;
}

static_assert(scene::Constraint::x == dof_x && scene::Constraint::y == dof_y && scene::Constraint::z == dof_z &&
              scene::Constraint::rx == rotation_x && scene::Constraint::ry == rotation_y &&
              scene::Constraint::rz == rotation_z);

std::string vector_text(const Vec3& v) {
  return fmt::format("[{:.6g}, {:.6g}, {:.6g}]", v.x(), v.y(), v.z());
}

// Body nodes at exactly the given positions (a mesh's physical group, placed as the body's nodes were:
// the same numbers through the same scale and translation).
std::vector<std::size_t> nodes_at(std::span<const Vec3> body_nodes, const std::vector<Vec3>& positions) {
  const auto less = [](const Vec3& a, const Vec3& b) {
    if (a.x() != b.x()) return a.x() < b.x();
    if (a.y() != b.y()) return a.y() < b.y();
    return a.z() < b.z();
  };
  std::vector<std::size_t> order(body_nodes.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return less(body_nodes[a], body_nodes[b]) || (body_nodes[a] == body_nodes[b] && a < b);
  });
  std::vector<std::size_t> found;
  for (const Vec3& p : positions) {
    auto it = std::lower_bound(order.begin(), order.end(), p,
                               [&](std::size_t node, const Vec3& q) { return less(body_nodes[node], q); });
    for (; it != order.end() && body_nodes[*it] == p; ++it) found.push_back(*it);
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  return found;
}

// The structure's constraints on a new body: the DOFs of the nodes each selects (docs/scene.md
// constraints). Throws SceneError for a selection without nodes and for rotations on a solid.
template <class Body>
void apply_constraints(Body& body, const scene::Structure& structure, bool shell) {
  std::optional<io::GmshGroups> groups;
  const unsigned all = shell ? (dof_all | rotations_all) : dof_all;
  for (const scene::Constraint& c : structure.constraints) {
    const std::string where = fmt::format("{}:{}: key '{}'", c.origin.file.string(), c.origin.line, c.origin.key);
    const unsigned dofs = c.all ? all : c.dofs;
    if ((dofs & ~all) != 0) {
      throw SceneError(fmt::format(
          "{}: structure '{}' is a solid (the mesh {} holds hexahedra): its nodes have no rotations to hold. Fix: "
          "hold \"x\", \"y\", \"z\" or \"all\"",
          where, structure.name, structure.shape.file.string()));
    }
    std::size_t count = 0;
    if (c.selection == scene::Constraint::Selection::box) {
      count = body.fix_in_box(c.box, dofs);
    } else {
      if (!groups) groups = io::read_gmsh_groups(structure.shape.file);
      const io::GmshGroup* group = groups->find(c.tag);
      std::vector<Vec3> positions;
      if (group != nullptr) {
        for (std::uint32_t n : group->node) {
          positions.push_back(structure.shape.scale * groups->node[n] + structure.shape.translate);
        }
      }
      const std::vector<std::size_t> nodes = nodes_at(body.reference_positions(), positions);
      for (std::size_t node : nodes) body.fix(node, dofs);
      count = nodes.size();
    }
    if (count == 0) {
      const Aabb extent = bounds_of(body.reference_positions());
      throw SceneError(fmt::format(
          "{}: selects no node of structure '{}' (its nodes span {} to {}). Fix: {}", where, structure.name,
          vector_text(extent.min), vector_text(extent.max),
          c.selection == scene::Constraint::Selection::box
              ? "move or grow the box over the nodes to hold (the mesh's node planes lie every element_size)"
              : "assign the group's elements in Gmsh and export again"));
    }
  }
}

// Gravity, the fixed faces, the constraints and the initial velocity of a new body.
template <class Body>
void set_up(Body& body, const scene::Structure& structure, const Vec3& gravity, unsigned fixed_dofs) {
  body.set_gravity(gravity);
  fix_faces(body, structure.fixed_faces, fixed_dofs);
  apply_constraints(body, structure, fixed_dofs != dof_all);
  body.set_velocity(structure.velocity);
}

}  // namespace

DeformablePart::DeformablePart(const scene::Structure& structure, const scene::Scene& scene) {
  const std::size_t material = scene.material_index(structure.material);
  if (structure.shape.type == scene::Shape::Type::mesh) {
    GmshMesh gmsh = read_gmsh(structure.shape.file);
    for (Vec3& p : gmsh.hexahedra.node) p = structure.shape.scale * p + structure.shape.translate;
    scene_material_ = {static_cast<std::uint32_t>(material), static_cast<std::uint32_t>(material)};
    bulk_modulus_ = {scene.materials[material].bulk_modulus(), scene.materials[material].bulk_modulus()};
    const MaterialParameters parameters = material_parameters(scene.materials[material]);
    if (!gmsh.hexahedra.element.empty()) {
      solid_ = std::make_unique<SolidBody>(std::move(gmsh.hexahedra), parameters, hex_formulation(structure));
      set_up(*solid_, structure, scene.run.gravity, dof_all);
    } else {
      if (!(structure.thickness > 0)) {
        throw SceneError(fmt::format(
            "{}:{}: structure '{}': the mesh {} holds quadrangles (shells) but the structure has no thickness. "
            "Fix: give thickness = the shell thickness in m",
            structure.origin.file.string(), structure.origin.line, structure.name, structure.shape.file.string()));
      }
      ShellMesh shells;
      shells.node = gmsh.hexahedra.node;
      shells.element = gmsh.quads;
      shells.thickness.assign(shells.element.size(), structure.thickness);
      shells.material.assign(shells.element.size(), 0);
      shell_ = std::make_unique<ShellBody>(std::move(shells), std::vector<MaterialParameters>{parameters},
                                           shell_formulation(structure));
      set_up(*shell_, structure, scene.run.gravity, dof_all | rotations_all);
    }
  } else if (structure.thickness > 0) {
    std::size_t slab_material = material;
    if (!structure.roof_material.empty()) slab_material = scene.material_index(structure.roof_material);
    scene_material_ = {static_cast<std::uint32_t>(material), static_cast<std::uint32_t>(slab_material)};
    std::vector<MaterialParameters> parameters;
    for (auto m : scene_material_) {
      parameters.push_back(material_parameters(scene.materials[m]));
      bulk_modulus_.push_back(scene.materials[m].bulk_modulus());
    }
    shell_ = std::make_unique<ShellBody>(structure_shells(structure), parameters, shell_formulation(structure));
    set_up(*shell_, structure, scene.run.gravity, dof_all | rotations_all);
  } else {
    scene_material_ = {static_cast<std::uint32_t>(material)};
    bulk_modulus_ = {scene.materials[material].bulk_modulus()};
    solid_ = std::make_unique<SolidBody>(structure_mesh(structure), material_parameters(scene.materials[material]),
                                         hex_formulation(structure));
    set_up(*solid_, structure, scene.run.gravity, dof_all);
  }
  refresh_surface();
}

double DeformablePart::stable_dt() const {
  return with_body([](const auto& body) { return body.stable_dt(); });
}

std::size_t DeformablePart::eroded_count() const {
  return with_body([](const auto& body) { return body.eroded_count(); });
}

DeformablePart::ReportedStress DeformablePart::reported_stress(std::size_t element) const {
  if (solid_) {
    const MaterialPoint& point = solid_->element_state(element).point;
    return {&point, von_mises(point.stress)};
  }
  const auto& points = shell_->element_state(element).point;
  const double front = von_mises(points.front().stress), back = von_mises(points.back().stress);
  return front >= back ? ReportedStress{&points.front(), front} : ReportedStress{&points.back(), back};
}

void DeformablePart::note_peak_stress(double time) {
  with_body([&](const auto& body) {
    for (std::size_t e = 0; e < body.element_count(); ++e) {
      if (body.eroded(e)) continue;
      const double stress = reported_stress(e).von_mises;
      if (stress > peak_stress_.von_mises) peak_stress_ = {stress, time, e};
    }
  });
}

SolidEnergies DeformablePart::solid_energies() const {
  return with_body([](const auto& body) { return body.energies(); });
}

Energies DeformablePart::energies() const {
  const SolidEnergies e = solid_energies();
  Energies out;
  out.kinetic = e.kinetic;
  out.potential = e.potential;
  out.elastic = e.internal + e.hourglass + e.eroded - e.plastic_work;
  out.dissipated = e.plastic_work;
  return out;
}

void DeformablePart::compute_internal_forces(double dt_previous) {
  with_body([&](auto& body) { body.compute_internal_forces(dt_previous); });
}

void DeformablePart::step(double dt, std::span<const Vec3> node_force) {
  external_.assign(with_body([](const auto& body) { return body.node_count(); }), Vec3::Zero());
  for (std::size_t i = 0; i < node_force.size() && i < surface_nodes_.size(); ++i) {
    external_[surface_nodes_[i]] = node_force[i];
  }
  with_body([&](auto& body) { body.integrate(dt_previous_, dt, external_); });
  dt_previous_ = dt;
}

Vec3 DeformablePart::position(std::size_t node) const {
  return with_body([&](const auto& body) { return body.positions()[node]; });
}

Vec3 DeformablePart::velocity(std::size_t node) const {
  return with_body([&](const auto& body) { return body.velocities()[node]; });
}

void DeformablePart::take_node(std::size_t node, const Vec3* position, const Vec3* velocity) {
  with_body([&](auto& body) { body.take_node(node, position, velocity); });
}

std::size_t DeformablePart::node_count() const {
  return with_body([](const auto& body) { return body.node_count(); });
}

BodyState DeformablePart::save_state() const {
  BodyState state = with_body([](const auto& body) { return body.save_state(); });
  state.real.push_back(dt_previous_);
  return state;
}

void DeformablePart::restore_state(const BodyState& state, const std::string& what) {
  if (state.real.empty()) throw FileError(fmt::format("{}: the checkpoint holds no values", what));
  BodyState body = state;
  dt_previous_ = body.real.back();
  body.real.pop_back();
  with_body([&](auto& part_body) { part_body.restore_state(body, what); });
  surface_built_ = false;
  refresh_surface();
}

bool DeformablePart::refresh_surface() {
  const std::uint64_t revision = with_body([](const auto& body) { return body.topology_revision(); });
  if (surface_built_ && surface_revision_ == revision) return false;
  surface_built_ = true;
  surface_revision_ = revision;
  std::size_t nodes = 0;
  if (solid_) {
    faces_ = exterior_faces(solid_->mesh(), solid_->active());
    nodes = solid_->node_count();
  } else {
    faces_.clear();
    for (std::size_t e = 0; e < shell_->element_count(); ++e) {
      if (!shell_->eroded(e)) faces_.push_back({shell_->mesh().element[e], static_cast<std::uint32_t>(e)});
    }
    nodes = shell_->node_count();
  }
  body_to_surface_.assign(nodes, std::numeric_limits<std::uint32_t>::max());
  surface_nodes_.clear();
  for (const BoundaryFace& face : faces_) {
    for (std::uint32_t n : face.node) {
      if (body_to_surface_[n] == std::numeric_limits<std::uint32_t>::max()) {
        body_to_surface_[n] = static_cast<std::uint32_t>(surface_nodes_.size());
        surface_nodes_.push_back(n);
      }
    }
  }
  return true;
}

geometry::SurfaceMesh DeformablePart::surface(bool reference) const {
  geometry::SurfaceMesh mesh;
  const std::span<const double> masses = with_body([](const auto& body) { return body.masses(); });
  const std::span<const Vec3> undeformed = with_body([](const auto& body) { return body.reference_positions(); });
  for (std::uint32_t n : surface_nodes_) {
    mesh.node_id.push_back(n);  // the model offsets ids per part
    mesh.node_position.push_back(reference ? undeformed[n] : position(n));
    mesh.node_mass.push_back(masses[n]);
  }
  for (const BoundaryFace& face : faces_) {
    const auto s = [&](std::size_t k) { return body_to_surface_[face.node[k]]; };
    std::uint32_t body_material = 0;
    double thickness = 0, volume = 0;
    if (solid_) {
      if (reference) {
        HexNodes x;
        for (std::size_t a = 0; a < 8; ++a) x[a] = undeformed[solid_->mesh().element[face.element][a]];
        volume = hex8_volume(x);
      } else {
        volume = solid_->element_state(face.element).volume;
      }
    } else {
      body_material = shell_->mesh().material[face.element];
      thickness = shell_->mesh().thickness[face.element];
    }
    for (const std::array<std::uint32_t, 3>& tri :
         {std::array<std::uint32_t, 3>{s(0), s(1), s(2)}, std::array<std::uint32_t, 3>{s(0), s(2), s(3)}}) {
      mesh.triangle.push_back(tri);
      mesh.face_part.push_back(0);
      mesh.face_material.push_back(scene_material_[body_material]);
      mesh.face_thickness.push_back(thickness);
      mesh.face_bulk_modulus.push_back(bulk_modulus_[body_material]);
      mesh.face_element_volume.push_back(volume);
    }
  }
  return mesh;
}

void DeformablePart::write_volume(const std::filesystem::path& file, const io::vtk::Options& options) const {
  const std::size_t elements = with_body([](const auto& body) { return body.element_count(); });
  const std::span<const Vec3> positions = with_body([](const auto& body) { return body.positions(); });
  const std::span<const Vec3> reference = with_body([](const auto& body) { return body.reference_positions(); });
  const std::span<const Vec3> velocities = with_body([](const auto& body) { return body.velocities(); });
  std::vector<std::int64_t> connectivity, offsets;
  std::vector<io::vtk::CellType> types(elements, solid_ ? io::vtk::CellType::hexahedron : io::vtk::CellType::quad);
  std::vector<double> stress(6 * elements), mises(elements), plastic(elements);
  std::vector<std::uint8_t> eroded(elements);
  for (std::size_t e = 0; e < elements; ++e) {
    const ReportedStress reported = reported_stress(e);
    if (solid_) {
      for (auto n : solid_->mesh().element[e]) connectivity.push_back(n);
      eroded[e] = solid_->eroded(e) ? 1 : 0;
    } else {
      for (auto n : shell_->mesh().element[e]) connectivity.push_back(n);
      eroded[e] = shell_->eroded(e) ? 1 : 0;
    }
    offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
    const Mat3& sigma = reported.point->stress;
    const double values[6] = {sigma(0, 0), sigma(1, 1), sigma(2, 2), sigma(0, 1), sigma(1, 2), sigma(0, 2)};
    for (std::size_t k = 0; k < 6; ++k) stress[6 * e + k] = values[k];
    mises[e] = reported.von_mises;
    plastic[e] = reported.point->plastic_strain;
  }
  std::vector<Vec3> displacement(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) displacement[i] = positions[i] - reference[i];
  const std::vector<io::vtk::Array> points{io::vtk::Array::vectors("displacement", displacement),
                                           io::vtk::Array::vectors("velocity", velocities)};
  const std::vector<io::vtk::Array> cells{
      io::vtk::Array::of<double>("stress", stress, 6), io::vtk::Array::scalars("von_mises", mises),
      io::vtk::Array::scalars("plastic_strain", plastic), io::vtk::Array::of<std::uint8_t>("eroded", eroded)};
  io::vtk::write_unstructured(file, positions, connectivity, offsets, types, points, cells, options);
}

FemModel::FemModel(const scene::Scene& scene) {
  std::uint64_t rigid_id = 0;
  for (std::size_t index = 0; index < scene.structures.size(); ++index) {
    const scene::Structure& structure = scene.structures[index];
    const std::size_t material = scene.material_index(structure.material);
    if (!structure.rigid) {
      const bool shell_plane = structure.shape.type == scene::Shape::Type::plane && structure.thickness > 0;
      if (structure.shape.type != scene::Shape::Type::box && structure.shape.type != scene::Shape::Type::mesh &&
          !shell_plane) {
        throw SceneError(
            fmt::format("{}:{}: structure '{}' (key '{}'): deformable structures are boxes (solid, or a thin-walled "
                        "building with a thickness) or planes with a thickness (shells). Fix: use shape = \"box\" or "
                        "rigid = true",
                        structure.origin.file.string(), structure.origin.line, structure.name, structure.origin.key));
      }
      parts_.push_back(std::make_unique<DeformablePart>(structure, scene));
      rigid_surface_.emplace_back();
      PartInfo info;
      info.name = structure.name;
      info.material = material;
      info_.push_back(info);
      continue;
    }
    geometry::SurfaceMesh part_surface = geometry::triangulate(structure.shape, structure.name, structure.origin);
    const double bulk_modulus = scene.materials[material].bulk_modulus();
    const std::size_t faces = part_surface.face_count();
    part_surface.face_material.assign(faces, static_cast<std::uint32_t>(material));
    part_surface.face_thickness.assign(faces, structure.thickness);
    part_surface.face_bulk_modulus.assign(faces, bulk_modulus);
    part_surface.face_element_volume.assign(faces, 0.0);
    for (auto& id : part_surface.node_id) id = rigid_id++;
    PartInfo info;
    info.name = structure.name;
    info.material = material;
    info_.push_back(info);
    rigid_surface_.push_back(std::move(part_surface));
    parts_.push_back(std::make_unique<RigidPart>());
  }
  part_series_.resize(parts_.size());
  if (StructureContact::any_pair(scene)) structure_contact_ = std::make_unique<StructureContact>(scene);
  rebuild_surface();
  if (structure_contact_) {
    // The state at t = 0 (the same as step 0 computes with dt_previous = 0): the contact's first stable step.
    structure_contact_->compute(surface_.node_position, node_velocity_, 0.0);
    contact_elastic_ = structure_contact_->elastic_energy();
  }
}

void FemModel::rebuild_surface() {
  surface_ = geometry::SurfaceMesh{};
  geometry::SurfaceMesh reference;  // the same at the undeformed geometry, for the structure contact
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    PartInfo& info = info_[index];
    geometry::SurfaceMesh part_surface;
    if (const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get())) {
      part_surface = part->surface();
      for (auto& id : part_surface.node_id) id += kDeformableIdBase * (index + 1);
      if (structure_contact_) {
        geometry::SurfaceMesh undeformed = part->surface(true);
        undeformed.node_id = part_surface.node_id;
        undeformed.part_name = {info.name};
        undeformed.face_part.assign(undeformed.face_count(), 0);
        reference.append(undeformed);
      }
    } else {
      part_surface = rigid_surface_[index];
      if (structure_contact_) {
        geometry::SurfaceMesh rigid = part_surface;
        rigid.part_name = {info.name};
        rigid.face_part.assign(rigid.face_count(), 0);
        reference.append(rigid);
      }
    }
    part_surface.part_name = {info.name};
    part_surface.face_part.assign(part_surface.face_count(), 0);
    info.node_begin = surface_.node_count();
    info.face_begin = surface_.face_count();
    info.area = 0;
    info.centroid.setZero();
    for (std::size_t f = 0; f < part_surface.face_count(); ++f) {
      const auto& t = part_surface.triangle[f];
      const Vec3 center =
          (part_surface.node_position[t[0]] + part_surface.node_position[t[1]] + part_surface.node_position[t[2]]) /
          3.0;
      const double area = part_surface.face_area(f);
      info.area += area;
      info.centroid += area * center;
    }
    if (info.area > 0) info.centroid /= info.area;
    surface_.append(part_surface);
    info.node_end = surface_.node_count();
    info.face_end = surface_.face_count();
  }
  surface_.validate("fem_solver surface");
  node_force_.assign(surface_.node_count(), Vec3::Zero());
  node_velocity_.assign(surface_.node_count(), Vec3::Zero());
  update_surface();
  if (structure_contact_) {
    structure_contact_->set_surface(reference);
    contact_force_.assign(surface_.node_count(), Vec3::Zero());
  }
}

void FemModel::compute_internal_forces(double dt_previous) {
  if (structure_contact_) {
    // At x_n on the surface the coupler sees this step (erosion below changes it at the next update_surface()).
    sync_surface_nodes();
    structure_contact_->compute(surface_.node_position, node_velocity_, dt_previous);
    const auto force = structure_contact_->node_force();
    contact_force_.assign(force.begin(), force.end());
    contact_elastic_ = structure_contact_->elastic_energy();
    contact_power_ = structure_contact_->dissipated_power();
  }
  for (auto& part : parts_) part->compute_internal_forces(dt_previous);
}

bool FemModel::update_surface() {
  bool changed = false;
  for (auto& part : parts_) {
    if (auto* deformable = dynamic_cast<DeformablePart*>(part.get()))
      changed = deformable->refresh_surface() || changed;
  }
  if (changed) {
    ++surface_revision_;
    rebuild_surface();
    return true;
  }
  sync_surface_nodes();
  return false;
}

void FemModel::sync_surface_nodes() {
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get());
    if (part == nullptr) continue;
    const auto nodes = part->surface_nodes();
    const std::size_t begin = info_[index].node_begin;
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      surface_.node_position[begin + i] = part->position(nodes[i]);
      node_velocity_[begin + i] = part->velocity(nodes[i]);
    }
  }
}

FemModel::~FemModel() = default;

double FemModel::stable_dt() const {
  double dt = std::numeric_limits<double>::infinity();
  for (const auto& part : parts_) dt = std::min(dt, part->stable_dt());
  if (structure_contact_) dt = std::min(dt, structure_contact_->stable_dt());
  return dt;
}

Energies FemModel::energies() const {
  Energies total;
  for (const auto& part : parts_) {
    const Energies e = part->energies();
    total.kinetic += e.kinetic;
    total.potential += e.potential;
    total.elastic += e.elastic;
    total.dissipated += e.dissipated;
  }
  total.elastic += contact_elastic_;
  total.dissipated += contact_dissipated_;
  return total;
}

bool FemModel::moved() const {
  for (const auto& part : parts_) {
    if (part->moved()) return true;
  }
  return false;
}

void FemModel::take_node_states(std::span<const std::uint64_t> node_id, std::span<const double> position,
                                std::span<const double> velocity) {
  for (const auto& [values, field] : {std::pair{position, "node_position"}, std::pair{velocity, "node_velocity"}}) {
    if (!values.empty() && values.size() != 3 * node_id.size()) {
      throw ProtocolError(fmt::format("StepForces.taken: {} {} values for {} surface node ids, expected 3 each",
                                      values.size(), field, node_id.size()));
    }
  }
  const auto vector = [](std::span<const double> values, std::size_t k) {
    return Vec3(values[3 * k], values[3 * k + 1], values[3 * k + 2]);
  };
  for (std::size_t k = 0; k < node_id.size(); ++k) {
    const std::uint64_t id = node_id[k];
    if (id < kDeformableIdBase) continue;  // a rigid part's node
    const std::uint64_t index = id / kDeformableIdBase - 1, node = id % kDeformableIdBase;
    auto* part = index < parts_.size() ? dynamic_cast<DeformablePart*>(parts_[index].get()) : nullptr;
    if (part == nullptr || node >= part->node_count()) {
      throw ProtocolError(fmt::format("StepForces.taken: surface node id {} is no node of this model", id));
    }
    const Vec3 x = position.empty() ? Vec3::Zero() : vector(position, k);
    const Vec3 v = velocity.empty() ? Vec3::Zero() : vector(velocity, k);
    part->take_node(node, position.empty() ? nullptr : &x, velocity.empty() ? nullptr : &v);
  }
}

void FemModel::apply_node_forces(std::span<const double> node_force) {
  const std::size_t nodes = surface_.node_count();
  if (!node_force.empty() && node_force.size() != 3 * nodes) {
    throw ModelInputError(
        fmt::format("fem_solver: StepForces.node_force has {} values but the surface has {} nodes "
                    "({} values expected, or none for zero force)",
                    node_force.size(), nodes, 3 * nodes));
  }
  for (std::size_t i = 0; i < nodes; ++i) {
    if (node_force.empty()) {
      node_force_[i].setZero();
      continue;
    }
    node_force_[i] = Vec3(node_force[3 * i], node_force[3 * i + 1], node_force[3 * i + 2]);
    if (!node_force_[i].allFinite()) {
      throw ModelInputError(fmt::format("fem_solver: StepForces.node_force of node {} is ({}, {}, {}): not finite", i,
                                        node_force_[i].x(), node_force_[i].y(), node_force_[i].z()));
    }
  }
  // Serial sums in node order: the same bits on every run.
  for (PartInfo& info : info_) {
    info.force.setZero();
    info.moment.setZero();
    for (std::size_t i = info.node_begin; i < info.node_end; ++i) {
      info.force += node_force_[i];
      info.moment += (surface_.node_position[i] - info.centroid).cross(node_force_[i]);
    }
  }
}

void FemModel::step(double dt) {
  std::span<const Vec3> force = node_force_;
  if (structure_contact_) {
    total_force_.resize(node_force_.size());
    for (std::size_t i = 0; i < node_force_.size(); ++i) total_force_[i] = node_force_[i] + contact_force_[i];
    force = total_force_;
    // The dashpots' and friction's power of step n acts over dt_n (as the coupler's pairs).
    contact_dissipated_ += contact_power_ * dt;
  }
  for (std::size_t p = 0; p < parts_.size(); ++p) {
    const PartInfo& info = info_[p];
    parts_[p]->step(dt, force.subspan(info.node_begin, info.node_end - info.node_begin));
  }
  time_ += dt;
  for (auto& part : parts_) {
    if (auto* deformable = dynamic_cast<DeformablePart*>(part.get())) deformable->note_peak_stress(time_);
  }
}

void FemModel::save_state(io::hdf5::Group& group) const {
  group.set_attribute("time", time_);
  group.set_attribute("surface_revision", static_cast<std::int64_t>(surface_revision_));
  io::hdf5::Group parts = group.create_group("parts");
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get());
    if (part == nullptr) continue;
    const BodyState state = part->save_state();
    io::hdf5::Group part_group = parts.create_group(info_[index].name);
    io::write_array(part_group, "real", state.real);
    io::write_array(part_group, "active", state.active);
    io::write_array(part_group, "counters", state.counters);
    const DeformablePart::StressPeak& peak = part->peak_stress();
    io::write_array(part_group, "peak_stress",
                    std::vector<double>{peak.von_mises, peak.time, static_cast<double>(peak.element)});
  }
  if (structure_contact_) {
    // The springs between structures and the contact's energy accounts.
    io::hdf5::Group springs = group.create_group("structure_contact");
    springs.set_attribute("dissipated", contact_dissipated_);
    springs.set_attribute("elastic", contact_elastic_);
    springs.set_attribute("power", contact_power_);
    contact::write_history(springs, structure_contact_->history());
  }
}

void FemModel::load_state(const io::hdf5::Group& group) {
  const std::string file = group.file_name();
  const io::hdf5::Group parts = group.group("parts");
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    auto* part = dynamic_cast<DeformablePart*>(parts_[index].get());
    if (part == nullptr) continue;
    const std::string& name = info_[index].name;
    const std::string what = fmt::format("{}: part '{}'", file, name);
    if (!parts.exists(name)) {
      throw FileError(
          fmt::format("{}: no state for this deformable part. Fix: restart from a checkpoint of this scene", what));
    }
    const io::hdf5::Group part_group = parts.group(name);
    BodyState state;
    state.real = io::read_array<double>(part_group, "real");
    state.active = io::read_array<std::uint8_t>(part_group, "active");
    state.counters = io::read_array<std::uint64_t>(part_group, "counters");
    part->restore_state(state, what);
    if (!part_group.exists("peak_stress")) {
      throw FileError(
          fmt::format("{}: no peak_stress (a checkpoint of an older Sabo). Fix: run the scene again "
                      "from the start",
                      what));
    }
    const auto peak = io::read_array<double>(part_group, "peak_stress");
    if (peak.size() != 3) throw FileError(fmt::format("{}: peak_stress holds {} values, not 3", what, peak.size()));
    part->set_peak_stress({peak[0], peak[1], static_cast<std::uint64_t>(peak[2])});
  }
  time_ = group.double_attribute("time");
  rebuild_surface();
  surface_revision_ = static_cast<std::uint64_t>(group.int_attribute("surface_revision"));
  if (structure_contact_) {
    if (!group.exists("structure_contact")) {
      throw FileError(fmt::format(
          "{}: no state for the contact between structures. Fix: restart from a checkpoint of this scene", file));
    }
    const io::hdf5::Group springs = group.group("structure_contact");
    contact_dissipated_ = springs.double_attribute("dissipated");
    contact_elastic_ = springs.double_attribute("elastic");
    contact_power_ = springs.double_attribute("power");
    try {
      structure_contact_->restore(contact::read_history(springs));
    } catch (const ProtocolError& error) {
      throw FileError(fmt::format("{}: {}", springs.path(), error.what()));
    }
  }
}

void FemModel::save_output_state(io::hdf5::Group& group, const std::filesystem::path& run_folder) const {
  group.set_attribute("energy_history_started", energy_history_started_ ? 1 : 0);
  io::write_file_size(group, "fem_energy_csv", run_folder / "fem_energy.csv");
  group.set_attribute("surface_series", series_ ? 1 : 0);
  if (series_) io::write_series(group, "fem_pvd", *series_);
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    if (part_series_[index]) io::write_series(group, "part_" + info_[index].name, *part_series_[index]);
  }
}

void FemModel::load_output_state(const io::hdf5::Group& group, const std::filesystem::path& run_folder) {
  energy_history_started_ = group.int_attribute("energy_history_started") != 0 &&
                            io::truncate_to_saved_size(group, "fem_energy_csv", run_folder / "fem_energy.csv");
  series_.reset();
  if (group.int_attribute("surface_series") != 0) {
    series_.emplace(run_folder / "fem.pvd");
    io::read_series(group, "fem_pvd", *series_);
  }
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    part_series_[index].reset();
    const std::string name = "part_" + info_[index].name;
    if (!group.has_attribute(name + "_files")) continue;
    part_series_[index].emplace(run_folder / fmt::format("fem_{}.pvd", info_[index].name));
    io::read_series(group, name, *part_series_[index]);
  }
}

void FemModel::write_output(const std::filesystem::path& run_folder, std::uint64_t step, double time,
                            const io::vtk::Options& options) {
  const std::filesystem::path folder = run_folder / "fem";
  std::error_code error;
  std::filesystem::create_directories(folder, error);
  if (error) {
    throw FileError(fmt::format("{}: cannot create the output folder: {}", folder.string(), error.message()));
  }
  const std::filesystem::path file = folder / fmt::format("fem_{:08}.vtp", step);
  std::vector<io::vtk::Array> point_data{io::vtk::Array::vectors("node_force", node_force_),
                                         io::vtk::Array::of<std::uint64_t>("node_id", surface_.node_id)};
  if (structure_contact_) point_data.push_back(io::vtk::Array::vectors("structure_contact_force", contact_force_));
  const std::vector<io::vtk::Array> cell_data{io::vtk::Array::of<std::uint32_t>("part", surface_.face_part),
                                              io::vtk::Array::of<std::uint32_t>("material", surface_.face_material),
                                              io::vtk::Array::scalars("thickness", surface_.face_thickness)};
  io::vtk::write_surface(file, surface_, point_data, cell_data, options);
  if (!series_) series_.emplace(run_folder / "fem.pvd");
  series_->add(time, std::filesystem::path("fem") / file.filename());
  write_energy_history(run_folder, time);
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get());
    if (part == nullptr) continue;
    const std::string name = info_[index].name;
    const std::filesystem::path volume_file = folder / fmt::format("{}_{:08}.vtu", name, step);
    part->write_volume(volume_file, options);
    if (!part_series_[index]) part_series_[index].emplace(run_folder / fmt::format("fem_{}.pvd", name));
    part_series_[index]->add(time, std::filesystem::path("fem") / volume_file.filename());
  }
}

void FemModel::write_energy_history(const std::filesystem::path& run_folder, double time) {
  bool any = false;
  SolidEnergies total;
  std::size_t eroded = 0;
  for (const auto& part : parts_) {
    const auto* deformable = dynamic_cast<const DeformablePart*>(part.get());
    if (deformable == nullptr) continue;
    any = true;
    const SolidEnergies e = deformable->solid_energies();
    total.kinetic += e.kinetic;
    total.internal += e.internal;
    total.plastic_work += e.plastic_work;
    total.hourglass += e.hourglass;
    total.eroded += e.eroded;
    total.external_work += e.external_work;
    eroded += deformable->eroded_count();
  }
  if (!any) return;
  const std::filesystem::path file = run_folder / "fem_energy.csv";
  const bool fresh = !energy_history_started_;
  std::ofstream out(file, fresh ? std::ios::trunc : std::ios::app);
  if (!out) throw FileError(fmt::format("{}: cannot write the FEM energy history", file.string()));
  if (fresh) {
    out << "time_s,kinetic_J,internal_J,plastic_work_J,hourglass_J,eroded_J,external_work_J,eroded_elements";
    // With contact between structures, its springs and its dissipated work (the parts' external work holds
    // the work of its forces).
    out << (structure_contact_ ? ",contact_elastic_J,contact_dissipated_J\n" : "\n");
    energy_history_started_ = true;
  }
  out << fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{}", time, total.kinetic, total.internal,
                     total.plastic_work, total.hourglass, total.eroded, total.external_work, eroded);
  out << (structure_contact_ ? fmt::format(",{:.9g},{:.9g}\n", contact_elastic_, contact_dissipated_) : "\n");
}

}  // namespace sabo::fem
