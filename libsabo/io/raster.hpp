#pragma once
// An elevation raster read through GDAL: a GeoTIFF, an ESRI ASCII grid or any other raster GDAL opens. Band 1
// holds the elevation (m); the raster is north-up (no rotation terms in its geotransform). Elevations
// between cell centres are bilinear, so a plane stored cell by cell is read back exactly.
#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace sabo::io {

struct Raster {
  std::filesystem::path file;
  std::string driver;  // GDAL's short name: "GTiff", "AAIGrid", ...
  // The coordinate system's name and authority code, e.g. "WGS 84 / UTM zone 48N (EPSG:32648)"; empty when
  // the file has none (an ESRI ASCII grid without its .prj).
  std::string crs;
  std::size_t columns = 0, rows = 0;
  double left = 0, top = 0;       // m: the outer corner of the first cell (row 0 is the northernmost)
  double cell_x = 0, cell_y = 0;  // m: cell size along x and along y (both > 0; rows run south)
  std::optional<double> no_data;  // the band's no-data value, when it has one
  std::vector<float> elevation;   // m, rows x columns, row-major

  // The extent of the cell centres, where elevation_at() is defined, m.
  [[nodiscard]] double x_min() const { return left + 0.5 * cell_x; }
  [[nodiscard]] double x_max() const { return left + (static_cast<double>(columns) - 0.5) * cell_x; }
  [[nodiscard]] double y_max() const { return top - 0.5 * cell_y; }
  [[nodiscard]] double y_min() const { return top - (static_cast<double>(rows) - 0.5) * cell_y; }
  [[nodiscard]] bool covers(double x, double y) const;
  // The elevation at (x, y), m, bilinear between the four nearest cell centres; nullopt outside the centres'
  // extent or where one of those cells is no-data.
  [[nodiscard]] std::optional<double> elevation_at(double x, double y) const;
  // One line for logs: file, driver, size, cell size, extent and coordinate system of the whole raster (also
  // when only a window of it was read).
  [[nodiscard]] const std::string& describe() const { return description; }
  std::string description;
};

// A region of a raster, in its coordinates (m): empty until extended by a point.
struct RasterWindow {
  double x_min = std::numeric_limits<double>::infinity(), y_min = std::numeric_limits<double>::infinity();
  double x_max = -std::numeric_limits<double>::infinity(), y_max = -std::numeric_limits<double>::infinity();
  void extend(double x, double y) {
    x_min = std::min(x_min, x);
    y_min = std::min(y_min, y);
    x_max = std::max(x_max, x);
    y_max = std::max(y_max, y);
  }
  [[nodiscard]] bool empty() const { return !(x_min <= x_max && y_min <= y_max); }
};

// Reads the elevations of the cells that cover `window` (and one cell around it, clamped to the raster;
// at least 2 x 2 cells), or of the whole raster (no window, or an empty one): a large elevation model is never read
// whole for a strip of it. Throws FileError naming the file and GDAL's own message: a file GDAL cannot open, a raster
// without a band, a rotated raster (the fix: gdalwarp it north-up), fewer than 2 x 2 cells, a band that does not read.
[[nodiscard]] Raster read_raster(const std::filesystem::path& file,
                                 const std::optional<RasterWindow>& window = std::nullopt);
// The raster's description (Raster::describe()) from its header alone, no elevation read; throws as
// read_raster().
[[nodiscard]] std::string describe_raster(const std::filesystem::path& file);

}  // namespace sabo::io
