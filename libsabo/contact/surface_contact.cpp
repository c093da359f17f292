// The particle-surface penalty contact (surface_contact.hpp, paper eqs. 3-6). Over 800 lines as one
// concept: the surface's geometry and grid, the closest-feature search, the one-contact-per-smooth-surface
// rule and the contacts' history are one algorithm; the laws are libsabo/physics'.
#include "libsabo/contact/surface_contact.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/covering_boxes.hpp"
#include "libsabo/physics/hertz_mindlin.hpp"
#include "libsabo/physics/stable_step.hpp"

namespace sabo::contact {

namespace {

constexpr std::uint64_t kNoNode = std::numeric_limits<std::uint64_t>::max();
// A face whose area is below this fraction of its longest edge squared has no
// usable normal: it takes no part in the contact.
constexpr double kDegenerateAreaRatio = 1e-12;
// A node update refreshes only the faces around the moved nodes while they are fewer than 1 in this many
// (a deformable dam in a rigid channel); more, and the whole surface is refreshed.
constexpr double kPartialRefreshShare = 4.0;
// Below this many particles a parallel region costs more than it saves.
constexpr std::int64_t kParallelThreshold = 64;
// A particle's static candidates are looked up for its query box grown by this fraction of its reach on
// every side, and reused until its query box leaves that box: a larger skin lists more faces to filter,
// a smaller one walks the grid more often. Results do not depend on it.
constexpr double kCandidateSkin = 0.25;
// Relative slack when comparing distances of the same point computed from different triangles.
constexpr double kDistanceSlack = 1e-9;
// How far outside a one-sided face (relative to its longest edge) a point behind it may project and still meet
// it as a face (evaluate(): nodes facing the nodes or edges of another structure).
constexpr double kFaceExtension = 0.01;

Vec3 vec3_at(std::span<const double> values, std::size_t i) {
  return {values[3 * i], values[3 * i + 1], values[3 * i + 2]};
}

void add_at(std::vector<double>& values, std::size_t i, const Vec3& v) {
  values[3 * i] += v.x();
  values[3 * i + 1] += v.y();
  values[3 * i + 2] += v.z();
}

int feature_rank(Feature feature) {
  return static_cast<int>(feature);
}

// m M / (m + M); an infinitely heavy side leaves the other's mass.
double reduced_mass(double particle, double face) {
  if (std::isinf(face)) return particle;
  if (std::isinf(particle)) return face;
  return particle * face / (particle + face);
}

}  // namespace

struct SurfaceContact::Scratch {
  std::vector<std::uint32_t> candidates;
  std::vector<Hit> hits;              // ascending face index
  std::vector<std::size_t> touching;  // indices into hits
  std::vector<std::size_t> kept;
  std::vector<char> history_used;
  std::vector<Vec3> displacement;
  std::vector<Vec3> rolling_torque;
  std::vector<double> normal_offset;
  std::vector<char> has_history;
};

SurfaceContact::SurfaceContact(const scene::Scene& scene, SurfaceContactOptions options) : options_(options) {
  for (const auto& set : scene.particle_sets) source_names_.push_back(set.name);
  // Keep only what the pair lookup needs, so that the scene need not outlive this object.
  scene::Scene pairs_only;
  pairs_only.interactions = scene.interactions;
  pairs_only.dem_fem_default = scene.dem_fem_default;
  settings_ = [pairs_only = std::move(pairs_only)](const std::string& source, const std::string& part) {
    return pairs_only.surface_contact(source, part);
  };
  std::map<std::string, std::array<double, 2>> elastic;  // body name -> {E, nu}
  const auto material_of = [&scene](const std::string& name) -> const scene::Material* {
    for (const auto& material : scene.materials) {
      if (material.name == name) return &material;
    }
    return nullptr;
  };
  for (const auto& set : scene.particle_sets) {
    if (const auto* material = material_of(set.material)) {
      elastic[set.name] = {material->youngs_modulus, material->poisson_ratio};
    }
  }
  for (const auto& structure : scene.structures) {
    if (const auto* material = material_of(structure.material)) {
      // A rigid part does not deform: it is rigid for the Hertz law too.
      elastic[structure.name] = {structure.rigid ? std::numeric_limits<double>::infinity() : material->youngs_modulus,
                                 material->poisson_ratio};
    }
  }
  materials_ = [elastic = std::move(elastic)](const std::string& source, const std::string& part) {
    const auto sphere = elastic.find(source), wall = elastic.find(part);
    if (sphere == elastic.end() || wall == elastic.end()) return std::array<double, 4>{0, 0, 0, 0};
    return std::array<double, 4>{sphere->second[0], sphere->second[1], wall->second[0], wall->second[1]};
  };
  cos_smooth_ = std::cos(options_.smooth_angle_deg * std::numbers::pi / 180.0);
  cos_transfer_ = std::cos(options_.history_transfer_angle_deg * std::numbers::pi / 180.0);
}

SurfaceContact::SurfaceContact(std::vector<std::string> source_names, PairSettings settings,
                               SurfaceContactOptions options, PairMaterials materials)
    : source_names_(std::move(source_names)),
      settings_(std::move(settings)),
      materials_(std::move(materials)),
      options_(options) {
  assert(settings_);
  cos_smooth_ = std::cos(options_.smooth_angle_deg * std::numbers::pi / 180.0);
  cos_transfer_ = std::cos(options_.history_transfer_angle_deg * std::numbers::pi / 180.0);
}

// ---------------------------------------------------------------- surface --

void SurfaceContact::set_surface(const geometry::SurfaceMesh& surface) {
  const std::size_t nodes = surface.node_position.size();
  const std::size_t faces = surface.triangle.size();
  auto fail = [](const std::string& problem) {
    throw ProtocolError(
        fmt::format("surface for the particle-surface contact: {}. Fix the FEM solver's surface export.", problem));
  };
  if (surface.node_id.size() != nodes) {
    fail(fmt::format("{} node ids for {} node positions", surface.node_id.size(), nodes));
  }
  auto check_face_array = [&](std::size_t size, const char* name) {
    if (size != faces) fail(fmt::format("{} has {} entries for {} triangles", name, size, faces));
  };
  check_face_array(surface.face_part.size(), "face_part");
  check_face_array(surface.face_thickness.size(), "face_thickness");
  check_face_array(surface.face_bulk_modulus.size(), "face_bulk_modulus");
  check_face_array(surface.face_element_volume.size(), "face_element_volume");
  if (nodes >= std::numeric_limits<std::uint32_t>::max() || faces >= std::numeric_limits<std::uint32_t>::max()) {
    fail(fmt::format("{} nodes and {} triangles exceed the 32-bit indices", nodes, faces));
  }
  for (std::size_t i = 0; i < nodes; ++i) {
    if (!surface.node_position[i].allFinite()) fail(fmt::format("node {} has a non-finite position", i));
  }
  for (std::size_t f = 0; f < faces; ++f) {
    for (std::uint32_t node : surface.triangle[f]) {
      if (node >= nodes) fail(fmt::format("triangle {} refers to node {} of {}", f, node, nodes));
    }
    if (surface.face_part[f] >= surface.part_name.size()) {
      fail(fmt::format("triangle {} belongs to part {} of {}", f, surface.face_part[f], surface.part_name.size()));
    }
    const double thickness = surface.face_thickness[f];
    if (!std::isfinite(thickness) || thickness < 0) {
      fail(fmt::format("triangle {} has thickness {} m (must be >= 0)", f, thickness));
    }
    const double volume = surface.face_element_volume[f];
    if (!std::isfinite(volume) || volume < 0) {
      fail(fmt::format("triangle {} has element volume {} m^3 (must be >= 0)", f, volume));
    }
  }
  surface_ = surface;
  node_velocity_.assign(nodes, Vec3::Zero());

  // Merge nodes at exactly the same position (unwelded STL meshes).
  std::vector<std::uint32_t> order(nodes);
  std::iota(order.begin(), order.end(), 0U);
  auto position_less = [&](std::uint32_t i, std::uint32_t j) {
    const Vec3& p = surface_.node_position[i];
    const Vec3& q = surface_.node_position[j];
    if (p.x() != q.x()) return p.x() < q.x();
    if (p.y() != q.y()) return p.y() < q.y();
    if (p.z() != q.z()) return p.z() < q.z();
    return i < j;
  };
  std::sort(order.begin(), order.end(), position_less);
  canonical_.assign(nodes, 0);
  for (std::size_t k = 0; k < nodes; ++k) {
    const std::uint32_t node = order[k];
    if (k > 0 && surface_.node_position[order[k - 1]] == surface_.node_position[node]) {
      canonical_[node] = canonical_[order[k - 1]];
    } else {
      canonical_[node] = node;
    }
  }

  // Faces around each (merged) node.
  node_face_start_.assign(nodes + 1, 0);
  for (const auto& tri : surface_.triangle) {
    for (std::uint32_t node : tri) ++node_face_start_[canonical_[node] + 1];
  }
  for (std::size_t i = 0; i < nodes; ++i) node_face_start_[i + 1] += node_face_start_[i];
  node_faces_.resize(node_face_start_[nodes]);
  std::vector<std::uint32_t> cursor(node_face_start_.begin(), node_face_start_.end() - 1);
  for (std::size_t f = 0; f < faces; ++f) {
    for (std::uint32_t node : surface_.triangle[f])
      node_faces_[cursor[canonical_[node]]++] = static_cast<std::uint32_t>(f);
  }

  // Node masses do not change while the surface moves.
  face_mass_.resize(faces);
  for (std::size_t f = 0; f < faces; ++f) {
    const auto& t = surface_.triangle[f];
    face_mass_[f] = std::min({surface_.mass_of(t[0]), surface_.mass_of(t[1]), surface_.mass_of(t[2])});
  }
  refresh_geometry(/*keep_stiffness=*/false);
  resolve_pairs();
}

void SurfaceContact::refresh_geometry(bool keep_stiffness) {
  const std::size_t faces = surface_.triangle.size();
  face_normal_.resize(faces);
  face_stiffness_factor_.resize(faces);
  face_shortest_edge_.resize(faces);
  degenerate_.resize(faces);
  face_box_.resize(faces);
  cover_.reset();
  max_thickness_ = 0;
  std::vector<double> sizes;
  sizes.reserve(faces);
  for (std::size_t f = 0; f < faces; ++f) {
    const double size = refresh_face(f, keep_stiffness);
    if (degenerate_[f]) continue;
    sizes.push_back(size);
    max_thickness_ = std::max(max_thickness_, surface_.face_thickness[f]);
  }
  if (sizes.empty()) {
    median_face_size_ = 0;
  } else {
    auto middle = sizes.begin() + static_cast<std::ptrdiff_t>(sizes.size() / 2);
    std::nth_element(sizes.begin(), middle, sizes.end());
    median_face_size_ = *middle;
  }
  moving_.assign(faces, 0);
  moving_faces_.clear();
  grid_valid_ = false;
  moving_grid_valid_ = false;
}

double SurfaceContact::refresh_face(std::size_t f, bool keep_stiffness) {
  const auto& tri = surface_.triangle[f];
  const Vec3& a = surface_.node_position[tri[0]];
  const Vec3& b = surface_.node_position[tri[1]];
  const Vec3& c = surface_.node_position[tri[2]];
  const bool merged = canonical_[tri[0]] == canonical_[tri[1]] || canonical_[tri[1]] == canonical_[tri[2]] ||
                      canonical_[tri[2]] == canonical_[tri[0]];
  const Vec3 cross = (b - a).cross(c - a);
  const double twice_area = cross.norm();
  const auto [shortest2, longest2] = std::minmax({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  const double longest = std::sqrt(longest2);
  face_shortest_edge_[f] = std::sqrt(shortest2);
  const bool degenerate = merged || !(twice_area > kDegenerateAreaRatio * longest * longest);
  degenerate_[f] = degenerate ? 1 : 0;
  face_box_[f] = Aabb{};
  if (degenerate) {
    face_normal_[f] = Vec3::UnitZ();
    face_stiffness_factor_[f] = 0;
    return 0;
  }
  face_normal_[f] = cross / twice_area;
  // Eq. 6's stiffness stays that of the surface as set: a stiffness following the deformed face area is not
  // the gradient of a penalty energy (it created energy).
  if (!keep_stiffness || !(face_stiffness_factor_[f] > 0)) {
    const double area = 0.5 * twice_area;
    const double bulk_modulus = surface_.face_bulk_modulus[f];
    const double volume = surface_.face_element_volume[f];
    // Eq. 6 without k1. A triangle's longest edge stands for the segment's "max diagonal".
    face_stiffness_factor_[f] = volume > 0 ? bulk_modulus * area * area / volume : bulk_modulus * area / longest;
  }
  face_box_[f].extend(a);
  face_box_[f].extend(b);
  face_box_[f].extend(c);
  return (face_box_[f].max - face_box_[f].min).maxCoeff();
}

void SurfaceContact::refresh_moved_faces(const std::vector<std::uint32_t>& faces) {
  bool new_moving = false;
  for (std::uint32_t f : faces) {
    refresh_face(f, /*keep_stiffness=*/true);
    if (!moving_[f]) {
      moving_[f] = 1;
      new_moving = true;
    }
    // The interest regions stay valid while every moved face lies inside them.
    if (cover_ && !degenerate_[f] && std::none_of(cover_->begin(), cover_->end(), [&](const Aabb& box) {
          return box.contains(face_box_[f].min) && box.contains(face_box_[f].max);
        })) {
      cover_.reset();
    }
  }
  if (new_moving) {
    moving_faces_.clear();
    for (std::size_t f = 0; f < moving_.size(); ++f) {
      if (moving_[f]) moving_faces_.push_back(static_cast<std::uint32_t>(f));
    }
    grid_valid_ = false;  // a face left the static grid
  }
  moving_grid_valid_ = false;
}

void SurfaceContact::resolve_pairs() {
  const std::size_t parts = surface_.part_name.size();
  pairs_.assign(source_names_.size() * parts, Pair{});
  for (std::size_t s = 0; s < source_names_.size(); ++s) {
    for (std::size_t p = 0; p < parts; ++p) {
      const scene::SurfaceContact settings = settings_(source_names_[s], surface_.part_name[p]);
      Pair& pair = pairs_[s * parts + p];
      pair.enabled = settings.enabled;
      pair.friction = settings.friction;
      pair.penalty_scale = settings.penalty_scale;
      pair.explicit_stiffness = settings.normal_stiffness.value_or(0.0);
      pair.normal_damping_ratio = settings.normal_damping_ratio;
      pair.tangential_damping_ratio = settings.tangential_damping_ratio;
      pair.hertz = settings.model == scene::SurfaceContact::Model::hertz_mindlin;
      pair.restitution = settings.restitution;
      if (settings.has_rolling()) {
        pair.rolling = settings.rolling == scene::RollingModel::constant ? 1 : 2;
        pair.rolling_friction = settings.rolling_friction;
        pair.rolling_viscosity = settings.rolling_viscosity;
      }
      if (!pair.hertz || !pair.enabled) continue;
      const std::array<double, 4> elastic =
          materials_ ? materials_(source_names_[s], surface_.part_name[p]) : std::array<double, 4>{0, 0, 0, 0};
      const double sphere_youngs = elastic[0], sphere_nu = elastic[1], wall_youngs = elastic[2], wall_nu = elastic[3];
      if (!(sphere_youngs > 0) || !(wall_youngs > 0)) {
        throw ProtocolError(fmt::format(
            "particle-surface contact of '{}' with part '{}': the pair asks for the Hertz-Mindlin law, but the "
            "elastic constants of its materials are unknown. Fix: give the coupler the scene's materials, or use "
            "model = \"penalty\" for this pair",
            source_names_[s], surface_.part_name[p]));
      }
      pair.effective_modulus = physics::hertz_effective_modulus(sphere_youngs, sphere_nu, wall_youngs, wall_nu);
      pair.effective_shear_modulus =
          physics::mindlin_effective_shear_modulus(sphere_youngs, sphere_nu, wall_youngs, wall_nu);
      const double sphere_shear = sphere_youngs / (2 * (1 + sphere_nu));
      pair.rayleigh_factor = 1.0 / (std::sqrt(sphere_shear) * (0.1631 * sphere_nu + 0.8766));
    }
  }
  for (std::size_t f = 0; f < surface_.triangle.size(); ++f) {
    if (degenerate_[f]) continue;
    for (std::size_t s = 0; s < source_names_.size(); ++s) {
      if (!pair(static_cast<std::uint32_t>(s), f).enabled || pair(static_cast<std::uint32_t>(s), f).hertz) continue;
      const double k = face_stiffness(f, s);
      if (!(k > 0) || !std::isfinite(k)) {
        const std::size_t part = surface_.face_part[f];
        throw ProtocolError(fmt::format(
            "surface for the particle-surface contact: triangle {} of part '{}' gets no penalty stiffness against "
            "'{}' (paper eq. 6 with bulk modulus {} Pa, element volume {} m^3, penalty scale {}). Fix: the FEM "
            "solver must send the bulk modulus of the face's material, or give the pair an explicit "
            "normal_stiffness in the scene",
            f, surface_.part_name[part], source_names_[s], surface_.face_bulk_modulus[f],
            surface_.face_element_volume[f], pairs_[s * parts + part].penalty_scale));
      }
    }
  }
}

double SurfaceContact::face_stiffness(std::size_t face, std::size_t source) const {
  const Pair& settings = pair(static_cast<std::uint32_t>(source), face);
  if (settings.explicit_stiffness > 0) return settings.explicit_stiffness;
  return settings.penalty_scale * face_stiffness_factor_[face];
}

void SurfaceContact::update_nodes(std::span<const double> position, std::span<const double> velocity) {
  const std::size_t nodes = surface_.node_position.size();
  if (position.size() != 3 * nodes || (!velocity.empty() && velocity.size() != 3 * nodes)) {
    throw ProtocolError(fmt::format(
        "surface node update: {} position and {} velocity values for {} nodes (3 each expected). Fix the FEM "
        "solver's StepState",
        position.size(), velocity.size(), nodes));
  }
  std::vector<std::uint32_t> moved_nodes;
  for (std::size_t i = 0; i < nodes; ++i) {
    const Vec3 p = vec3_at(position, i);
    if (!p.allFinite()) throw ProtocolError(fmt::format("surface node update: node {} has a non-finite position", i));
    if (p != surface_.node_position[i]) {
      surface_.node_position[i] = p;
      moved_nodes.push_back(static_cast<std::uint32_t>(i));
    }
    node_velocity_[i] = velocity.empty() ? Vec3::Zero() : vec3_at(velocity, i);
  }
  if (moved_nodes.empty()) return;
  // The faces around the moved nodes (a node at the same place as another shares its faces: canonical_).
  std::vector<std::uint32_t> moved_faces;
  for (std::uint32_t i : moved_nodes) {
    const std::uint32_t c = canonical_[i];
    moved_faces.insert(moved_faces.end(), node_faces_.begin() + node_face_start_[c],
                       node_faces_.begin() + node_face_start_[c + 1]);
  }
  std::sort(moved_faces.begin(), moved_faces.end());
  moved_faces.erase(std::unique(moved_faces.begin(), moved_faces.end()), moved_faces.end());
  if (kPartialRefreshShare * static_cast<double>(moved_faces.size()) < static_cast<double>(surface_.triangle.size())) {
    refresh_moved_faces(moved_faces);
  } else {
    refresh_geometry(/*keep_stiffness=*/true);
  }
}

void SurfaceContact::build_grid(double query_reach, bool points) {
  // Spheres: cells of their reach at least. Points: of the faces' size (a rigid part's few nodes may reach
  // far: their queries visit more cells, rather than every node's query visiting every face).
  double cell = points && median_face_size_ > 0 ? median_face_size_ : std::max(median_face_size_, query_reach);
  if (!(cell > 0)) cell = 1.0;
  if (!grid_valid_ || query_reach > grid_reach_) {
    if (moving_faces_.empty()) {
      grid_.build_boxes(face_box_, cell);
    } else {
      std::vector<Aabb> still(face_box_);
      for (std::uint32_t f : moving_faces_) still[f] = Aabb{};  // left out: binned in moving_grid_
      grid_.build_boxes(still, cell);
    }
    grid_valid_ = true;
    moving_grid_valid_ = false;
    ++static_generation_;
  }
  std::vector<Aabb> moving_boxes;
  moving_boxes.reserve(moving_faces_.size());
  for (std::uint32_t f : moving_faces_) moving_boxes.push_back(face_box_[f]);
  moving_grid_.build_boxes(moving_boxes, cell);
  moving_grid_valid_ = true;
  grid_reach_ = query_reach;
}

std::vector<Aabb> SurfaceContact::interest_regions(double max_radius) const {
  if (!cover_) cover_ = geometry::covering_boxes(face_box_, geometry::kMaxInterestBoxes);
  std::vector<Aabb> boxes = *cover_;
  const double reach = max_radius * (2.0 + options_.potential_margin) + 0.5 * max_thickness_;
  for (Aabb& box : boxes) box = box.inflated(reach);
  return boxes;
}

// ------------------------------------------------------------- per particle --

SurfaceContact::Hit SurfaceContact::evaluate(std::size_t face, const Vec3& centre, double radius, double depth,
                                             bool point) const {
  const auto& tri = surface_.triangle[face];
  const Vec3& a = surface_.node_position[tri[0]];
  const Vec3& b = surface_.node_position[tri[1]];
  const Vec3& c = surface_.node_position[tri[2]];
  Hit hit;
  hit.face = static_cast<std::uint32_t>(face);
  hit.closest = closest_point_on_triangle(centre, a, b, c);
  if (point && hit.closest.feature != Feature::face && surface_.face_thickness[face] == 0) {
    // A point behind a one-sided face whose projection falls on the face's boundary (a node facing a node or
    // an edge of the other structure, as meshes aligned across the contact put them) meets the face: every
    // triangle around that vertex or edge calls it a vertex or edge point, which a point of radius 0 cannot
    // touch, and it would pass through until it drifted inside a face with its whole overlap at once. "On the
    // boundary" within kFaceExtension of the face's size: once pressed, the faces tilt by 1e-6 rad and a
    // node under a node projects 1e-9 m outside every triangle around it, and a rim node bulges past the
    // other block's edge by its Poisson expansion (1e-4 m on 0.25 m elements); with a round-off slack both
    // lost their contact and passed in (energy +207 % for two equal blocks stacked node on node).
    const Vec3& n = face_normal_[face];
    const double height = (centre - a).dot(n);
    const Vec3 projection = centre - height * n;
    const double size = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    if (height < 0 && (projection - hit.closest.point).norm() <= kFaceExtension * size) {
      hit.closest.feature = Feature::face;
      hit.closest.index = 0;
    }
  }
  hit.gap =
      sphere_triangle_gap(centre, radius, surface_.face_thickness[face], a, face_normal_[face], hit.closest, depth);
  return hit;
}

bool SurfaceContact::shares_node(std::uint32_t face_a, std::uint32_t face_b) const {
  const auto& a = surface_.triangle[face_a];
  const auto& b = surface_.triangle[face_b];
  for (std::uint32_t i : a) {
    for (std::uint32_t j : b) {
      if (canonical_[i] == canonical_[j]) return true;
    }
  }
  return false;
}

Vec3 SurfaceContact::surface_velocity_at(const Hit& hit) const {
  const auto& tri = surface_.triangle[hit.face];
  const auto& w = hit.closest.weight;
  return w[0] * node_velocity_[tri[0]] + w[1] * node_velocity_[tri[1]] + w[2] * node_velocity_[tri[2]];
}

SurfaceContact::FeatureKey SurfaceContact::feature_key(const Hit& hit) const {
  const auto& tri = surface_.triangle[hit.face];
  FeatureKey key;
  key.kind = hit.closest.feature;
  key.node = {kNoNode, kNoNode, kNoNode};
  auto id = [&](int corner) { return surface_.node_id[canonical_[tri[static_cast<std::size_t>(corner % 3)]]]; };
  switch (hit.closest.feature) {
    case Feature::face: key.node = {id(0), id(1), id(2)}; break;
    case Feature::edge: key.node = {id(hit.closest.index), id(hit.closest.index + 1), kNoNode}; break;
    case Feature::vertex: key.node = {id(hit.closest.index), kNoNode, kNoNode}; break;
  }
  std::sort(key.node.begin(), key.node.end());
  return key;
}

bool SurfaceContact::feature_is_local_minimum(const Hit& hit, std::uint32_t source, const Vec3& centre, double radius,
                                              double depth, bool point, Scratch& scratch) const {
  const auto& tri = surface_.triangle[hit.face];
  const auto corner = [&](int k) { return canonical_[tri[static_cast<std::size_t>(k % 3)]]; };
  const bool is_edge = hit.closest.feature == Feature::edge;
  const std::uint32_t u = corner(hit.closest.index);
  const std::uint32_t v = is_edge ? corner(hit.closest.index + 1) : u;
  for (std::uint32_t k = node_face_start_[u]; k < node_face_start_[u + 1]; ++k) {
    const std::uint32_t other = node_faces_[k];
    if (other == hit.face || !usable(source, other)) continue;
    const auto& other_tri = surface_.triangle[other];
    std::array<std::uint32_t, 3> nodes{canonical_[other_tri[0]], canonical_[other_tri[1]], canonical_[other_tri[2]]};
    if (is_edge && std::find(nodes.begin(), nodes.end(), v) == nodes.end()) continue;  // not around this edge
    // The neighbour's own closest point (computed once per particle and face).
    auto found = std::lower_bound(scratch.hits.begin(), scratch.hits.end(), other,
                                  [](const Hit& h, std::uint32_t face) { return h.face < face; });
    const Hit other_hit =
        (found != scratch.hits.end() && found->face == other) ? *found : evaluate(other, centre, radius, depth, point);
    const TrianglePoint& closest = other_hit.closest;
    if (closest.feature == Feature::face) return false;
    const std::uint32_t p = nodes[static_cast<std::size_t>(closest.index)];
    const std::uint32_t q =
        closest.feature == Feature::edge ? nodes[static_cast<std::size_t>((closest.index + 1) % 3)] : p;
    if (is_edge) {
      // The neighbour's closest point must lie on this edge: the edge itself or one of its ends.
      if ((p != u && p != v) || (q != u && q != v)) return false;
    } else if (closest.feature != Feature::vertex || p != u) {
      return false;
    }
  }
  return true;
}

void SurfaceContact::process_particle(std::size_t i, const ParticleView& particles, double dt_previous,
                                      Scratch& scratch, ParticleResult& result, ContactOutput& out) const {
  result.contacts.clear();
  result.stable_dt = std::numeric_limits<double>::infinity();
  const Vec3 centre = vec3_at(particles.position, i);
  const double radius = particles.radius[i];
  const double mass = particles.mass[i];
  const std::uint32_t source = particles.body.empty() ? 0U : particles.body[i];
  // Spheres: depth = radius, and the potential zone one margin of radii wide; points: of depths.
  const bool point = !particles.depth.empty();
  const double depth = point ? particles.depth[i] : radius;
  const double potential_reach =
      point ? radius + options_.potential_margin * depth : radius * (1.0 + options_.potential_margin);
  const double reach = potential_reach + 0.5 * max_thickness_;

  if (options_.brute_force_search) {
    scratch.candidates.resize(surface_.triangle.size());
    std::iota(scratch.candidates.begin(), scratch.candidates.end(), 0U);
  } else {
    // Faces whose own box misses the query box are dropped; the candidates come out sorted and unique.
    const Aabb query{centre.array() - reach, centre.array() + reach};
    StaticCandidates& cached = static_candidates_[i];
    const bool inside =
        (query.min.array() >= cached.box.min.array()).all() && (query.max.array() <= cached.box.max.array()).all();
    if (cached.generation != static_generation_ || !inside) {
      // Every static face whose box overlaps the query box overlaps this larger box, and grid_ has not
      // changed since: filtering these by the query box gives what a query of grid_ would.
      cached.generation = static_generation_;
      cached.box = query.inflated(kCandidateSkin * reach);
      cached.faces.clear();
      grid_.for_each_in(cached.box, [&](std::uint32_t face) {
        if (face_box_[face].overlaps(cached.box)) cached.faces.push_back(face);
      });
      std::sort(cached.faces.begin(), cached.faces.end());
      cached.faces.erase(std::unique(cached.faces.begin(), cached.faces.end()), cached.faces.end());
    }
    scratch.candidates.clear();
    for (std::uint32_t face : cached.faces) {
      if (face_box_[face].overlaps(query)) scratch.candidates.push_back(face);
    }
    if (!moving_faces_.empty()) {
      const std::size_t still = scratch.candidates.size();
      moving_grid_.for_each_in(query, [&](std::uint32_t k) {
        const std::uint32_t face = moving_faces_[k];
        if (face_box_[face].overlaps(query)) scratch.candidates.push_back(face);
      });
      if (scratch.candidates.size() > still) {
        // The moving faces are not in grid_: sorted apart, then merged with the static ones.
        const auto middle = scratch.candidates.begin() + static_cast<std::ptrdiff_t>(still);
        std::sort(middle, scratch.candidates.end());
        scratch.candidates.erase(std::unique(middle, scratch.candidates.end()), scratch.candidates.end());
        std::inplace_merge(scratch.candidates.begin(), middle, scratch.candidates.end());
      }
    }
  }
  scratch.hits.clear();
  double nearest = std::numeric_limits<double>::infinity();
  for (std::uint32_t face : scratch.candidates) {
    if (!usable(source, face)) continue;
    const Hit hit = evaluate(face, centre, radius, depth, point);
    nearest = std::min(nearest, hit.gap.distance);
    if (hit.gap.reachable && hit.gap.overlap > radius - potential_reach) {
      const Pair& settings = pair(source, face);
      const double pair_mass = reduced_mass(mass, face_mass_[face]);
      if (settings.hertz) {
        // A fifth of the particle's Rayleigh time pi r sqrt(rho / G) / (0.1631 nu + 0.8766), and a tenth of the
        // contact period at the current overlap (fast impacts go deeper than the Rayleigh bound assumes).
        const double density = mass / (4.0 / 3.0 * std::numbers::pi * radius * radius * radius);
        result.stable_dt =
            std::min(result.stable_dt, 0.2 * std::numbers::pi * radius * std::sqrt(density) * settings.rayleigh_factor);
        if (hit.gap.overlap > 0) {
          const double stiffness = 2.0 * settings.effective_modulus * std::sqrt(radius * hit.gap.overlap);
          result.stable_dt = std::min(result.stable_dt, physics::spring_stable_dt(pair_mass, stiffness));
        }
      } else {
        // The rolling spring's k_r / I is 5.625 mu_r^2 times k_n / m (dem_model.hpp, stable_dt()).
        const double rolling =
            settings.rolling == 1 ? std::max(1.0, 5.625 * std::pow(settings.rolling_friction, 2)) : 1.0;
        const double k = rolling * face_stiffness(face, source);
        result.stable_dt = std::min(result.stable_dt, physics::spring_stable_dt(pair_mass, k));
      }
    }
    scratch.hits.push_back(hit);
  }

  const std::uint64_t id = particles.id[i];
  const auto range =
      std::equal_range(history_.begin(), history_.end(), HistoryEntry{id, {}, {}, {}, 0.0, 0.0, {}},
                       [](const HistoryEntry& a, const HistoryEntry& b) { return a.particle < b.particle; });
  const auto previous = std::span<const HistoryEntry>(history_).subspan(
      static_cast<std::size_t>(range.first - history_.begin()), static_cast<std::size_t>(range.second - range.first));
  const Vec3 velocity = vec3_at(particles.velocity, i);
  // Whether the particle is behind `hit`'s face because it went through it: it held a contact on that face in
  // the previous step, or its centre was in front of the face's plane one step ago (the approach over
  // dt_previous, relative to the face's nodes, covers its depth behind the plane).
  const auto entered_through = [&](const Hit& hit) {
    const FeatureKey key = feature_key(hit);
    if (std::any_of(previous.begin(), previous.end(), [&](const HistoryEntry& e) { return e.key == key; })) {
      return true;
    }
    const Vec3& n = face_normal_[hit.face];
    const double height = (centre - surface_.node_position[surface_.triangle[hit.face][0]]).dot(n);
    return height - (velocity - surface_velocity_at(hit)).dot(n) * dt_previous >= 0;
  };

  // Contacts: in reach, not behind a one-sided face unless it is the nearest or the particle went through
  // it (two blocks meshed alike and stacked node on node: a rim node that has crossed the other block's top
  // lies on that block's side face, at distance 0, the nearest; judged by the distance alone, the rims
  // passed into each other), edges and vertices only where they are a local minimum of the distance.
  scratch.touching.clear();
  for (std::size_t h = 0; h < scratch.hits.size(); ++h) {
    const Hit& hit = scratch.hits[h];
    if (!(hit.gap.overlap > 0) || !hit.gap.reachable) continue;
    if (hit.gap.behind && hit.gap.distance > nearest * (1.0 + kDistanceSlack) && !entered_through(hit)) continue;
    if (hit.closest.feature != Feature::face &&
        !feature_is_local_minimum(hit, source, centre, radius, depth, point, scratch)) {
      continue;
    }
    scratch.touching.push_back(h);
  }
  // One contact per smooth piece of surface: deepest first, then lower face, then face before edge before vertex.
  std::sort(scratch.touching.begin(), scratch.touching.end(), [&](std::size_t x, std::size_t y) {
    const Hit& a = scratch.hits[x];
    const Hit& b = scratch.hits[y];
    if (a.gap.overlap != b.gap.overlap) return a.gap.overlap > b.gap.overlap;
    if (a.face != b.face) return a.face < b.face;
    return feature_rank(a.closest.feature) < feature_rank(b.closest.feature);
  });
  // Rule 3 with memory: a feature merged into a neighbouring contact stays
  // merged while a contact on a triangle sharing a node with it remains, even
  // once the angle between them has grown past the smooth angle. Deciding by
  // the angle every step made a dented surface add a second full-stiffness
  // contact, with its whole overlap, the step two faces of the dent passed the
  // smooth angle: a jump of the force and of the penalty energy, energy created
  // (docs/physics.md, FEM, "coupling"). Merging stays immediate (a merge can
  // only take energy out).
  const auto merged_range =
      std::equal_range(merged_.begin(), merged_.end(), MergedEntry{id, {}},
                       [](const MergedEntry& a, const MergedEntry& b) { return a.particle < b.particle; });
  const auto was_merged = [&](const FeatureKey& key) {
    return std::any_of(merged_range.first, merged_range.second, [&](const MergedEntry& e) { return e.key == key; });
  };
  const auto same_as_kept = [&](const FeatureKey& key) {
    return std::any_of(scratch.kept.begin(), scratch.kept.end(),
                       [&](std::size_t k) { return feature_key(scratch.hits[k]) == key; });
  };
  scratch.kept.clear();
  result.merged.clear();
  // Pass 1, deepest first, by the angle: every feature not merged in the previous step.
  for (std::size_t h : scratch.touching) {
    const Hit& hit = scratch.hits[h];
    const FeatureKey key = feature_key(hit);
    if (was_merged(key) || same_as_kept(key)) continue;
    const bool duplicate = std::any_of(scratch.kept.begin(), scratch.kept.end(), [&](std::size_t k) {
      const Hit& other = scratch.hits[k];
      return hit.gap.normal.dot(other.gap.normal) >= cos_smooth_ && shares_node(hit.face, other.face);
    });
    if (duplicate) {
      result.merged.push_back(key);
    } else {
      scratch.kept.push_back(h);
    }
  }
  // Pass 2: features merged in the previous step stay merged while a neighbouring contact remains.
  for (std::size_t h : scratch.touching) {
    const Hit& hit = scratch.hits[h];
    const FeatureKey key = feature_key(hit);
    if (!was_merged(key) || same_as_kept(key)) continue;
    const bool carried = std::any_of(scratch.kept.begin(), scratch.kept.end(),
                                     [&](std::size_t k) { return shares_node(hit.face, scratch.hits[k].face); });
    if (carried) {
      if (std::find(result.merged.begin(), result.merged.end(), key) == result.merged.end()) {
        result.merged.push_back(key);
      }
    } else {
      scratch.kept.push_back(h);
    }
  }
  if (scratch.kept.empty()) return;

  // Tangential springs: same feature first, then the closest-normal vanished contact.
  const std::size_t count = scratch.kept.size();
  result.contacts.resize(count);
  scratch.history_used.assign(previous.size(), 0);
  scratch.has_history.assign(count, 0);
  scratch.displacement.assign(count, Vec3::Zero());
  scratch.rolling_torque.assign(count, Vec3::Zero());
  scratch.normal_offset.assign(count, 0.0);
  for (std::size_t c = 0; c < count; ++c) {
    ActiveContact& contact = result.contacts[c];
    contact.hit = scratch.hits[scratch.kept[c]];
    contact.key = feature_key(contact.hit);
    for (std::size_t e = 0; e < previous.size(); ++e) {
      if (!scratch.history_used[e] && previous[e].key == contact.key) {
        scratch.history_used[e] = 1;
        scratch.has_history[c] = 1;
        scratch.displacement[c] = previous[e].displacement;
        scratch.rolling_torque[c] = previous[e].rolling_torque;
        scratch.normal_offset[c] = previous[e].normal_offset;
        break;
      }
    }
  }
  for (std::size_t c = 0; c < count; ++c) {
    if (scratch.has_history[c]) continue;
    const Vec3& normal = result.contacts[c].hit.gap.normal;
    std::size_t best = previous.size();
    double best_alignment = cos_transfer_;
    for (std::size_t e = 0; e < previous.size(); ++e) {
      const double alignment = previous[e].normal.dot(normal);
      if (!scratch.history_used[e] && alignment >= best_alignment) {
        if (best == previous.size() || alignment > best_alignment) {
          best = e;
          best_alignment = alignment;
        }
      }
    }
    const double overlap = result.contacts[c].hit.gap.overlap;
    if (best < previous.size()) {
      scratch.history_used[best] = 1;
      scratch.displacement[c] = previous[best].displacement;
      scratch.rolling_torque[c] = previous[best].rolling_torque;
      scratch.normal_offset[c] = std::max(0.0, overlap - previous[best].spring_overlap);
    } else if (!previous.empty()) {
      scratch.normal_offset[c] = overlap;  // born inside a lasting contact: no stored energy
    }
  }

  const Vec3 spin = particles.angular_velocity.empty() ? Vec3::Zero() : vec3_at(particles.angular_velocity, i);
  Vec3 force_sum = Vec3::Zero();
  Vec3 torque_sum = Vec3::Zero();
  for (std::size_t c = 0; c < count; ++c) {
    ActiveContact& contact = result.contacts[c];
    const Hit& hit = contact.hit;
    const Pair& settings = pair(source, hit.face);

    const Vec3& n = hit.gap.normal;
    const Vec3 lever = -radius * n;  // centre to the particle's contact point
    const Vec3 relative_velocity = velocity + spin.cross(lever) - surface_velocity_at(hit);
    physics::TangentialHistory spring{scratch.displacement[c]};
    contact.normal_offset = std::min(scratch.normal_offset[c], hit.gap.overlap);
    const double spring_overlap = hit.gap.overlap - contact.normal_offset;
    if (settings.hertz) {
      const physics::HertzMindlin law{.effective_modulus = settings.effective_modulus,
                                      .effective_radius = radius,
                                      .effective_mass = mass,
                                      .effective_shear_modulus = settings.effective_shear_modulus,
                                      .restitution = settings.restitution,
                                      .friction = settings.friction};
      contact.law = physics::hertz_mindlin_force(law, spring_overlap, n, relative_velocity, dt_previous, spring);
      contact.normal_stiffness = physics::hertz_normal_stiffness(law, spring_overlap);
    } else {
      const double k = face_stiffness(hit.face, source);
      const double damping_mass = options_.damping_mass == SurfaceContactOptions::DampingMass::reduced
                                      ? reduced_mass(mass, face_mass_[hit.face])
                                      : mass;
      physics::SpringDashpot law{};
      law.normal_stiffness = k;
      law.normal_damping = physics::damping_coefficient(k, damping_mass, settings.normal_damping_ratio);
      law.tangential_stiffness = k;
      law.tangential_damping = physics::damping_coefficient(k, damping_mass, settings.tangential_damping_ratio);
      law.friction = settings.friction;
      contact.law = physics::spring_dashpot_force(law, spring_overlap, n, relative_velocity, dt_previous, spring);
      contact.normal_stiffness = k;
    }
    contact.displacement = spring.displacement;
    contact.dissipated_power = -contact.law.dissipative_force.dot(relative_velocity);
    force_sum += contact.law.force;
    torque_sum += lever.cross(contact.law.force);
    if (settings.rolling == 1) {
      // The elastic-plastic rolling spring of the DEM-DEM contact (physics::rolling_spring_torque) against a
      // face that does not turn: r_eff = the sphere's radius, its dashpot with the pair's tangential damping
      // ratio and the sphere's moment of inertia.
      const double k_r = physics::rolling_stiffness(contact.normal_stiffness, settings.rolling_friction, radius);
      const physics::RollingSpring law{
          .stiffness = k_r,
          .damping = physics::damping_coefficient(k_r, 0.4 * mass * radius * radius, settings.tangential_damping_ratio),
          .friction = settings.rolling_friction,
          .effective_radius = radius};
      physics::RollingHistory rolling{scratch.rolling_torque[c]};
      const physics::RollingTorque torque =
          physics::rolling_spring_torque(law, contact.law.normal_force, spin, dt_previous, rolling);
      contact.rolling_torque = rolling.torque;
      contact.law.elastic_energy += torque.elastic_energy;
      contact.dissipated_power -= torque.dissipative_torque.dot(spin);
      torque_sum += torque.torque;
    } else if (settings.rolling == 2) {
      const Vec3 torque =
          (-settings.rolling_viscosity * radius * std::max(contact.law.normal_force, 0.0) * radius) * spin;
      contact.dissipated_power -= torque.dot(spin);
      torque_sum += torque;
    }
  }
  for (int axis = 0; axis < 3; ++axis) {
    out.particle_force[3 * i + static_cast<std::size_t>(axis)] = force_sum[axis];
    out.particle_torque[3 * i + static_cast<std::size_t>(axis)] = torque_sum[axis];
  }
}

void SurfaceContact::restore(History history) {
  const auto by_particle = [](const auto& a, const auto& b) { return a.particle < b.particle; };
  if (!std::is_sorted(history.springs.begin(), history.springs.end(), by_particle) ||
      !std::is_sorted(history.merged.begin(), history.merged.end(), by_particle)) {
    throw ProtocolError("particle-surface contact history: entries not sorted by particle id");
  }
  history_ = std::move(history.springs);
  merged_ = std::move(history.merged);
  max_radius_seen_ = history.max_radius_seen;
}

// ------------------------------------------------------------------- step --

void SurfaceContact::match_static_candidates(std::span<const std::uint64_t> ids) {
  const std::size_t n = ids.size();
  const bool same = static_candidates_.size() == n &&
                    std::equal(ids.begin(), ids.end(), static_candidates_.begin(),
                               [](std::uint64_t id, const StaticCandidates& c) { return id == c.id; });
  if (same) return;
  // Particles came, went or changed places (interest regions, new particles): each takes its own list again.
  std::vector<StaticCandidates>& next = static_candidates_spare_;
  next.resize(n);
  // The previous entries in id order (usually already so: views list particles by index).
  std::vector<std::uint32_t> order(static_candidates_.size());
  std::iota(order.begin(), order.end(), 0U);
  const auto id_of = [&](std::uint32_t k) { return static_candidates_[k].id; };
  if (!std::is_sorted(order.begin(), order.end(), [&](auto a, auto b) { return id_of(a) < id_of(b); })) {
    std::stable_sort(order.begin(), order.end(), [&](auto a, auto b) { return id_of(a) < id_of(b); });
  }
  for (std::size_t i = 0; i < n; ++i) {
    next[i].id = ids[i];
    next[i].generation = 0;
    const auto it = std::lower_bound(order.begin(), order.end(), ids[i],
                                     [&](std::uint32_t k, std::uint64_t id) { return id_of(k) < id; });
    if (it == order.end() || id_of(*it) != ids[i]) continue;
    StaticCandidates& previous = static_candidates_[*it];
    if (previous.generation == 0) continue;  // taken by an earlier particle of the same id
    next[i].generation = previous.generation;
    next[i].box = previous.box;
    std::swap(next[i].faces, previous.faces);
    previous.generation = 0;
  }
  std::swap(static_candidates_, next);
}

void SurfaceContact::compute(const ParticleView& particles, double dt_previous, ContactOutput& out) {
  const std::size_t n = particles.size();
  const auto fail = [](const std::string& problem) {
    throw ProtocolError(fmt::format("particles for the particle-surface contact: {}", problem));
  };
  if (particles.position.size() != 3 * n || particles.velocity.size() != 3 * n ||
      (!particles.angular_velocity.empty() && particles.angular_velocity.size() != 3 * n) ||
      particles.radius.size() != n || particles.mass.size() != n ||
      (!particles.body.empty() && particles.body.size() != n) ||
      (!particles.depth.empty() && particles.depth.size() != n)) {
    fail(
        fmt::format("array sizes disagree: {} ids, {} positions, {} velocities, {} angular velocities, {} radii, "
                    "{} masses, {} bodies",
                    n, particles.position.size(), particles.velocity.size(), particles.angular_velocity.size(),
                    particles.radius.size(), particles.mass.size(), particles.body.size()));
  }
  if (!(dt_previous >= 0)) fail(fmt::format("dt_previous = {} s must be >= 0", dt_previous));
  if (n >= std::numeric_limits<std::uint32_t>::max()) fail(fmt::format("{} particles exceed 32-bit indices", n));
  double max_radius = 0;
  const bool points = !particles.depth.empty();
  const bool heavy_allowed = options_.damping_mass == SurfaceContactOptions::DampingMass::reduced;
  double max_potential_reach = 0;  // points
  for (std::size_t i = 0; i < n; ++i) {
    const double radius = particles.radius[i];
    if (!(points ? radius >= 0 : radius > 0) || !std::isfinite(radius)) {
      fail(fmt::format("particle {} (id {}) has radius {} m", i, particles.id[i], radius));
    }
    if (points) {
      const double depth = particles.depth[i];
      if (!(depth > 0) || !(depth >= radius) || !std::isfinite(depth)) {
        fail(fmt::format("point {} (id {}) has depth {} m (radius {} m)", i, particles.id[i], depth, radius));
      }
      max_potential_reach = std::max(max_potential_reach, radius + options_.potential_margin * depth);
    }
    const double mass = particles.mass[i];
    if (!(mass > 0) || (!std::isfinite(mass) && !(heavy_allowed && std::isinf(mass)))) {
      fail(fmt::format("particle {} (id {}) has mass {} kg", i, particles.id[i], mass));
    }
    if (!particles.body.empty() && particles.body[i] >= source_names_.size()) {
      fail(fmt::format("particle {} (id {}) belongs to body {} but there are {} bodies", i, particles.id[i],
                       particles.body[i], source_names_.size()));
    }
    if (!vec3_at(particles.position, i).allFinite()) {
      fail(fmt::format("particle {} (id {}) has a non-finite position", i, particles.id[i]));
    }
    max_radius = std::max(max_radius, particles.radius[i]);
  }
  if (n > 0 && source_names_.empty()) fail("particles given but no particle bodies are known");
  max_radius_seen_ = std::max(max_radius_seen_, max_radius);

  const std::size_t parts = surface_.part_name.size();
  const std::size_t sources = source_names_.size();
  out.particle_force.assign(3 * n, 0.0);
  out.particle_torque.assign(3 * n, 0.0);
  out.node_force.assign(3 * surface_.node_position.size(), 0.0);
  out.part_force.assign(parts, Vec3::Zero());
  out.part_source_force.assign(parts * sources, Vec3::Zero());
  out.source_count = sources;
  out.contact_count = 0;
  out.elastic_energy = 0;
  out.dissipated_power = 0;
  out.max_contact_stiffness = 0;
  out.min_contact_mass = std::numeric_limits<double>::infinity();
  out.deepest_overlap_ratio = 0;
  out.deepest_overlap = 0;
  out.deepest_face_edge = 0;
  records_.clear();
  stable_dt_ = std::numeric_limits<double>::infinity();
  if (surface_.triangle.empty()) {
    history_.clear();
    merged_.clear();
    return;
  }

  const double query_reach =
      (points ? max_potential_reach : max_radius * (1.0 + options_.potential_margin)) + 0.5 * max_thickness_;
  if (!grid_valid_ || !moving_grid_valid_ || query_reach > grid_reach_) build_grid(query_reach, points);

  if (results_.size() < n) results_.resize(n);
  if (!options_.brute_force_search) match_static_candidates(particles.id);
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel if (count > kParallelThreshold)
  {
    Scratch scratch;
#pragma omp for schedule(dynamic, 64)
    for (std::int64_t i = 0; i < count; ++i) {
      const auto index = static_cast<std::size_t>(i);
      process_particle(index, particles, dt_previous, scratch, results_[index], out);
    }
  }

  // Sums over particles, in particle order.
  next_history_.clear();
  next_merged_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const ParticleResult& result = results_[i];
    stable_dt_ = std::min(stable_dt_, result.stable_dt);
    const std::uint32_t source = particles.body.empty() ? 0U : particles.body[i];
    for (const FeatureKey& key : result.merged) next_merged_.push_back(MergedEntry{particles.id[i], key});
    for (const ActiveContact& contact : result.contacts) {
      const Hit& hit = contact.hit;
      const Vec3& force = contact.law.force;
      const auto& tri = surface_.triangle[hit.face];
      const auto& w = hit.closest.weight;
      const Vec3 f0 = -w[0] * force;
      const Vec3 f1 = -w[1] * force;
      const Vec3 f2 = -force - f0 - f1;
      add_at(out.node_force, tri[0], f0);
      add_at(out.node_force, tri[1], f1);
      add_at(out.node_force, tri[2], f2);
      const std::size_t part = surface_.face_part[hit.face];
      out.part_force[part] -= force;
      out.part_source_force[part * sources + source] -= force;
      out.elastic_energy += contact.law.elastic_energy;
      out.dissipated_power += contact.dissipated_power;
      out.max_contact_stiffness = std::max(out.max_contact_stiffness, contact.normal_stiffness);
      out.min_contact_mass = std::min(out.min_contact_mass, particles.mass[i]);
      const double overlap_ratio = hit.gap.overlap / face_shortest_edge_[hit.face];
      if (overlap_ratio > out.deepest_overlap_ratio) {
        out.deepest_overlap_ratio = overlap_ratio;
        out.deepest_overlap = hit.gap.overlap;
        out.deepest_face_edge = face_shortest_edge_[hit.face];
      }
      ++out.contact_count;

      ContactRecord record;
      record.particle = static_cast<std::uint32_t>(i);
      record.face = hit.face;
      record.feature = hit.closest.feature;
      record.point = hit.closest.point;
      record.normal = hit.gap.normal;
      record.overlap = hit.gap.overlap;
      record.normal_stiffness = contact.normal_stiffness;
      record.force = force;
      record.normal_force = contact.law.normal_force;
      record.sliding = contact.law.sliding;
      records_.push_back(record);

      next_history_.push_back(HistoryEntry{particles.id[i], contact.key, contact.displacement, hit.gap.normal,
                                           contact.normal_offset, hit.gap.overlap - contact.normal_offset,
                                           contact.rolling_torque});
    }
  }
  std::stable_sort(next_history_.begin(), next_history_.end(),
                   [](const HistoryEntry& a, const HistoryEntry& b) { return a.particle < b.particle; });
  history_.swap(next_history_);
  std::stable_sort(next_merged_.begin(), next_merged_.end(),
                   [](const MergedEntry& a, const MergedEntry& b) { return a.particle < b.particle; });
  merged_.swap(next_merged_);
}

}  // namespace sabo::contact
