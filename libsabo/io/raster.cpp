#include "libsabo/io/raster.hpp"

#include <cpl_error.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <mutex>
#include <utility>

#include "libsabo/core/error.hpp"

namespace sabo::io {
namespace {

// GDAL's last error, or a stand-in when it left none.
std::string gdal_message() {
  const char* text = CPLGetLastErrorMsg();
  return text != nullptr && *text != '\0' ? std::string(text) : std::string("no message from GDAL");
}

struct DatasetCloser {
  void operator()(void* dataset) const { GDALClose(static_cast<GDALDatasetH>(dataset)); }
};
using Dataset = std::unique_ptr<void, DatasetCloser>;

struct SpatialReferenceDeleter {
  void operator()(void* srs) const { OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(srs)); }
};

std::string crs_of(GDALDatasetH dataset) {
  const char* wkt = GDALGetProjectionRef(dataset);
  if (wkt == nullptr || *wkt == '\0') return {};
  std::unique_ptr<void, SpatialReferenceDeleter> srs(OSRNewSpatialReference(wkt));
  if (!srs) return "unnamed";
  auto* handle = static_cast<OGRSpatialReferenceH>(srs.get());
  const char* name = OSRGetName(handle);
  std::string text = name != nullptr ? name : "unnamed";
  const char* node = OSRIsProjected(handle) ? "PROJCS" : "GEOGCS";
  const char* authority = OSRGetAuthorityName(handle, node);
  const char* code = OSRGetAuthorityCode(handle, node);
  if (authority != nullptr && code != nullptr) text += fmt::format(" ({}:{})", authority, code);
  return text;
}

}  // namespace

bool Raster::covers(double x, double y) const {
  return x >= x_min() && x <= x_max() && y >= y_min() && y <= y_max();
}

std::optional<double> Raster::elevation_at(double x, double y) const {
  if (!covers(x, y)) return std::nullopt;
  // Continuous indices of the cell centres: column c at x = left + (c + 0.5) cell_x.
  const double u = (x - left) / cell_x - 0.5, v = (top - y) / cell_y - 0.5;
  const auto c0 = static_cast<std::size_t>(std::clamp(std::floor(u), 0.0, static_cast<double>(columns - 2)));
  const auto r0 = static_cast<std::size_t>(std::clamp(std::floor(v), 0.0, static_cast<double>(rows - 2)));
  const double a = u - static_cast<double>(c0), b = v - static_cast<double>(r0);
  std::array<double, 4> z{};
  const std::array<std::size_t, 4> cells{r0 * columns + c0, r0 * columns + c0 + 1, (r0 + 1) * columns + c0,
                                         (r0 + 1) * columns + c0 + 1};
  for (std::size_t k = 0; k < 4; ++k) {
    z[k] = elevation[cells[k]];
    if ((no_data && z[k] == static_cast<double>(static_cast<float>(*no_data))) || !std::isfinite(z[k])) {
      return std::nullopt;
    }
  }
  return (1 - a) * (1 - b) * z[0] + a * (1 - b) * z[1] + (1 - a) * b * z[2] + a * b * z[3];
}

namespace {

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& problem, const std::string& fix) {
  throw FileError(fmt::format("{}: {}. Fix: {}", file.string(), problem, fix));
}

// Opens `file` and fills everything of `raster` but the elevations (the whole raster's header and
// description); the dataset stays open for reading the band.
Dataset open_raster(const std::filesystem::path& file, Raster& raster) {
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  CPLErrorReset();
  // GDAL prints its errors to stderr by default; they go into the exception instead.
  CPLPushErrorHandler(CPLQuietErrorHandler);
  Dataset dataset(GDALOpen(file.c_str(), GA_ReadOnly));
  CPLPopErrorHandler();
  if (!dataset) {
    fail(file, fmt::format("GDAL cannot open it as a raster ({})", gdal_message()),
         "give an elevation raster GDAL reads (a GeoTIFF .tif, an ESRI ASCII grid .asc), with the path "
         "relative to the scene file's folder");
  }
  auto* handle = static_cast<GDALDatasetH>(dataset.get());
  raster.file = file;
  raster.driver = GDALGetDriverShortName(GDALGetDatasetDriver(handle));
  if (GDALGetRasterCount(handle) < 1) fail(file, "the raster has no band", "give a raster whose band 1 is elevation");
  raster.columns = static_cast<std::size_t>(GDALGetRasterXSize(handle));
  raster.rows = static_cast<std::size_t>(GDALGetRasterYSize(handle));
  if (raster.columns < 2 || raster.rows < 2) {
    fail(file,
         fmt::format("{} x {} cells; elevations between cell centres need at least 2 x 2", raster.columns, raster.rows),
         "give a larger raster");
  }
  std::array<double, 6> transform{};
  if (GDALGetGeoTransform(handle, transform.data()) != CE_None) {
    fail(file, "the raster has no georeference (no geotransform)",
         "give a georeferenced raster (a GeoTIFF with its georeference, an .asc grid with its header)");
  }
  if (transform[2] != 0.0 || transform[4] != 0.0 || !(transform[1] > 0) || !(transform[5] < 0)) {
    fail(file, fmt::format("the raster is rotated or flipped (geotransform {})", fmt::join(transform, ", ")),
         "warp it north-up first: gdalwarp in.tif out.tif");
  }
  raster.left = transform[0];
  raster.top = transform[3];
  raster.cell_x = transform[1];
  raster.cell_y = -transform[5];
  raster.crs = crs_of(handle);
  raster.description =
      fmt::format("{} ({}, {} x {} cells of {} x {} m, x {} to {} m, y {} to {} m, coordinate system {})",
                  file.string(), raster.driver, raster.columns, raster.rows, raster.cell_x, raster.cell_y, raster.left,
                  raster.left + static_cast<double>(raster.columns) * raster.cell_x,
                  raster.top - static_cast<double>(raster.rows) * raster.cell_y, raster.top,
                  raster.crs.empty() ? std::string("not given") : raster.crs);
  return dataset;
}

}  // namespace

Raster read_raster(const std::filesystem::path& file, const std::optional<RasterWindow>& window) {
  Raster raster;
  const Dataset dataset = open_raster(file, raster);
  // The window's cells: those whose centres bracket it, and one more on each side.
  std::size_t first_column = 0, first_row = 0;
  if (window && !window->empty()) {
    const auto span = [](double low, double high, double cell, std::size_t count) {
      const double first = std::floor(low / cell - 0.5) - 1, last = std::ceil(high / cell - 0.5) + 1;
      const double top_index = static_cast<double>(count - 1);
      auto a = static_cast<std::size_t>(std::clamp(first, 0.0, top_index));
      auto b = static_cast<std::size_t>(std::clamp(last, 0.0, top_index));
      if (b < a + 1) {  // at least two cells: a window beyond the raster reads its edge, and is refused there
        b = std::min(a + 1, count - 1);
        a = b - 1;
      }
      return std::pair{a, b - a + 1};
    };
    const auto [c0, nc] = span(window->x_min - raster.left, window->x_max - raster.left, raster.cell_x, raster.columns);
    const auto [r0, nr] = span(raster.top - window->y_max, raster.top - window->y_min, raster.cell_y, raster.rows);
    first_column = c0;
    first_row = r0;
    raster.left += static_cast<double>(c0) * raster.cell_x;
    raster.top -= static_cast<double>(r0) * raster.cell_y;
    raster.columns = nc;
    raster.rows = nr;
  }
  GDALRasterBandH band = GDALGetRasterBand(static_cast<GDALDatasetH>(dataset.get()), 1);
  int has_no_data = 0;
  const double no_data = GDALGetRasterNoDataValue(band, &has_no_data);
  if (has_no_data != 0) raster.no_data = no_data;
  raster.elevation.resize(raster.columns * raster.rows);
  CPLErrorReset();
  if (GDALRasterIO(band, GF_Read, static_cast<int>(first_column), static_cast<int>(first_row),
                   static_cast<int>(raster.columns), static_cast<int>(raster.rows), raster.elevation.data(),
                   static_cast<int>(raster.columns), static_cast<int>(raster.rows), GDT_Float32, 0, 0) != CE_None) {
    fail(file, fmt::format("its band 1 does not read ({})", gdal_message()), "check the file is complete");
  }
  return raster;
}

std::string describe_raster(const std::filesystem::path& file) {
  Raster raster;
  (void)open_raster(file, raster);
  return raster.description;
}

}  // namespace sabo::io
