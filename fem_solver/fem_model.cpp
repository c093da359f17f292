#include "fem_solver/fem_model.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/primitives.hpp"

namespace sabo::fem {

double RigidPart::stable_dt() const {
  return std::numeric_limits<double>::infinity();
}

void RigidPart::step(double /*dt*/, std::span<const Vec3> /*node_force*/) {
  // Fixed in space: the contact forces are reactions of the supports.
}

namespace {

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
  if (m.failure_strain) p.failure_principal_strain = *m.failure_strain;
  return p;
}

HexMesh structure_mesh(const scene::Structure& structure) {
  const Aabb& box = structure.shape.box;
  std::array<std::size_t, 3> divisions{1, 1, 1};
  if (structure.shape.element_size > 0) {
    for (int d = 0; d < 3; ++d) {
      divisions[static_cast<std::size_t>(d)] =
          static_cast<std::size_t>(std::max(1.0, std::round((box.max(d) - box.min(d)) / structure.shape.element_size)));
    }
  }
  return structured_box(box, divisions);
}

constexpr std::uint64_t kDeformableIdBase = std::uint64_t{1} << 40;

}  // namespace

DeformablePart::DeformablePart(const scene::Structure& structure, const scene::Material& material, const Vec3& gravity)
    : body_(structure_mesh(structure), material_parameters(material)), bulk_modulus_(material.bulk_modulus()) {
  body_.set_gravity(gravity);
  const Aabb& box = structure.shape.box;
  const double tolerance = 1e-9 * (box.max - box.min).norm();
  for (const std::string& face : structure.fixed_faces) {
    const int axis = face[0] - 'x';
    Aabb slab{Vec3::Constant(-std::numeric_limits<double>::infinity()),
              Vec3::Constant(std::numeric_limits<double>::infinity())};
    const double at = face[1] == '-' ? box.min(axis) : box.max(axis);
    slab.min(axis) = at - tolerance;
    slab.max(axis) = at + tolerance;
    body_.fix_in_box(slab, dof_all);
  }
  body_.set_velocity(structure.velocity);
  refresh_surface();
}

Energies DeformablePart::energies() const {
  const SolidEnergies e = body_.energies();
  Energies out;
  out.kinetic = e.kinetic;
  out.potential = e.potential;
  out.elastic = e.internal + e.hourglass + e.eroded - e.plastic_work;
  out.dissipated = e.plastic_work;
  return out;
}

void DeformablePart::compute_internal_forces(double dt_previous) {
  body_.compute_internal_forces(dt_previous);
}

void DeformablePart::step(double dt, std::span<const Vec3> node_force) {
  external_.assign(body_.node_count(), Vec3::Zero());
  for (std::size_t i = 0; i < node_force.size() && i < surface_nodes_.size(); ++i) {
    external_[surface_nodes_[i]] = node_force[i];
  }
  body_.integrate(dt_previous_, dt, external_);
  dt_previous_ = dt;
}

bool DeformablePart::refresh_surface() {
  if (surface_built_ && surface_revision_ == body_.topology_revision()) return false;
  surface_built_ = true;
  surface_revision_ = body_.topology_revision();
  faces_ = exterior_faces(body_.mesh(), body_.active());
  body_to_surface_.assign(body_.node_count(), std::numeric_limits<std::uint32_t>::max());
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

geometry::SurfaceMesh DeformablePart::surface() const {
  geometry::SurfaceMesh mesh;
  for (std::uint32_t n : surface_nodes_) {
    mesh.node_id.push_back(n);  // the model offsets ids per part
    mesh.node_position.push_back(body_.positions()[n]);
  }
  for (const BoundaryFace& face : faces_) {
    const auto s = [&](std::size_t k) { return body_to_surface_[face.node[k]]; };
    const double volume = body_.element_state(face.element).volume;
    for (const std::array<std::uint32_t, 3>& tri :
         {std::array<std::uint32_t, 3>{s(0), s(1), s(2)}, std::array<std::uint32_t, 3>{s(0), s(2), s(3)}}) {
      mesh.triangle.push_back(tri);
      mesh.face_part.push_back(0);
      mesh.face_material.push_back(0);
      mesh.face_thickness.push_back(0.0);
      mesh.face_bulk_modulus.push_back(bulk_modulus_);
      mesh.face_element_volume.push_back(volume);
    }
  }
  return mesh;
}

FemModel::FemModel(const scene::Scene& scene) {
  std::uint64_t rigid_id = 0;
  for (std::size_t index = 0; index < scene.structures.size(); ++index) {
    const scene::Structure& structure = scene.structures[index];
    const std::size_t material = scene.material_index(structure.material);
    if (!structure.rigid) {
      if (structure.shape.type != scene::Shape::Type::box) {
        throw SceneError(fmt::format(
            "{}:{}: structure '{}' (key '{}'): deformable structures are boxes. Fix: use shape = \"box\" or "
            "rigid = true",
            structure.origin.file.string(), structure.origin.line, structure.name, structure.origin.key));
      }
      parts_.push_back(std::make_unique<DeformablePart>(structure, scene.materials[material], scene.run.gravity));
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
  rebuild_surface();
}

void FemModel::rebuild_surface() {
  surface_ = geometry::SurfaceMesh{};
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    PartInfo& info = info_[index];
    geometry::SurfaceMesh part_surface;
    if (const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get())) {
      part_surface = part->surface();
      for (auto& id : part_surface.node_id) id += kDeformableIdBase * (index + 1);
      part_surface.face_material.assign(part_surface.face_count(), static_cast<std::uint32_t>(info.material));
    } else {
      part_surface = rigid_surface_[index];
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
}

void FemModel::compute_internal_forces(double dt_previous) {
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
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get());
    if (part == nullptr) continue;
    const auto nodes = part->surface_nodes();
    const std::size_t begin = info_[index].node_begin;
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      surface_.node_position[begin + i] = part->body().positions()[nodes[i]];
      node_velocity_[begin + i] = part->body().velocities()[nodes[i]];
    }
  }
  return false;
}

FemModel::~FemModel() = default;

double FemModel::stable_dt() const {
  double dt = std::numeric_limits<double>::infinity();
  for (const auto& part : parts_) dt = std::min(dt, part->stable_dt());
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
  return total;
}

bool FemModel::moved() const {
  for (const auto& part : parts_) {
    if (part->moved()) return true;
  }
  return false;
}

void FemModel::apply_node_forces(std::span<const double> node_force) {
  const std::size_t nodes = surface_.node_count();
  if (!node_force.empty() && node_force.size() != 3 * nodes) {
    throw ProtocolError(
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
      throw ProtocolError(fmt::format("fem_solver: StepForces.node_force of node {} is ({}, {}, {}): not finite", i,
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
  dt_previous_ = dt;
  for (std::size_t p = 0; p < parts_.size(); ++p) {
    const PartInfo& info = info_[p];
    parts_[p]->step(dt, std::span<const Vec3>(node_force_).subspan(info.node_begin, info.node_end - info.node_begin));
  }
  time_ += dt;
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
  const std::vector<io::vtk::Array> point_data{io::vtk::Array::vectors("node_force", node_force_),
                                               io::vtk::Array::of<std::uint64_t>("node_id", surface_.node_id)};
  const std::vector<io::vtk::Array> cell_data{io::vtk::Array::of<std::uint32_t>("part", surface_.face_part),
                                              io::vtk::Array::of<std::uint32_t>("material", surface_.face_material),
                                              io::vtk::Array::scalars("thickness", surface_.face_thickness)};
  io::vtk::write_surface(file, surface_, point_data, cell_data, options);
  if (!series_) series_.emplace(run_folder / "fem.pvd");
  series_->add(time, std::filesystem::path("fem") / file.filename());
  for (std::size_t index = 0; index < parts_.size(); ++index) {
    const auto* part = dynamic_cast<const DeformablePart*>(parts_[index].get());
    if (part == nullptr) continue;
    const SolidBody& body = part->body();
    const std::size_t elements = body.element_count();
    std::vector<std::int64_t> connectivity, offsets;
    std::vector<io::vtk::CellType> types(elements, io::vtk::CellType::hexahedron);
    std::vector<double> stress(6 * elements), mises(elements), plastic(elements);
    std::vector<std::uint8_t> eroded(elements);
    for (std::size_t e = 0; e < elements; ++e) {
      for (auto n : body.mesh().element[e]) connectivity.push_back(n);
      offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
      const Mat3& s = body.element_state(e).point.stress;
      const double values[6] = {s(0, 0), s(1, 1), s(2, 2), s(0, 1), s(1, 2), s(0, 2)};
      for (std::size_t k = 0; k < 6; ++k) stress[6 * e + k] = values[k];
      mises[e] = von_mises(s);
      plastic[e] = body.element_state(e).point.plastic_strain;
      eroded[e] = body.eroded(e) ? 1 : 0;
    }
    std::vector<Vec3> displacement(body.node_count());
    for (std::size_t i = 0; i < body.node_count(); ++i) {
      displacement[i] = body.positions()[i] - body.reference_positions()[i];
    }
    const std::vector<io::vtk::Array> points{io::vtk::Array::vectors("displacement", displacement),
                                             io::vtk::Array::vectors("velocity", body.velocities())};
    const std::vector<io::vtk::Array> cells{
        io::vtk::Array::of<double>("stress", stress, 6), io::vtk::Array::scalars("von_mises", mises),
        io::vtk::Array::scalars("plastic_strain", plastic), io::vtk::Array::of<std::uint8_t>("eroded", eroded)};
    const std::string name = info_[index].name;
    const std::filesystem::path volume_file = folder / fmt::format("{}_{:08}.vtu", name, step);
    io::vtk::write_unstructured(volume_file, body.positions(), connectivity, offsets, types, points, cells, options);
    if (!part_series_[index]) part_series_[index].emplace(run_folder / fmt::format("fem_{}.pvd", name));
    part_series_[index]->add(time, std::filesystem::path("fem") / volume_file.filename());
  }
}

}  // namespace sabo::fem
