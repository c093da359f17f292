#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/surface_mesh.hpp"
#include "libsabo/io/vtk.hpp"
#include "tests/support/scratch.hpp"

namespace fs = std::filesystem;
using namespace sabo::io;
using sabo::Vec3;

namespace {

using sabo::testing::scratch;

std::string slurp(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

std::string attribute(const std::string& tag, const std::string& name) {
  const std::string key = " " + name + "=\"";
  const auto start = tag.find(key);
  if (start == std::string::npos) return {};
  const auto begin = start + key.size();
  return tag.substr(begin, tag.find('"', begin) - begin);
}

std::vector<std::uint8_t> base64_decode(const std::string& text) {
  static const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::vector<std::uint8_t> out;
  std::uint32_t word = 0;
  int bits = 0;
  for (char c : text) {
    if (c == '=' || std::isspace(static_cast<unsigned char>(c))) continue;
    const auto value = alphabet.find(c);
    EXPECT_NE(value, std::string::npos) << "bad base64 character " << c;
    word = (word << 6) | static_cast<std::uint32_t>(value);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>((word >> bits) & 0xff));
    }
  }
  return out;
}

// A minimal reader of what the writer produces: finds the DataArray named
// `name` (the `occurrence`-th one) and decodes its values, whatever the encoding.
struct Decoded {
  std::string type;
  int components = 0;
  std::vector<double> values;  // converted for comparison
};

template <class T>
void convert(const std::uint8_t* data, std::size_t bytes, std::vector<double>& out) {
  for (std::size_t i = 0; i < bytes / sizeof(T); ++i) {
    T value;
    std::memcpy(&value, data + i * sizeof(T), sizeof(T));
    out.push_back(static_cast<double>(value));
  }
}

Decoded decode(const std::string& file, const std::string& name, int occurrence = 0) {
  Decoded result;
  std::size_t at = 0;
  for (int i = 0; i <= occurrence; ++i) {
    at = file.find("Name=\"" + name + "\"", at + 1);
    if (at == std::string::npos) {
      ADD_FAILURE() << "no DataArray named " << name;
      return result;
    }
  }
  const auto tag_begin = file.rfind("<DataArray", at);
  const auto tag_end = file.find('>', at);
  const std::string tag = file.substr(tag_begin, tag_end - tag_begin + 1);
  result.type = attribute(tag, "type");
  result.components = std::stoi(attribute(tag, "NumberOfComponents"));
  const std::string format = attribute(tag, "format");
  std::vector<std::uint8_t> raw;
  if (format == "ascii") {
    const auto end = file.find("</DataArray>", tag_end);
    std::istringstream values(file.substr(tag_end + 1, end - tag_end - 1));
    double value = 0;
    while (values >> value) result.values.push_back(value);
    return result;
  }
  if (format == "binary") {
    const auto end = file.find("</DataArray>", tag_end);
    raw = base64_decode(file.substr(tag_end + 1, end - tag_end - 1));
  } else {
    EXPECT_EQ(format, "appended");
    const auto section = file.find("<AppendedData encoding=\"raw\">");
    EXPECT_NE(section, std::string::npos);
    const auto base = file.find('_', section) + 1;
    const auto offset = base + std::stoull(attribute(tag, "offset"));
    std::uint64_t size = 0;
    std::memcpy(&size, file.data() + offset, 8);
    raw.assign(file.begin() + static_cast<std::ptrdiff_t>(offset),
               file.begin() + static_cast<std::ptrdiff_t>(offset + 8 + size));
  }
  std::uint64_t size = 0;
  std::memcpy(&size, raw.data(), 8);
  EXPECT_EQ(size + 8, raw.size()) << name << ": header says " << size << " bytes";
  const std::uint8_t* data = raw.data() + 8;
  if (result.type == "Float64") convert<double>(data, size, result.values);
  if (result.type == "Int64") convert<std::int64_t>(data, size, result.values);
  if (result.type == "UInt64") convert<std::uint64_t>(data, size, result.values);
  if (result.type == "UInt32") convert<std::uint32_t>(data, size, result.values);
  if (result.type == "UInt8") convert<std::uint8_t>(data, size, result.values);
  return result;
}

std::vector<double> flatten(const std::vector<Vec3>& points) {
  std::vector<double> out;
  for (const auto& p : points) out.insert(out.end(), {p.x(), p.y(), p.z()});
  return out;
}

class VtkEncodings : public ::testing::TestWithParam<vtk::Encoding> {};

}  // namespace

TEST_P(VtkEncodings, ParticlesRoundTrip) {
  const std::vector<Vec3> points{{0, 0, 0}, {1.5, -2, 3e-7}, {1e10, 0.1, -0.3}};
  const std::vector<double> radius{0.1, 0.2, 0.30000000000000004};
  const std::vector<Vec3> velocity{{1, 2, 3}, {4, 5, 6}, {-7, -8, -9}};
  const std::vector<std::uint64_t> id{7, 1ull << 40, 9};
  const std::vector<vtk::Array> arrays{vtk::Array::scalars("radius", radius), vtk::Array::vectors("velocity", velocity),
                                       vtk::Array::of<std::uint64_t>("id", id)};
  const fs::path file = scratch("particles.vtp");
  vtk::write_points(file, points, arrays, {GetParam()});
  EXPECT_FALSE(fs::exists(fs::path(file.string() + ".tmp")));
  const std::string text = slurp(file);
  EXPECT_EQ(text.rfind("<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\"", 0), 0u);
  EXPECT_NE(text.find("NumberOfPoints=\"3\" NumberOfVerts=\"3\""), std::string::npos);
  EXPECT_NE(text.find("header_type=\"UInt64\""), std::string::npos);

  const auto decoded_points = decode(text, "Points");
  EXPECT_EQ(decoded_points.type, "Float64");
  EXPECT_EQ(decoded_points.components, 3);
  EXPECT_EQ(decoded_points.values, flatten(points));
  EXPECT_EQ(decode(text, "radius").values, radius);
  EXPECT_EQ(decode(text, "velocity").values, flatten(velocity));
  const auto decoded_id = decode(text, "id");
  EXPECT_EQ(decoded_id.type, "UInt64");
  EXPECT_EQ(decoded_id.values, (std::vector<double>{7, static_cast<double>(1ull << 40), 9}));
  EXPECT_EQ(decode(text, "connectivity").values, (std::vector<double>{0, 1, 2}));
  EXPECT_EQ(decode(text, "offsets").values, (std::vector<double>{1, 2, 3}));
}

TEST_P(VtkEncodings, SurfaceAndGridRoundTrip) {
  sabo::geometry::SurfaceMesh mesh;
  mesh.node_position = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh.triangle = {{0, 1, 2}, {0, 2, 3}};
  const std::vector<double> force{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  const std::vector<std::uint32_t> part{0, 1};
  const std::vector<vtk::Array> point_data{vtk::Array::vectors("force", force)};
  const std::vector<vtk::Array> cell_data{vtk::Array::of<std::uint32_t>("part", part)};
  const fs::path surface = scratch("surface.vtp");
  vtk::write_surface(surface, mesh, point_data, cell_data, {GetParam()});
  const std::string text = slurp(surface);
  EXPECT_NE(text.find("NumberOfPoints=\"4\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" "
                      "NumberOfPolys=\"2\""),
            std::string::npos);
  EXPECT_EQ(decode(text, "connectivity").values, (std::vector<double>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(decode(text, "offsets").values, (std::vector<double>{3, 6}));
  EXPECT_EQ(decode(text, "force").values, force);
  EXPECT_EQ(decode(text, "part").values, (std::vector<double>{0, 1}));
  EXPECT_NE(text.find("<CellData>"), std::string::npos);

  // One hexahedron and one quad.
  std::vector<Vec3> points;
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 2; ++j) {
      for (int i = 0; i < 2; ++i) points.emplace_back(i ^ j, j, k);
    }
  }
  const std::vector<std::int64_t> connectivity{0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 5, 4};
  const std::vector<std::int64_t> offsets{8, 12};
  const std::vector<vtk::CellType> types{vtk::CellType::hexahedron, vtk::CellType::quad};
  const std::vector<double> pressure{1.0, 2.0};
  const std::vector<vtk::Array> grid_cell_data{vtk::Array::scalars("pressure", pressure)};
  const fs::path grid = scratch("grid.vtu");
  vtk::write_unstructured(grid, points, connectivity, offsets, types, {}, grid_cell_data, {GetParam()});
  const std::string grid_text = slurp(grid);
  EXPECT_NE(grid_text.find("<VTKFile type=\"UnstructuredGrid\""), std::string::npos);
  EXPECT_NE(grid_text.find("NumberOfPoints=\"8\" NumberOfCells=\"2\""), std::string::npos);
  EXPECT_EQ(decode(grid_text, "types").values, (std::vector<double>{12, 9}));
  EXPECT_EQ(decode(grid_text, "offsets").values, (std::vector<double>{8, 12}));
  EXPECT_EQ(decode(grid_text, "connectivity").values.size(), 12u);
  EXPECT_EQ(decode(grid_text, "pressure").values, pressure);
}

INSTANTIATE_TEST_SUITE_P(Encodings, VtkEncodings,
                         ::testing::Values(vtk::Encoding::appended_raw, vtk::Encoding::base64, vtk::Encoding::ascii));

TEST(Vtk, RejectsInconsistentArrays) {
  const std::vector<Vec3> points{{0, 0, 0}, {1, 0, 0}};
  const std::vector<double> too_short{1.0};
  const std::vector<vtk::Array> arrays{vtk::Array::scalars("radius", too_short)};
  EXPECT_THROW(vtk::write_points(scratch("bad.vtp"), points, arrays), std::logic_error);
  EXPECT_THROW(vtk::write_points(scratch("no_such_folder") / "x.vtp", points, {}), sabo::Error);
}

TEST(Vtk, BinaryIsCompact) {
  std::vector<Vec3> points(10000, Vec3(0.1, 0.2, 0.3));
  std::vector<double> radius(points.size(), 0.05);
  const std::vector<vtk::Array> arrays{vtk::Array::scalars("radius", radius)};
  vtk::write_points(scratch("big.vtp"), points, arrays);
  vtk::write_points(scratch("big_ascii.vtp"), points, arrays, {vtk::Encoding::ascii});
  const auto binary = fs::file_size(scratch("big.vtp"));
  const auto payload = points.size() * (3 * 8 + 8 + 8 + 8);  // points, radius, connectivity, offsets
  std::cout << "10000 particles: binary " << binary << " bytes (payload " << payload << "), ascii "
            << fs::file_size(scratch("big_ascii.vtp")) << " bytes\n";
  EXPECT_LT(binary, payload + 2000);
}

TEST(Vtk, TimeSeriesStaysValid) {
  const fs::path pvd = scratch("series/fem.pvd");
  fs::create_directories(pvd.parent_path());
  vtk::TimeSeries series(pvd);
  series.add(0.0, pvd.parent_path() / "fem" / "fem_000000.vtp");  // absolute: stored relative
  const std::string first = slurp(pvd);
  EXPECT_NE(first.find("<DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"fem/fem_000000.vtp\"/>"),
            std::string::npos)
      << first;
  EXPECT_NE(first.find("</VTKFile>"), std::string::npos);
  series.add(0.125, "fem/fem_000010.vtp");
  const std::string second = slurp(pvd);
  EXPECT_NE(second.find("timestep=\"0.125\" group=\"\" part=\"0\" file=\"fem/fem_000010.vtp\""), std::string::npos);
  EXPECT_EQ(series.size(), 2u);
  EXPECT_EQ(second.find("<Collection>"), second.rfind("<Collection>"));
  EXPECT_FALSE(fs::exists(fs::path(pvd.string() + ".tmp")));
}
