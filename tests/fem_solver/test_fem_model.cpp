#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <numbers>
#include <sstream>

#include "fem_solver/fem_model.hpp"
#include "libsabo/core/error.hpp"
#include "libsabo/geometry/primitives.hpp"
#include "libsabo/scene/loader.hpp"
#include "tests/fem_solver/fem_test_support.hpp"
#include "tests/support/scratch.hpp"

namespace fs = std::filesystem;
using sabo::Vec3;
using sabo::fem::FemModel;
using sabo::scene::Shape;

namespace {

using sabo::testing::scratch;

sabo::scene::Structure structure(const std::string& name, const std::string& material_name, double thickness,
                                 const Shape& shape) {
  sabo::scene::Structure s;
  s.name = name;
  s.material = material_name;
  s.thickness = thickness;
  s.shape = shape;
  s.origin = {"/scenes/test.toml", 10, "structures." + name};
  return s;
}

Shape chute_shape() {
  Shape shape;
  shape.type = Shape::Type::chute;
  shape.origin = Vec3(0, 0, 20);
  shape.direction = Vec3(1, 0, 0);
  shape.length = 40;
  shape.width = 7;
  shape.slope_deg = 20;
  shape.wall_height = 3;
  shape.end_wall_height = 2;
  shape.element_size = 2.0;  // the paper's 2.0 m channel mesh
  return shape;
}

Shape box_shape() {
  Shape shape;
  shape.type = Shape::Type::box;
  shape.box.min = Vec3(30, -2, 0);
  shape.box.max = Vec3(36, 2, 10.8);
  shape.element_size = 1.0;
  return shape;
}

// Materials sorted by name: brick = 0, concrete = 1.
sabo::scene::Scene test_scene() {
  sabo::scene::Scene scene;
  scene.materials = {sabo::fem::test::scene_material("brick", 2300, 8e9, 0.23),
                     sabo::fem::test::scene_material("concrete", 3000, 30e9, 0.24)};
  scene.structures = {structure("channel", "concrete", 0.0, chute_shape()),
                      structure("house", "brick", 0.24, box_shape())};
  return scene;
}

// The 12 triangles of the cube [0, 1]^3 as a binary STL, outward.
void write_cube_stl(const fs::path& file) {
  std::vector<std::array<Vec3, 3>> triangles;
  auto c = [](int i, int j, int k) { return Vec3(i, j, k); };
  auto quad = [&](Vec3 a, Vec3 b, Vec3 d, Vec3 e) {
    triangles.push_back({a, b, d});
    triangles.push_back({a, d, e});
  };
  quad(c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0));
  quad(c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1));
  quad(c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1));
  quad(c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0));
  quad(c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0));
  quad(c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1));
  std::string data(80, ' ');
  const auto count = static_cast<std::uint32_t>(triangles.size());
  data.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& t : triangles) {
    std::array<float, 12> values{};
    for (int corner = 0; corner < 3; ++corner) {
      for (int k = 0; k < 3; ++k) values[3 + 3 * corner + k] = static_cast<float>(t[corner][k]);
    }
    data.append(reinterpret_cast<const char*>(values.data()), sizeof values);
    data.append(2, '\0');
  }
  std::ofstream(file, std::ios::binary) << data;
}

double part_area(const FemModel& model, std::size_t part) {
  double area = 0;
  for (std::size_t f = model.part(part).face_begin; f < model.part(part).face_end; ++f) {
    area += model.surface().face_area(f);
  }
  return area;
}

Vec3 face_centroid(const sabo::geometry::SurfaceMesh& mesh, std::size_t f) {
  const auto& t = mesh.triangle[f];
  return (mesh.node_position[t[0]] + mesh.node_position[t[1]] + mesh.node_position[t[2]]) / 3.0;
}

}  // namespace

TEST(FemModel, PartBookkeeping) {
  const auto scene = test_scene();
  const FemModel model(scene);
  const auto& surface = model.surface();
  ASSERT_EQ(model.part_count(), 2u);
  EXPECT_EQ(surface.part_name, (std::vector<std::string>{"channel", "house"}));
  EXPECT_EQ(model.part(0).name, "channel");
  EXPECT_EQ(model.part(0).material, 1u);
  EXPECT_EQ(model.part(1).material, 0u);
  EXPECT_EQ(model.part(0).node_begin, 0u);
  EXPECT_EQ(model.part(0).node_end, model.part(1).node_begin);
  EXPECT_EQ(model.part(1).node_end, surface.node_count());
  EXPECT_EQ(model.part(1).face_end, surface.face_count());
  EXPECT_NO_THROW(surface.validate("model"));
  for (std::size_t i = 0; i < surface.node_count(); ++i) ASSERT_EQ(surface.node_id[i], i);

  const double k_concrete = 30e9 / (3 * (1 - 2 * 0.24));
  const double k_brick = 8e9 / (3 * (1 - 2 * 0.23));
  for (std::size_t p = 0; p < 2; ++p) {
    const auto& info = model.part(p);
    for (std::size_t f = info.face_begin; f < info.face_end; ++f) {
      ASSERT_EQ(surface.face_part[f], p);
      ASSERT_EQ(surface.face_material[f], info.material);
      ASSERT_EQ(surface.face_thickness[f], p == 0 ? 0.0 : 0.24);
      ASSERT_DOUBLE_EQ(surface.face_bulk_modulus[f], p == 0 ? k_concrete : k_brick);
      ASSERT_EQ(surface.face_element_volume[f], 0.0);
      // No triangle spans two parts.
      for (std::uint32_t node : surface.triangle[f]) {
        ASSERT_GE(node, info.node_begin);
        ASSERT_LT(node, info.node_end);
      }
    }
  }
  EXPECT_EQ(model.stable_dt(), std::numeric_limits<double>::infinity());
  const auto energies = model.energies();
  EXPECT_EQ(energies.kinetic + energies.potential + energies.elastic + energies.dissipated, 0.0);
  EXPECT_FALSE(model.moved());
  EXPECT_TRUE(model.part_model(0).rigid());
}

TEST(FemModel, ChuteAreaNormalsAndElementSize) {
  const FemModel model(test_scene());
  const double expected = 40 * 7 + 2 * 40 * 3 + 7 * 2;
  const double measured = part_area(model, 0);
  std::cout << "chute area: measured " << measured << " m^2, expected " << expected << " m^2\n";
  EXPECT_NEAR(measured, expected, 1e-9 * expected);
  EXPECT_NEAR(model.part(0).area, expected, 1e-9 * expected);

  const auto frame = sabo::geometry::chute_frame(chute_shape());
  const Vec3 origin = chute_shape().origin;
  const auto& surface = model.surface();
  double longest = 0;
  for (std::size_t f = model.part(0).face_begin; f < model.part(0).face_end; ++f) {
    // Inward: toward a point on the centre line, 1 m above the floor and
    // upstream of the end wall.
    const Vec3 c = face_centroid(surface, f);
    const double along = (c - origin).dot(frame.down_slope);
    const Vec3 inside = origin + std::clamp(along, 1.0, 39.0) * frame.down_slope + 1.0 * frame.normal;
    ASSERT_GT((inside - c).dot(surface.face_normal(f)), 0) << "face " << f;
    const auto& t = surface.triangle[f];
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (surface.node_position[t[k]] - surface.node_position[t[(k + 1) % 3]]).norm());
    }
  }
  std::cout << "chute longest edge: " << longest << " m for element size 2 m (quad diagonal bound "
            << 2 * std::sqrt(2.0) << ")\n";
  EXPECT_LE(longest, 2 * std::sqrt(2.0) * (1 + 1e-12));
  EXPECT_GT(model.part(0).face_end - model.part(0).face_begin, 2u * 20 * 4);  // floor alone: 20 x 4 quads
}

TEST(FemModel, ClosedBoxHasZeroNetAreaAndOutwardNormals) {
  const FemModel model(test_scene());
  const auto& surface = model.surface();
  const auto& house = model.part(1);
  Vec3 area_vector = Vec3::Zero();
  for (std::size_t f = house.face_begin; f < house.face_end; ++f) {
    area_vector += surface.face_area(f) * surface.face_normal(f);
    ASSERT_GT((face_centroid(surface, f) - house.centroid).dot(surface.face_normal(f)), 0) << "face " << f;
  }
  std::cout << "box net area vector: |sum n dA| = " << area_vector.norm() << " m^2 (expected 0), area " << house.area
            << " (expected " << 2 * (6 * 4 + 6 * 10.8 + 4 * 10.8) << ")\n";
  EXPECT_LT(area_vector.norm(), 1e-10);
  EXPECT_NEAR(house.area, 2 * (6 * 4 + 6 * 10.8 + 4 * 10.8), 1e-9);
  EXPECT_LT((house.centroid - Vec3(33, 0, 5.4)).norm(), 1e-12);
}

TEST(FemModel, MeshImportRoundTrip) {
  const fs::path stl = scratch("cube.stl");
  write_cube_stl(stl);
  Shape shape;
  shape.type = Shape::Type::mesh;
  shape.file = stl;
  shape.scale = 2.0;
  shape.translate = Vec3(10, 0, -1);
  auto scene = test_scene();
  scene.structures.push_back(structure("block", "concrete", 0.0, shape));
  const FemModel model(scene);
  ASSERT_EQ(model.part_count(), 3u);
  const auto& block = model.part(2);
  EXPECT_EQ(block.node_end - block.node_begin, 8u);
  EXPECT_EQ(block.face_end - block.face_begin, 12u);
  EXPECT_NEAR(block.area, 6 * 4.0, 1e-12);
  sabo::Aabb box;
  for (std::size_t i = block.node_begin; i < block.node_end; ++i) box.extend(model.surface().node_position[i]);
  EXPECT_EQ(box.min, Vec3(10, 0, -1));
  EXPECT_EQ(box.max, Vec3(12, 2, 1));
  EXPECT_EQ(model.surface().part_name[2], "block");
  for (std::size_t f = block.face_begin; f < block.face_end; ++f) {
    EXPECT_GT((face_centroid(model.surface(), f) - Vec3(11, 1, 0)).dot(model.surface().face_normal(f)), 0);
  }
  // A mesh file that does not exist names the file.
  scene.structures.back().shape.file = scratch("missing.stl");
  EXPECT_THROW(FemModel{scene}, sabo::FileError);
}

TEST(FemModel, ResultantForceAndMomentPerPart) {
  FemModel model(test_scene());
  const std::size_t nodes = model.surface().node_count();
  std::vector<double> force(3 * nodes, 0.0);
  // A horizontal push of 1 kN on every node of the house, and one 5 kN
  // vertical load on the first channel node.
  const auto& house = model.part(1);
  Vec3 expected_moment = Vec3::Zero();
  for (std::size_t i = house.node_begin; i < house.node_end; ++i) {
    force[3 * i] = 1000.0;
    expected_moment += (model.surface().node_position[i] - house.centroid).cross(Vec3(1000, 0, 0));
  }
  force[2] = -5000.0;
  model.apply_node_forces(force);
  const double house_nodes = static_cast<double>(house.node_end - house.node_begin);
  EXPECT_EQ(model.part(1).force, Vec3(1000 * house_nodes, 0, 0));
  EXPECT_LT((model.part(1).moment - expected_moment).norm(), 1e-6);
  EXPECT_EQ(model.part(0).force, Vec3(0, 0, -5000));
  const Vec3 arm = model.surface().node_position[0] - model.part(0).centroid;
  EXPECT_LT((model.part(0).moment - arm.cross(Vec3(0, 0, -5000))).norm(), 1e-9);
  std::cout << "house: force " << model.part(1).force.transpose() << " N, moment " << model.part(1).moment.transpose()
            << " N m about " << model.part(1).centroid.transpose() << "\n";
  EXPECT_EQ(model.node_forces()[0], Vec3(0, 0, -5000));

  model.apply_node_forces({});  // empty: zero everywhere
  EXPECT_EQ(model.part(1).force, Vec3::Zero());
  EXPECT_EQ(model.node_forces()[0], Vec3::Zero());
  std::vector<double> wrong(5, 0.0);
  EXPECT_THROW(model.apply_node_forces(wrong), sabo::ModelInputError);
  force[7] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(model.apply_node_forces(force), sabo::ModelInputError);

  model.step(1e-3);
  model.step(2e-3);
  EXPECT_DOUBLE_EQ(model.time(), 3e-3);
  EXPECT_FALSE(model.moved());
}

TEST(FemModel, DeformableStructuresOtherThanBoxesAreRefused) {
  auto scene = test_scene();
  scene.structures[1].rigid = false;
  scene.structures[1].shape = chute_shape();
  try {
    FemModel model(scene);
    ADD_FAILURE() << "no exception";
  } catch (const sabo::SceneError& error) {
    const std::string text = error.what();
    EXPECT_NE(text.find("/scenes/test.toml:10: structure 'house'"), std::string::npos) << text;
    EXPECT_NE(text.find("Fix: use shape = \"box\" or rigid = true"), std::string::npos) << text;
  }
}

TEST(FemModel, WritesSurfaceSeries) {
  FemModel model(test_scene());
  const fs::path run = scratch("run");
  fs::create_directories(run);
  std::vector<double> force(3 * model.surface().node_count(), 1.0);
  model.apply_node_forces(force);
  model.write_output(run, 0, 0.0);
  model.write_output(run, 250, 0.05);
  ASSERT_TRUE(fs::exists(run / "fem" / "fem_00000000.vtp"));
  ASSERT_TRUE(fs::exists(run / "fem" / "fem_00000250.vtp"));
  std::ifstream in(run / "fem" / "fem_00000250.vtp", std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  const std::string vtp = text.str();
  EXPECT_NE(vtp.find("NumberOfPoints=\"" + std::to_string(model.surface().node_count()) + "\""), std::string::npos);
  EXPECT_NE(vtp.find("NumberOfPolys=\"" + std::to_string(model.surface().face_count()) + "\""), std::string::npos);
  for (const char* name : {"node_force", "node_id", "part", "material", "thickness"}) {
    EXPECT_NE(vtp.find("Name=\"" + std::string(name) + "\""), std::string::npos) << name;
  }
  std::ifstream pvd_in(run / "fem.pvd");
  std::stringstream pvd;
  pvd << pvd_in.rdbuf();
  EXPECT_NE(pvd.str().find("timestep=\"0.05\" group=\"\" part=\"0\" file=\"fem/fem_00000250.vtp\""), std::string::npos)
      << pvd.str();
  EXPECT_NE(pvd.str().find("file=\"fem/fem_00000000.vtp\""), std::string::npos);
}

// A slit dam from the scene (loader and schema keys slit_*): the mesh has the
// slits exactly (node lines on their edges), its mass is that of the box less
// the slits, the surface carries the slits' floors, and the FEM model reports
// the node masses of the deformable surface for the coupler's stable dt.
TEST(FemModel, SlitDamFromTheScene) {
  const fs::path file = scratch("slit_dam.toml");
  {
    std::ofstream out(file);
    out << "format_version = 1\n[run]\nend_time = 1.0\noutput_interval = 0.1\n"
           "[materials.concrete]\ndensity = 2300.0\nyoungs_modulus = 8e9\npoisson_ratio = 0.23\n"
           "[[structures]]\nname = \"dam\"\nmaterial = \"concrete\"\nrigid = false\nshape = \"box\"\n"
           "min = [0.0, 0.0, 0.0]\nmax = [6.0, 2.0, 4.0]\nelement_size = 0.5\nfixed = [\"z-\"]\n"
           "slit_count = 2\nslit_width = 1.0\nslit_depth = 2.0\nslit_axis = \"y\"\n";
  }
  const sabo::scene::Scene scene = sabo::scene::load_scene(file);
  ASSERT_EQ(scene.structures.size(), 1u);
  EXPECT_EQ(scene.structures[0].slit_count, 2u);
  EXPECT_EQ(scene.structures[0].slit_axis, 1);
  FemModel model(scene);
  const auto* solid = model.deformable(0)->solid();
  ASSERT_NE(solid, nullptr);
  // Piers (6 - 2 x 1) / 3 = 1.333 m: 3 elements each, slits 2, so 13 x 4 x 8 less 2 x (2 x 4 x 4).
  EXPECT_EQ(solid->element_count(), 13u * 4u * 8u - 64u);
  const double expected_mass = 2300.0 * (6.0 * 2.0 * 4.0 - 2 * (1.0 * 2.0 * 2.0));
  std::cout << "slit dam mass: measured " << solid->total_mass() << " kg expected " << expected_mass << " kg\n";
  EXPECT_NEAR(solid->total_mass(), expected_mass, 1e-9 * expected_mass);
  const double pier = 4.0 / 3.0;
  std::vector<sabo::Aabb> slits;
  for (int k = 0; k < 2; ++k) {
    const double x0 = (k + 1) * pier + k * 1.0;
    slits.push_back(sabo::Aabb{Vec3(x0, 0, 2), Vec3(x0 + 1.0, 2, 4)});
  }
  for (std::size_t e = 0; e < solid->element_count(); ++e) {
    Vec3 centre = Vec3::Zero();
    for (auto n : solid->mesh().element[e]) centre += solid->reference_positions()[n] / 8.0;
    for (const auto& slit : slits) ASSERT_FALSE(slit.contains(centre)) << "element " << e << " inside a slit";
  }
  // The slits' floors (z = 2, inside the slits, facing up) are on the contact surface.
  const auto& surface = model.surface();
  double floor_area = 0;
  for (std::size_t f = 0; f < surface.face_count(); ++f) {
    const auto& t = surface.triangle[f];
    const Vec3 c = (surface.node_position[t[0]] + surface.node_position[t[1]] + surface.node_position[t[2]]) / 3.0;
    if (std::abs(c.z() - 2.0) < 1e-9 && surface.face_normal(f).z() > 0.999) floor_area += surface.face_area(f);
  }
  std::cout << "slit floor area on the surface: measured " << floor_area << " m^2 expected 4 m^2\n";
  EXPECT_NEAR(floor_area, 2 * 1.0 * 2.0, 1e-9);
  // Node masses travel with the surface (eq. 7's contact term), their sum at most the dam's mass.
  ASSERT_EQ(surface.node_mass.size(), surface.node_count());
  double surface_mass = 0;
  for (double m : surface.node_mass) {
    EXPECT_GT(m, 0.0);
    surface_mass += m;
  }
  EXPECT_LT(surface_mass, solid->total_mass());
}
