#include "libsabo/geometry/surface_sampling.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "libsabo/core/error.hpp"
#include "libsabo/physics/cell_list.hpp"

namespace sabo::geometry {

namespace {

struct ClosestOnTriangle {
  Vec3 point;
  std::array<double, 3> weight;  // barycentric, each >= 0, sum 1
};

// Closest point of triangle (a, b, c) to p (Ericson, Real-Time Collision Detection, 5.1.5).
ClosestOnTriangle closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {a, {1, 0, 0}};
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {b, {0, 1, 0}};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {a + v * ab, {1 - v, v, 0}};
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {c, {0, 0, 1}};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {a + w * ac, {1 - w, 0, w}};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), {0, 1 - w, w}};
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {a + ab * v + ac * w, {1 - v - w, v, w}};
}

struct Frame {
  Vec3 e1, e2, n;
};

Frame face_frame(const SurfaceMesh& mesh, std::size_t face) {
  const auto& t = mesh.triangle[face];
  Frame f;
  f.n = mesh.face_normal(face);
  f.e1 = (mesh.node_position[t[1]] - mesh.node_position[t[0]]).normalized();
  f.e2 = f.n.cross(f.e1);
  return f;
}

Vec3 anchor_of(const SurfaceMesh& mesh, std::uint32_t face, const std::array<double, 3>& w) {
  const auto& t = mesh.triangle[face];
  return w[0] * mesh.node_position[t[0]] + w[1] * mesh.node_position[t[1]] + w[2] * mesh.node_position[t[2]];
}

// Faces in one plane, sampled on one lattice.
struct Patch {
  Vec3 n = Vec3::UnitZ();  // outward unit normal
  double offset = 0;       // n . x on the plane, m
  double thickness = 0;    // m
  Vec3 u, v;               // in-plane lattice axes
  double u_min = 0, v_min = 0, u_max = 0, v_max = 0;
  std::vector<std::uint32_t> faces;
  Aabb bounds;  // of its nodes
};

// A patch's view of a point: how deep behind its plane, how far beyond its faces.
struct Claim {
  bool valid = false;
  bool extension = false;  // the point's projection lies beyond the patch's faces
  double depth = 0;        // m behind the plane
};

class Sampler {
 public:
  Sampler(const SurfaceMesh& mesh, double spacing, std::size_t layers)
      : mesh_(mesh), dx_(spacing), layers_(layers), reach_(static_cast<double>(layers) * spacing) {}

  SurfaceSampling run() {
    build_patches();
    SurfaceSampling out;
    out.spacing = dx_;
    out.layers = layers_;
    for (std::size_t a = 0; a < patches_.size(); ++a) sample_patch(a, out);
    drop_near_doubles(out);
    return out;
  }

 private:
  // Where two patches' lattices meet along a bisector without coinciding, a
  // particle of one can come arbitrarily close to one of the other: of two
  // particles of different patches closer than dx/2, the later is dropped.
  void drop_near_doubles(SurfaceSampling& out) const {
    physics::CellList grid;
    grid.build_points(position_, 0.5 * dx_);
    const double limit2 = 0.25 * dx_ * dx_ * (1 - 1e-9);
    std::vector<char> kept(out.size(), 1);
    for (std::size_t k = 0; k < out.size(); ++k) {
      grid.for_each_near(position_[k], [&](std::uint32_t j) {
        if (j < k && kept[j] && patch_of_[j] != patch_of_[k] && (position_[j] - position_[k]).squaredNorm() < limit2) {
          kept[k] = 0;
        }
      });
    }
    std::size_t n = 0;
    for (std::size_t k = 0; k < out.size(); ++k) {
      if (!kept[k]) continue;
      out.face[n] = out.face[k];
      out.weight[n] = out.weight[k];
      out.offset[n] = out.offset[k];
      out.depth[n] = out.depth[k];
      out.extension[n] = out.extension[k];
      out.partner_face[n] = out.partner_face[k];
      out.partner_weight[n] = out.partner_weight[k];
      ++n;
    }
    out.face.resize(n), out.weight.resize(n), out.offset.resize(n), out.depth.resize(n);
    out.extension.resize(n), out.partner_face.resize(n), out.partner_weight.resize(n);
  }

  void build_patches() {
    const double scale = std::max(1.0, mesh_.bounds().inflated(0).max.cwiseAbs().maxCoeff());
    for (std::uint32_t f = 0; f < mesh_.face_count(); ++f) {
      if (!(mesh_.face_area(f) > 0)) continue;  // degenerate: takes no part
      const Vec3 n = mesh_.face_normal(f);
      const double offset = n.dot(mesh_.node_position[mesh_.triangle[f][0]]);
      const double thickness = mesh_.face_thickness[f];
      auto same = [&](const Patch& p) {
        return p.n.dot(n) > 1 - 1e-12 && std::abs(p.offset - offset) <= 1e-12 * scale && p.thickness == thickness;
      };
      auto it = std::find_if(patches_.begin(), patches_.end(), same);
      if (it == patches_.end()) {
        Patch p;
        p.n = n;
        p.offset = offset;
        p.thickness = thickness;
        // Lattice axis: the global axis closest to the plane, projected onto it.
        int axis = 0;
        for (int k = 1; k < 3; ++k) {
          if (std::abs(n[k]) < std::abs(n[axis]) - 1e-12) axis = k;
        }
        const Vec3 e = Vec3::Unit(axis);
        p.u = (e - e.dot(n) * n).normalized();
        p.v = n.cross(p.u);
        patches_.push_back(p);
        it = patches_.end() - 1;
      }
      it->faces.push_back(f);
      for (auto node : mesh_.triangle[f]) it->bounds.extend(mesh_.node_position[node]);
    }
    for (auto& p : patches_) {
      p.u_min = p.v_min = std::numeric_limits<double>::infinity();
      p.u_max = p.v_max = -std::numeric_limits<double>::infinity();
      for (auto f : p.faces) {
        for (auto node : mesh_.triangle[f]) {
          const Vec3& x = mesh_.node_position[node];
          p.u_min = std::min(p.u_min, p.u.dot(x)), p.u_max = std::max(p.u_max, p.u.dot(x));
          p.v_min = std::min(p.v_min, p.v.dot(x)), p.v_max = std::max(p.v_max, p.v.dot(x));
        }
      }
    }
  }

  // Distance from x's projection on the patch's plane to the patch's faces (0: on a face).
  [[nodiscard]] double overshoot(const Patch& p, const Vec3& x) const {
    const Vec3 q = x - (p.n.dot(x) - p.offset) * p.n;
    double best = std::numeric_limits<double>::infinity();
    for (auto f : p.faces) {
      const auto& t = mesh_.triangle[f];
      const Vec3 &a = mesh_.node_position[t[0]], &b = mesh_.node_position[t[1]], &c = mesh_.node_position[t[2]];
      const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
      if (((q - lo).array() < -best).any() || ((q - hi).array() > best).any()) continue;
      best = std::min(best, (closest_on_triangle(q, a, b, c).point - q).norm());
      if (best <= on_face_tolerance()) return 0;
    }
    return best;
  }

  [[nodiscard]] double on_face_tolerance() const { return 1e-9 * dx_; }

  // n . x on the face the fluid wets: the plane itself for a solid's face, a shell's front face t/2 in front
  // of its mid-surface.
  [[nodiscard]] static double front_offset(const Patch& p) { return p.offset + 0.5 * p.thickness; }

  [[nodiscard]] Claim claim(const Patch& p, const Vec3& x) const {
    Claim c;
    if (!p.bounds.inflated(reach_ + p.thickness).contains(x)) return c;
    const double depth = front_offset(p) - p.n.dot(x);
    if (depth <= on_face_tolerance() || depth > reach_ + on_face_tolerance()) return c;
    const double o = overshoot(p, x);
    if (!(o < reach_)) return c;
    c.valid = true;
    c.extension = o > on_face_tolerance();
    c.depth = depth;
    return c;
  }

  // True when x lies in front of patch p's faces, closer than `depth`: it came
  // out through the far side of a thin solid.
  [[nodiscard]] bool crossed(const Patch& p, const Vec3& x, double depth) const {
    if (!p.bounds.inflated(depth + p.thickness).contains(x)) return false;
    const double front = p.n.dot(x) - front_offset(p);
    if (front < -on_face_tolerance() || front >= depth) return false;
    return overshoot(p, x) <= on_face_tolerance();
  }

  // Lexicographic: a face's own layers before extensions, then the nearer plane, then the lower patch.
  [[nodiscard]] bool wins(const Claim& a, std::size_t a_index, const Claim& b, std::size_t b_index) const {
    if (a.extension != b.extension) return !a.extension;
    if (std::abs(a.depth - b.depth) > on_face_tolerance()) return a.depth < b.depth;
    return a_index < b_index;
  }

  void sample_patch(std::size_t a, SurfaceSampling& out) {
    const Patch& p = patches_[a];
    const auto before = static_cast<long>(layers_);
    const auto nu = static_cast<long>(std::ceil((p.u_max - p.u_min) / dx_ - 1e-9)) + 2 * before;
    const auto nv = static_cast<long>(std::ceil((p.v_max - p.v_min) / dx_ - 1e-9)) + 2 * before;
    auto u_at = [&](long i) { return p.u_min + (static_cast<double>(i - before) + 0.5) * dx_; };
    auto v_at = [&](long j) { return p.v_min + (static_cast<double>(j - before) + 0.5) * dx_; };
    struct Cell {
      double distance = std::numeric_limits<double>::infinity();
      std::uint32_t face = 0;
      std::array<double, 3> weight{};
      Vec3 anchor = Vec3::Zero();
    };
    std::vector<Cell> cells(static_cast<std::size_t>(nu * nv));
    for (auto f : p.faces) {
      const auto& t = mesh_.triangle[f];
      const Vec3 &x0 = mesh_.node_position[t[0]], &x1 = mesh_.node_position[t[1]], &x2 = mesh_.node_position[t[2]];
      const double fu_min = std::min({p.u.dot(x0), p.u.dot(x1), p.u.dot(x2)}) - reach_;
      const double fu_max = std::max({p.u.dot(x0), p.u.dot(x1), p.u.dot(x2)}) + reach_;
      const double fv_min = std::min({p.v.dot(x0), p.v.dot(x1), p.v.dot(x2)}) - reach_;
      const double fv_max = std::max({p.v.dot(x0), p.v.dot(x1), p.v.dot(x2)}) + reach_;
      const long i0 = std::max(0L, static_cast<long>(std::floor((fu_min - p.u_min) / dx_)) + before - 1);
      const long i1 = std::min(nu - 1, static_cast<long>(std::ceil((fu_max - p.u_min) / dx_)) + before);
      const long j0 = std::max(0L, static_cast<long>(std::floor((fv_min - p.v_min) / dx_)) + before - 1);
      const long j1 = std::min(nv - 1, static_cast<long>(std::ceil((fv_max - p.v_min) / dx_)) + before);
      for (long j = j0; j <= j1; ++j) {
        for (long i = i0; i <= i1; ++i) {
          const Vec3 q = p.offset * p.n + u_at(i) * p.u + v_at(j) * p.v;
          const auto closest = closest_on_triangle(q, x0, x1, x2);
          double distance = (closest.point - q).norm();
          if (distance <= on_face_tolerance()) distance = 0;
          Cell& cell = cells[static_cast<std::size_t>(j * nu + i)];
          // Strictly nearer only: a point on an edge shared by two faces goes to the first.
          if (distance < reach_ && distance < cell.distance) {
            cell = {distance, f, closest.weight, distance == 0 ? q : closest.point};
          }
        }
      }
    }
    for (long j = 0; j < nv; ++j) {
      for (long i = 0; i < nu; ++i) {
        const Cell& cell = cells[static_cast<std::size_t>(j * nu + i)];
        if (!(cell.distance < reach_)) continue;
        const Vec3 q = p.offset * p.n + u_at(i) * p.u + v_at(j) * p.v;
        const Frame frame = face_frame(mesh_, cell.face);
        for (std::size_t k = 0; k < layers_; ++k) {
          const double depth = (static_cast<double>(k) + 0.5) * dx_;
          const Vec3 x = q + (0.5 * p.thickness - depth) * p.n;
          std::size_t partner = 0;
          if (!keep(a, x, cell.anchor, {true, cell.distance > 0, depth}, partner)) continue;
          std::uint32_t partner_face = kNoFace;
          std::array<double, 3> partner_weight{};
          if (partner < patches_.size()) nearest_face(partner, x, partner_face, partner_weight);
          out.partner_face.push_back(partner_face);
          out.partner_weight.push_back(partner_weight);
          const Vec3 d = x - cell.anchor;
          out.face.push_back(cell.face);
          out.weight.push_back(cell.weight);
          out.offset.emplace_back(d.dot(frame.e1), d.dot(frame.e2), d.dot(frame.n));
          out.depth.push_back(depth);
          out.extension.push_back(cell.distance > 0 ? 1 : 0);
          patch_of_.push_back(static_cast<std::uint32_t>(a));
          position_.push_back(x);
        }
      }
    }
  }

  // An extension of patch a anchored at `anchor` (on a's edge) fills a concave
  // corner with patch `other` when other is at an angle to a (not its opposite
  // face) and the anchor lies on other's faces too (the two meet there).
  [[nodiscard]] bool fills_corner_with(const Patch& other, std::size_t a, const Vec3& anchor) const {
    const Patch& own = patches_[a];
    if (other.n.dot(own.n) <= -1 + 1e-9) return false;
    const double tolerance = 1e-3 * dx_;
    // The wetted faces meet: a shell's front face, not its mid-surface, joins a wall standing on it.
    const Vec3 front = anchor + 0.5 * own.thickness * own.n;
    if (std::abs(other.n.dot(front) - front_offset(other)) > tolerance) return false;
    return overshoot(other, front) <= tolerance;
  }

  // Whether patch a keeps particle x; for a corner fill, `partner` becomes the
  // nearest patch it fills the corner with (its force is shared with it).
  [[nodiscard]] bool keep(std::size_t a, const Vec3& x, const Vec3& anchor, const Claim& own,
                          std::size_t& partner) const {
    partner = patches_.size();
    double partner_depth = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < patches_.size(); ++b) {
      if (b == a) continue;
      const Patch& other = patches_[b];
      if (crossed(other, x, own.depth)) return false;
      // An extension is a corner fill only if a face at an angle has it behind
      // too: the extensions of a thin solid's two opposite faces meet outside it.
      if (own.extension && crossed(other, x, reach_ + other.thickness)) return false;
      const Claim c = claim(other, x);
      if (!c.valid) continue;
      if (own.extension && c.depth < partner_depth && fills_corner_with(other, a, anchor)) {
        partner = b;
        partner_depth = c.depth;
      }
      if (!wins(own, a, c, b)) return false;
    }
    return !own.extension || partner < patches_.size();
  }

  // The face of patch b nearest to x and the barycentric weights of the nearest point.
  void nearest_face(std::size_t b, const Vec3& x, std::uint32_t& face, std::array<double, 3>& weight) const {
    double best = std::numeric_limits<double>::infinity();
    for (auto f : patches_[b].faces) {
      const auto& t = mesh_.triangle[f];
      const auto c =
          closest_on_triangle(x, mesh_.node_position[t[0]], mesh_.node_position[t[1]], mesh_.node_position[t[2]]);
      const double d = (c.point - x).squaredNorm();
      if (d < best) best = d, face = f, weight = c.weight;
    }
  }

  const SurfaceMesh& mesh_;
  double dx_;
  std::size_t layers_;
  double reach_;  // m: layers * dx
  std::vector<Patch> patches_;
  // Per sampled particle, until the near doubles are dropped.
  std::vector<std::uint32_t> patch_of_;
  std::vector<Vec3> position_;
};

}  // namespace

SurfaceSampling sample_surface(const SurfaceMesh& mesh, double spacing, std::size_t layers) {
  if (!(spacing > 0) || !std::isfinite(spacing)) {
    throw Error(fmt::format("surface sampling: the particle spacing must be > 0 m, got {}", spacing));
  }
  if (layers == 0) throw Error("surface sampling: at least one layer of boundary particles is needed");
  mesh.validate("surface to sample into boundary particles");
  return Sampler(mesh, spacing, layers).run();
}

Vec3 boundary_particle_position(const SurfaceMesh& mesh, const SurfaceSampling& sampling, std::size_t k) {
  const Frame f = face_frame(mesh, sampling.face[k]);
  const Vec3& o = sampling.offset[k];
  return anchor_of(mesh, sampling.face[k], sampling.weight[k]) + o.x() * f.e1 + o.y() * f.e2 + o.z() * f.n;
}

void place_boundary_particles(const SurfaceMesh& mesh, const SurfaceSampling& sampling,
                              std::span<const Vec3> node_velocity, std::span<const Vec3> node_acceleration,
                              std::span<const std::uint32_t> selection, physics::BoundaryParticles& out) {
  assert(node_velocity.empty() || node_velocity.size() == mesh.node_count());
  assert(node_acceleration.empty() || node_acceleration.size() == mesh.node_count());
  out.resize(selection.size());
  const double volume = sampling.particle_volume();
  for (std::size_t s = 0; s < selection.size(); ++s) {
    const std::uint32_t k = selection[s];
    const std::uint32_t face = sampling.face[k];
    const auto& t = mesh.triangle[face];
    const auto& w = sampling.weight[k];
    const Frame f = face_frame(mesh, face);
    const Vec3& o = sampling.offset[k];
    out.position[s] = anchor_of(mesh, face, w) + o.x() * f.e1 + o.y() * f.e2 + o.z() * f.n;
    out.normal[s] = f.n;
    out.velocity[s] = node_velocity.empty()
                          ? Vec3::Zero()
                          : Vec3(w[0] * node_velocity[t[0]] + w[1] * node_velocity[t[1]] + w[2] * node_velocity[t[2]]);
    out.acceleration[s] =
        node_acceleration.empty()
            ? Vec3::Zero()
            : Vec3(w[0] * node_acceleration[t[0]] + w[1] * node_acceleration[t[1]] + w[2] * node_acceleration[t[2]]);
    out.volume[s] = volume;
  }
}

std::array<Vec3, 2> split_boundary_force(const SurfaceMesh& mesh, const SurfaceSampling& sampling, std::size_t k,
                                         const Vec3& force) {
  const std::uint32_t partner = sampling.partner_face[k];
  if (partner == kNoFace) return {force, Vec3::Zero()};
  // force = alpha n_a + beta n_b + along the corner's edge; each face takes its
  // normal part and half of the rest.
  const Vec3 na = mesh.face_normal(sampling.face[k]), nb = mesh.face_normal(partner);
  const double c = na.dot(nb);
  const double det = 1 - c * c;
  if (det < 1e-6) return {force, Vec3::Zero()};
  const double fa = force.dot(na), fb = force.dot(nb);
  const double alpha = (fa - c * fb) / det, beta = (fb - c * fa) / det;
  const Vec3 rest = force - alpha * na - beta * nb;
  const Vec3 on_a = alpha * na + 0.5 * rest;
  return {on_a, force - on_a};
}

namespace {
void add_to_face(const SurfaceMesh& mesh, std::uint32_t face, const std::array<double, 3>& w, const Vec3& force,
                 std::span<double> node_force) {
  const auto& t = mesh.triangle[face];
  for (int c = 0; c < 3; ++c) {
    const double f0 = w[0] * force[c], f1 = w[1] * force[c];
    node_force[3 * t[0] + static_cast<std::size_t>(c)] += f0;
    node_force[3 * t[1] + static_cast<std::size_t>(c)] += f1;
    node_force[3 * t[2] + static_cast<std::size_t>(c)] += force[c] - f0 - f1;
  }
}
}  // namespace

void spread_boundary_forces(const SurfaceMesh& mesh, const SurfaceSampling& sampling,
                            std::span<const std::uint32_t> selection, std::span<const double> boundary_force,
                            std::span<double> node_force) {
  assert(boundary_force.size() == 3 * selection.size());
  assert(node_force.size() == 3 * mesh.node_count());
  for (std::size_t s = 0; s < selection.size(); ++s) {
    const std::uint32_t k = selection[s];
    const Vec3 force(boundary_force[3 * s], boundary_force[3 * s + 1], boundary_force[3 * s + 2]);
    const auto parts = split_boundary_force(mesh, sampling, k, force);
    add_to_face(mesh, sampling.face[k], sampling.weight[k], parts[0], node_force);
    if (sampling.partner_face[k] != kNoFace) {
      add_to_face(mesh, sampling.partner_face[k], sampling.partner_weight[k], parts[1], node_force);
    }
  }
}

void keep_particles(SurfaceSampling& sampling, const std::vector<char>& keep) {
  assert(keep.size() == sampling.size());
  std::size_t kept = 0;
  for (std::size_t k = 0; k < keep.size(); ++k) {
    if (!keep[k]) continue;
    sampling.face[kept] = sampling.face[k];
    sampling.weight[kept] = sampling.weight[k];
    sampling.offset[kept] = sampling.offset[k];
    sampling.depth[kept] = sampling.depth[k];
    sampling.extension[kept] = sampling.extension[k];
    sampling.partner_face[kept] = sampling.partner_face[k];
    sampling.partner_weight[kept] = sampling.partner_weight[k];
    ++kept;
  }
  sampling.face.resize(kept);
  sampling.weight.resize(kept);
  sampling.offset.resize(kept);
  sampling.depth.resize(kept);
  sampling.extension.resize(kept);
  sampling.partner_face.resize(kept);
  sampling.partner_weight.resize(kept);
}

}  // namespace sabo::geometry
