#include "libsabo/io/vtk.hpp"

#include <fmt/format.h>

#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <numeric>
#include <stdexcept>

#include "libsabo/core/error.hpp"
#include "libsabo/geometry/surface_mesh.hpp"

namespace sabo::io::vtk {

static_assert(std::endian::native == std::endian::little, "the VTK writer declares byte_order=\"LittleEndian\"");
static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 arrays are written as packed doubles");

namespace {

struct Bytes {
  const void* data = nullptr;
  std::size_t size = 0;  // bytes
};

Bytes bytes_of(const Array::Values& values) {
  return std::visit(
      [](auto span) {
        return Bytes{static_cast<const void*>(span.data()), span.size() * sizeof(typename decltype(span)::value_type)};
      },
      values);
}

std::size_t value_count(const Array::Values& values) {
  return std::visit([](auto span) { return span.size(); }, values);
}

std::string escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

constexpr char kBase64Alphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

void append_base64(std::string& out, std::span<const std::uint8_t> data) {
  std::size_t i = 0;
  for (; i + 3 <= data.size(); i += 3) {
    const std::uint32_t word = (std::uint32_t{data[i]} << 16) | (std::uint32_t{data[i + 1]} << 8) | data[i + 2];
    out += kBase64Alphabet[(word >> 18) & 63];
    out += kBase64Alphabet[(word >> 12) & 63];
    out += kBase64Alphabet[(word >> 6) & 63];
    out += kBase64Alphabet[word & 63];
  }
  const std::size_t rest = data.size() - i;
  if (rest > 0) {
    std::uint32_t word = std::uint32_t{data[i]} << 16;
    if (rest == 2) word |= std::uint32_t{data[i + 1]} << 8;
    out += kBase64Alphabet[(word >> 18) & 63];
    out += kBase64Alphabet[(word >> 12) & 63];
    out += rest == 2 ? kBase64Alphabet[(word >> 6) & 63] : '=';
    out += '=';
  }
}

// One VTK XML file being assembled: the XML text, and the blocks of the
// appended section (written straight from the caller's memory).
class Document {
 public:
  explicit Document(const Options& options, const char* type) : options_(options) {
    xml_ = fmt::format(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"{}\" version=\"1.0\" byte_order=\"LittleEndian\" "
        "header_type=\"UInt64\">\n",
        type);
  }

  void text(const std::string& line) { xml_ += line; }

  void data_array(const Array& array, std::size_t expected_tuples, const char* indent) {
    const std::size_t count = value_count(array.values);
    if (array.components == 0 || count != expected_tuples * array.components) {
      throw std::logic_error(fmt::format("VTK array '{}': {} values for {} tuples of {} components", array.name, count,
                                         expected_tuples, array.components));
    }
    xml_ += fmt::format("{}<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" ", indent, array.vtk_type(),
                        escape(array.name), array.components);
    const Bytes bytes = bytes_of(array.values);
    switch (options_.encoding) {
      case Encoding::appended_raw:
        xml_ += fmt::format("format=\"appended\" offset=\"{}\"/>\n", appended_size_);
        blocks_.push_back(bytes);
        appended_size_ += sizeof(std::uint64_t) + bytes.size;
        break;
      case Encoding::base64: {
        xml_ += "format=\"binary\">\n";
        // One base64 stream of the UInt64 byte count followed by the data, as VTK writes it.
        std::vector<std::uint8_t> raw(sizeof(std::uint64_t) + bytes.size);
        const std::uint64_t header = bytes.size;
        std::memcpy(raw.data(), &header, sizeof header);
        if (bytes.size > 0) std::memcpy(raw.data() + sizeof header, bytes.data, bytes.size);
        xml_ += indent;
        xml_ += "  ";
        append_base64(xml_, raw);
        xml_ += fmt::format("\n{}</DataArray>\n", indent);
        break;
      }
      case Encoding::ascii:
        xml_ += "format=\"ascii\">\n";
        xml_ += indent;
        xml_ += " ";
        std::visit(
            [&](auto span) {
              for (auto value : span) {
                if constexpr (sizeof(value) == 1) {
                  fmt::format_to(std::back_inserter(xml_), " {}", static_cast<unsigned>(value));
                } else {
                  fmt::format_to(std::back_inserter(xml_), " {}", value);
                }
              }
            },
            array.values);
        xml_ += fmt::format("\n{}</DataArray>\n", indent);
        break;
    }
  }

  void arrays(const char* element, std::span<const Array> arrays, std::size_t tuples) {
    if (arrays.empty()) return;
    xml_ += fmt::format("      <{}>\n", element);
    for (const auto& array : arrays) data_array(array, tuples, "        ");
    xml_ += fmt::format("      </{}>\n", element);
  }

  void write(const std::filesystem::path& file) {
    std::filesystem::path temporary = file;
    temporary += ".tmp";
    {
      std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
      if (!out) {
        throw FileError(fmt::format("{}: cannot write: {}. Fix: check that the folder exists and is writable",
                                    temporary.string(), std::strerror(errno)));
      }
      out.write(xml_.data(), static_cast<std::streamsize>(xml_.size()));
      if (options_.encoding == Encoding::appended_raw) {
        out << "  <AppendedData encoding=\"raw\">\n   _";
        for (const Bytes& block : blocks_) {
          const std::uint64_t header = block.size;
          out.write(reinterpret_cast<const char*>(&header), sizeof header);
          out.write(static_cast<const char*>(block.data), static_cast<std::streamsize>(block.size));
        }
        out << "\n  </AppendedData>\n";
      }
      out << "</VTKFile>\n";
      out.flush();
      if (!out) {
        throw FileError(
            fmt::format("{}: write failed: {}. Fix: check free disk space", temporary.string(), std::strerror(errno)));
      }
    }
    std::error_code error;
    std::filesystem::rename(temporary, file, error);
    if (error) {
      throw FileError(fmt::format("{}: cannot rename to {}: {}", temporary.string(), file.string(), error.message()));
    }
  }

 private:
  Options options_;
  std::string xml_;
  std::vector<Bytes> blocks_;
  std::uint64_t appended_size_ = 0;
};

std::span<const double> flat(std::span<const Vec3> points) {
  return {points.empty() ? nullptr : points.data()->data(), points.size() * 3};
}

void points_element(Document& document, std::span<const Vec3> points) {
  document.text("      <Points>\n");
  document.data_array(Array::vectors("Points", points), points.size(), "        ");
  document.text("      </Points>\n");
}

void cell_block(Document& document, const char* element, std::span<const std::int64_t> connectivity,
                std::span<const std::int64_t> offsets, std::size_t cells) {
  document.text(fmt::format("      <{}>\n", element));
  document.data_array(Array::of<std::int64_t>("connectivity", connectivity), connectivity.size(), "        ");
  document.data_array(Array::of<std::int64_t>("offsets", offsets), cells, "        ");
  document.text(fmt::format("      </{}>\n", element));
}

}  // namespace

std::size_t Array::tuples() const {
  return components == 0 ? 0 : value_count(values) / components;
}

const char* Array::vtk_type() const {
  struct Name {
    const char* operator()(std::span<const double>) const { return "Float64"; }
    const char* operator()(std::span<const float>) const { return "Float32"; }
    const char* operator()(std::span<const std::int64_t>) const { return "Int64"; }
    const char* operator()(std::span<const std::uint64_t>) const { return "UInt64"; }
    const char* operator()(std::span<const std::int32_t>) const { return "Int32"; }
    const char* operator()(std::span<const std::uint32_t>) const { return "UInt32"; }
    const char* operator()(std::span<const std::uint8_t>) const { return "UInt8"; }
  };
  return std::visit(Name{}, values);
}

Array Array::vectors(std::string name, std::span<const Vec3> values) {
  return {std::move(name), 3, flat(values)};
}

void write_points(const std::filesystem::path& file, std::span<const Vec3> points, std::span<const Array> point_data,
                  const Options& options) {
  const std::size_t n = points.size();
  std::vector<std::int64_t> connectivity(n);
  std::iota(connectivity.begin(), connectivity.end(), std::int64_t{0});
  std::vector<std::int64_t> offsets(n);
  std::iota(offsets.begin(), offsets.end(), std::int64_t{1});
  Document document(options, "PolyData");
  document.text("  <PolyData>\n");
  document.text(
      fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfVerts=\"{}\" NumberOfLines=\"0\" "
                  "NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n",
                  n, n));
  points_element(document, points);
  cell_block(document, "Verts", connectivity, offsets, n);
  document.arrays("PointData", point_data, n);
  document.text("    </Piece>\n  </PolyData>\n");
  document.write(file);
}

void write_surface(const std::filesystem::path& file, std::span<const Vec3> points,
                   std::span<const std::array<std::uint32_t, 3>> triangles, std::span<const Array> point_data,
                   std::span<const Array> cell_data, const Options& options) {
  const std::size_t faces = triangles.size();
  std::vector<std::int64_t> connectivity;
  connectivity.reserve(3 * faces);
  for (const auto& triangle : triangles) {
    for (std::uint32_t node : triangle) {
      if (node >= points.size()) {
        throw std::logic_error(
            fmt::format("VTK surface: node {} of a triangle is not one of the {} points", node, points.size()));
      }
      connectivity.push_back(node);
    }
  }
  std::vector<std::int64_t> offsets(faces);
  for (std::size_t i = 0; i < faces; ++i) offsets[i] = static_cast<std::int64_t>(3 * (i + 1));
  Document document(options, "PolyData");
  document.text("  <PolyData>\n");
  document.text(
      fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" "
                  "NumberOfStrips=\"0\" NumberOfPolys=\"{}\">\n",
                  points.size(), faces));
  points_element(document, points);
  cell_block(document, "Polys", connectivity, offsets, faces);
  document.arrays("PointData", point_data, points.size());
  document.arrays("CellData", cell_data, faces);
  document.text("    </Piece>\n  </PolyData>\n");
  document.write(file);
}

void write_surface(const std::filesystem::path& file, const geometry::SurfaceMesh& mesh,
                   std::span<const Array> point_data, std::span<const Array> cell_data, const Options& options) {
  write_surface(file, mesh.node_position, mesh.triangle, point_data, cell_data, options);
}

void write_unstructured(const std::filesystem::path& file, std::span<const Vec3> points,
                        std::span<const std::int64_t> connectivity, std::span<const std::int64_t> offsets,
                        std::span<const CellType> types, std::span<const Array> point_data,
                        std::span<const Array> cell_data, const Options& options) {
  const std::size_t cells = types.size();
  if (offsets.size() != cells || (cells > 0 && offsets.back() != static_cast<std::int64_t>(connectivity.size()))) {
    throw std::logic_error(fmt::format("VTK grid: {} cell types, {} offsets (last {}), {} connectivity entries", cells,
                                       offsets.size(), offsets.empty() ? 0 : offsets.back(), connectivity.size()));
  }
  Document document(options, "UnstructuredGrid");
  document.text("  <UnstructuredGrid>\n");
  document.text(fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", points.size(), cells));
  points_element(document, points);
  document.text("      <Cells>\n");
  document.data_array(Array::of<std::int64_t>("connectivity", connectivity), connectivity.size(), "        ");
  document.data_array(Array::of<std::int64_t>("offsets", offsets), cells, "        ");
  const std::span<const std::uint8_t> type_codes(reinterpret_cast<const std::uint8_t*>(types.data()), cells);
  document.data_array(Array::of<std::uint8_t>("types", type_codes), cells, "        ");
  document.text("      </Cells>\n");
  document.arrays("PointData", point_data, points.size());
  document.arrays("CellData", cell_data, cells);
  document.text("    </Piece>\n  </UnstructuredGrid>\n");
  document.write(file);
}

void write_file_atomically(const std::filesystem::path& file, const std::string& text) {
  std::filesystem::path temporary = file;
  temporary += ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.flush();
    if (!out) {
      throw FileError(fmt::format("{}: cannot write: {}. Fix: check that the folder exists and is writable",
                                  temporary.string(), std::strerror(errno)));
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, file, error);
  if (error) {
    throw FileError(fmt::format("{}: cannot rename to {}: {}", temporary.string(), file.string(), error.message()));
  }
}

TimeSeries::TimeSeries(std::filesystem::path pvd_file) : path_(std::move(pvd_file)) {}

void TimeSeries::add(double time, const std::filesystem::path& data_file) {
  std::filesystem::path stored = data_file;
  if (data_file.is_absolute()) {
    stored = data_file.lexically_relative(std::filesystem::absolute(path_).parent_path());
  }
  entries_.push_back({time, stored.generic_string()});
  std::string text =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
      "  <Collection>\n";
  for (const auto& entry : entries_) {
    text += fmt::format("    <DataSet timestep=\"{}\" group=\"\" part=\"0\" file=\"{}\"/>\n", entry.time,
                        escape(entry.file));
  }
  text += "  </Collection>\n</VTKFile>\n";
  write_file_atomically(path_, text);
}

}  // namespace sabo::io::vtk
