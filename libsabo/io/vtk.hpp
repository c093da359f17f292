#pragma once
// ParaView output: VTK XML files (.vtp PolyData for particles and triangle
// surfaces, .vtu UnstructuredGrid for volume meshes) and .pvd time series.
// Binary by default (appended raw data, UInt64 headers, little endian); base64
// inline binary and ASCII (for debugging) on request. Every file is written to
// a temporary name and renamed, so a reader never sees half a file.
#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "libsabo/core/types.hpp"

namespace sabo::geometry {
struct SurfaceMesh;
}

namespace sabo::io::vtk {

enum class Encoding { appended_raw, base64, ascii };

struct Options {
  Encoding encoding = Encoding::appended_raw;
};

// A named array of tuples of `components` values, borrowed from the caller
// (nothing is copied; the values must outlive the write call).
struct Array {
  using Values = std::variant<std::span<const double>, std::span<const float>, std::span<const std::int64_t>,
                              std::span<const std::uint64_t>, std::span<const std::int32_t>,
                              std::span<const std::uint32_t>, std::span<const std::uint8_t>>;
  std::string name;
  std::uint32_t components = 1;
  Values values;

  [[nodiscard]] std::size_t tuples() const;
  [[nodiscard]] const char* vtk_type() const;  // "Float64", "UInt64", ...

  static Array scalars(std::string name, std::span<const double> values) { return {std::move(name), 1, values}; }
  static Array vectors(std::string name, std::span<const Vec3> values);
  // 3 values per tuple, x0 y0 z0 x1 ...
  static Array vectors(std::string name, std::span<const double> xyz) { return {std::move(name), 3, xyz}; }
  template <class T>
  static Array of(std::string name, std::span<const T> values, std::uint32_t components = 1) {
    return {std::move(name), components, values};
  }
};

enum class CellType : std::uint8_t { vertex = 1, triangle = 5, quad = 9, tetra = 10, hexahedron = 12 };

// Particles: points with a vertex cell each, and per-point arrays.
void write_points(const std::filesystem::path& file, std::span<const Vec3> points, std::span<const Array> point_data,
                  const Options& options = {});

// A triangle surface (PolyData with Polys).
void write_surface(const std::filesystem::path& file, std::span<const Vec3> points,
                   std::span<const std::array<std::uint32_t, 3>> triangles, std::span<const Array> point_data,
                   std::span<const Array> cell_data, const Options& options = {});
void write_surface(const std::filesystem::path& file, const geometry::SurfaceMesh& mesh,
                   std::span<const Array> point_data, std::span<const Array> cell_data, const Options& options = {});

// An unstructured grid: cell i has nodes connectivity[offsets[i-1] .. offsets[i]) (offsets[-1] = 0),
// as in VTK's own layout.
void write_unstructured(const std::filesystem::path& file, std::span<const Vec3> points,
                        std::span<const std::int64_t> connectivity, std::span<const std::int64_t> offsets,
                        std::span<const CellType> types, std::span<const Array> point_data,
                        std::span<const Array> cell_data, const Options& options = {});

// A .pvd collection of time steps, valid on disk after every add().
class TimeSeries {
 public:
  // Starts an empty series at `pvd_file` (replacing an existing one on the first add()).
  explicit TimeSeries(std::filesystem::path pvd_file);
  // Adds a data file for `time` (s); stored relative to the .pvd's folder.
  // Rewrites the .pvd atomically (temporary file and rename).
  void add(double time, const std::filesystem::path& data_file);
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  [[nodiscard]] std::size_t size() const { return entries_.size(); }

  struct Entry {
    double time;       // s
    std::string file;  // relative to the .pvd's folder
  };
  [[nodiscard]] const std::vector<Entry>& entries() const { return entries_; }
  // The entries of a checkpoint: the .pvd is rewritten at the next add().
  void restore(std::vector<Entry> entries) { entries_ = std::move(entries); }

 private:
  std::filesystem::path path_;
  std::vector<Entry> entries_;
};

// Writes `text` to `file` through a temporary file and a rename.
void write_file_atomically(const std::filesystem::path& file, const std::string& text);

}  // namespace sabo::io::vtk
