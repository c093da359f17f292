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

FemModel::FemModel(const scene::Scene& scene) {
  for (std::size_t index = 0; index < scene.structures.size(); ++index) {
    const scene::Structure& structure = scene.structures[index];
    if (!structure.rigid) {
      throw SceneError(
          fmt::format("{}:{}: structure '{}' (key '{}'): rigid = false, but deformable structures are "
                      "not supported yet. Fix: set rigid = true",
                      structure.origin.file.string(), structure.origin.line, structure.name, structure.origin.key));
    }
    geometry::SurfaceMesh part_surface = geometry::triangulate(structure.shape, structure.name, structure.origin);
    const std::size_t material = scene.material_index(structure.material);
    const double bulk_modulus = scene.materials[material].bulk_modulus();
    const std::size_t faces = part_surface.face_count();
    part_surface.face_material.assign(faces, static_cast<std::uint32_t>(material));
    part_surface.face_thickness.assign(faces, structure.thickness);
    part_surface.face_bulk_modulus.assign(faces, bulk_modulus);
    part_surface.face_element_volume.assign(faces, 0.0);

    PartInfo info;
    info.name = structure.name;
    info.material = material;
    info.node_begin = surface_.node_count();
    info.face_begin = surface_.face_count();
    for (std::size_t f = 0; f < faces; ++f) {
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
    info_.push_back(info);
    parts_.push_back(std::make_unique<RigidPart>());
  }
  // Node ids: unique over the whole surface.
  for (std::size_t i = 0; i < surface_.node_id.size(); ++i) surface_.node_id[i] = i;
  surface_.validate("fem_solver surface");
  node_force_.assign(surface_.node_count(), Vec3::Zero());
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
}

}  // namespace sabo::fem
