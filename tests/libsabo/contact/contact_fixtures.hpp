#pragma once
// Meshes and particle clouds for the particle-surface contact tests.
#include <cstdint>
#include <string>
#include <vector>

#include "libsabo/contact/surface_contact.hpp"

namespace sabo::contact::test {

// Builds a SurfaceMesh triangle by triangle.
class MeshBuilder {
 public:
  std::uint32_t part(const std::string& name) {
    mesh_.part_name.push_back(name);
    return static_cast<std::uint32_t>(mesh_.part_name.size() - 1);
  }
  std::uint32_t node(const Vec3& p) {
    mesh_.node_id.push_back(1000 + mesh_.node_position.size());
    mesh_.node_position.push_back(p);
    return static_cast<std::uint32_t>(mesh_.node_position.size() - 1);
  }
  // Counter-clockwise seen from the outward side.
  void triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t part, double thickness = 0,
                double bulk_modulus = 1e9, double element_volume = 0) {
    mesh_.triangle.push_back({a, b, c});
    mesh_.face_part.push_back(part);
    mesh_.face_material.push_back(0);
    mesh_.face_thickness.push_back(thickness);
    mesh_.face_bulk_modulus.push_back(bulk_modulus);
    mesh_.face_element_volume.push_back(element_volume);
  }
  // With its own three nodes (in the order a, b, c).
  void triangle(const Vec3& a, const Vec3& b, const Vec3& c, std::uint32_t part, double thickness = 0) {
    const std::uint32_t ia = node(a);
    const std::uint32_t ib = node(b);
    const std::uint32_t ic = node(c);
    triangle(ia, ib, ic, part, thickness);
  }
  // Flat quad grid in the plane z = z0 (outward +z), nx * ny squares of side
  // `spacing` from `origin`, each split along alternating diagonals.
  void grid(const Vec3& origin, int nx, int ny, double spacing, std::uint32_t part, double thickness = 0) {
    std::vector<std::uint32_t> ids;
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) ids.push_back(node(origin + Vec3(i * spacing, j * spacing, 0)));
    }
    auto at = [&](int i, int j) { return ids[static_cast<std::size_t>(j * (nx + 1) + i)]; };
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        if ((i + j) % 2 == 0) {
          triangle(at(i, j), at(i + 1, j), at(i + 1, j + 1), part, thickness);
          triangle(at(i, j), at(i + 1, j + 1), at(i, j + 1), part, thickness);
        } else {
          triangle(at(i, j), at(i + 1, j), at(i, j + 1), part, thickness);
          triangle(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1), part, thickness);
        }
      }
    }
  }
  // Closed box [lo, hi], outward normals, two triangles per side.
  void box(const Vec3& lo, const Vec3& hi, std::uint32_t part, double element_volume = 0) {
    std::uint32_t v[8];
    for (int k = 0; k < 8; ++k) {
      v[k] = node(Vec3((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(), (k & 4) ? hi.z() : lo.z()));
    }
    const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
      triangle(v[q[0]], v[q[1]], v[q[2]], part, 0, 1e9, element_volume);
      triangle(v[q[0]], v[q[2]], v[q[3]], part, 0, 1e9, element_volume);
    }
  }
  [[nodiscard]] const geometry::SurfaceMesh& mesh() const { return mesh_; }
  geometry::SurfaceMesh& mesh() { return mesh_; }

 private:
  geometry::SurfaceMesh mesh_;
};

// Particles as structure of arrays.
struct Cloud {
  std::vector<std::uint64_t> id;
  std::vector<double> position, velocity, spin, radius, mass;
  std::vector<std::uint32_t> body;

  void add(const Vec3& p, double r, double m = 10.0, const Vec3& v = Vec3::Zero(), const Vec3& w = Vec3::Zero(),
           std::uint32_t source = 0) {
    id.push_back(7 + 3 * id.size());
    for (int k = 0; k < 3; ++k) {
      position.push_back(p[k]);
      velocity.push_back(v[k]);
      spin.push_back(w[k]);
    }
    radius.push_back(r);
    mass.push_back(m);
    body.push_back(source);
  }
  [[nodiscard]] std::size_t size() const { return id.size(); }
  void move(std::size_t i, const Vec3& p) {
    for (int k = 0; k < 3; ++k) position[3 * i + static_cast<std::size_t>(k)] = p[k];
  }
  [[nodiscard]] Vec3 at(std::size_t i) const { return {position[3 * i], position[3 * i + 1], position[3 * i + 2]}; }
  [[nodiscard]] ParticleView view() const {
    ParticleView v;
    v.id = id;
    v.position = position;
    v.velocity = velocity;
    v.angular_velocity = spin;
    v.radius = radius;
    v.mass = mass;
    v.body = body;
    return v;
  }
};

inline Vec3 vec_at(const std::vector<double>& values, std::size_t i) {
  return {values[3 * i], values[3 * i + 1], values[3 * i + 2]};
}

// Same settings for every pair.
inline SurfaceContact::PairSettings uniform(const scene::SurfaceContact& settings) {
  return [settings](const std::string&, const std::string&) { return settings; };
}

inline scene::SurfaceContact explicit_stiffness(double k, double friction = 0.0) {
  scene::SurfaceContact s;
  s.normal_stiffness = k;
  s.friction = friction;
  return s;
}

}  // namespace sabo::contact::test
