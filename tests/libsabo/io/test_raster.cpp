// io/raster.hpp: elevation rasters through GDAL (an ESRI ASCII grid, a GeoTIFF with its coordinate system),
// bilinear elevations, no-data, and the errors of files GDAL cannot use.
#include <cpl_conv.h>
#include <gdal.h>
#include <gtest/gtest.h>
#include <ogr_srs_api.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <string>

#include "libsabo/core/error.hpp"
#include "libsabo/io/raster.hpp"
#include "tests/support/scratch.hpp"

namespace {

using sabo::io::read_raster;
using sabo::testing::scratch;

// A plane z = 100 + 0.25 x - 0.5 y, stored at the cell centres of an ESRI ASCII grid (values exact in
// float): bilinear elevations between the centres are the plane's to rounding.
double plane(double x, double y) {
  return 100.0 + 0.25 * x - 0.5 * y;
}

std::filesystem::path write_grid(const std::string& name, int columns, int rows, double cell, double left,
                                 double bottom, int no_data_column = -1) {
  const auto path = scratch(name);
  std::ofstream out(path);
  out << "ncols " << columns << "\nnrows " << rows << "\nxllcorner " << left << "\nyllcorner " << bottom
      << "\ncellsize " << cell << "\nNODATA_value -9999\n";
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      const double x = left + (c + 0.5) * cell, y = bottom + (rows - r - 0.5) * cell;  // row 0 is the north
      out << (c == no_data_column && r == 1 ? -9999.0 : plane(x, y)) << (c + 1 < columns ? " " : "\n");
    }
  }
  return path;
}

TEST(Raster, EsriGridReadsBackThePlaneBetweenCellCentres) {
  const auto raster = read_raster(write_grid("plane.asc", 6, 5, 8.0, 1000.0, 2000.0));
  EXPECT_EQ(raster.driver, "AAIGrid");
  EXPECT_EQ(raster.columns, 6u);
  EXPECT_EQ(raster.rows, 5u);
  EXPECT_DOUBLE_EQ(raster.cell_x, 8.0);
  EXPECT_DOUBLE_EQ(raster.left, 1000.0);
  EXPECT_DOUBLE_EQ(raster.top, 2040.0);
  EXPECT_TRUE(raster.crs.empty()) << raster.crs;
  ASSERT_TRUE(raster.no_data.has_value());
  EXPECT_DOUBLE_EQ(*raster.no_data, -9999.0);
  EXPECT_DOUBLE_EQ(raster.x_min(), 1004.0);
  EXPECT_DOUBLE_EQ(raster.x_max(), 1044.0);
  EXPECT_DOUBLE_EQ(raster.y_min(), 2004.0);
  EXPECT_DOUBLE_EQ(raster.y_max(), 2036.0);
  double worst = 0;
  for (double x = raster.x_min(); x <= raster.x_max(); x += 1.37) {
    for (double y = raster.y_min(); y <= raster.y_max(); y += 0.91) {
      const auto z = raster.elevation_at(x, y);
      ASSERT_TRUE(z.has_value()) << x << ", " << y;
      worst = std::max(worst, std::abs(*z - plane(x, y)));
    }
  }
  std::cout << "bilinear elevation of a plane: largest error " << worst << " m (expected below 1e-9)\n";
  EXPECT_LT(worst, 1e-9);
  EXPECT_FALSE(raster.elevation_at(1003.9, 2020.0).has_value()) << "outside the cell centres";
  EXPECT_FALSE(raster.elevation_at(1020.0, 2036.1).has_value());
  EXPECT_NE(raster.describe().find("AAIGrid, 6 x 5 cells of 8 x 8 m"), std::string::npos) << raster.describe();
  EXPECT_NE(raster.describe().find("coordinate system not given"), std::string::npos);
}

TEST(Raster, AWindowReadsOnlyTheCellsAroundIt) {
  const auto path = write_grid("large.asc", 40, 30, 8.0, 1000.0, 2000.0);
  const auto window = read_raster(path, sabo::io::RasterWindow{1100.0, 2100.0, 1130.0, 2110.0});
  std::cout << "window of a 40 x 30 grid: " << window.columns << " x " << window.rows << " cells read\n";
  EXPECT_LE(window.columns, 7u);  // 30 m across 8 m cells, and one more on each side
  EXPECT_LE(window.rows, 5u);
  EXPECT_LE(window.x_min(), 1100.0);
  EXPECT_GE(window.x_max(), 1130.0);
  EXPECT_LE(window.y_min(), 2100.0);
  EXPECT_GE(window.y_max(), 2110.0);
  for (double x = 1100.0; x <= 1130.0; x += 2.5) {
    for (double y = 2100.0; y <= 2110.0; y += 2.5) {
      const auto z = window.elevation_at(x, y);
      ASSERT_TRUE(z.has_value()) << x << ", " << y;
      EXPECT_NEAR(*z, plane(x, y), 1e-9);
    }
  }
  EXPECT_NE(window.describe().find("40 x 30 cells"), std::string::npos) << "the whole raster is described";
  const auto edge = read_raster(path, sabo::io::RasterWindow{5000.0, 5000.0, 5001.0, 5001.0});
  EXPECT_EQ(edge.columns, 2u) << "a window beyond the raster reads its edge";
  EXPECT_FALSE(edge.elevation_at(5000.0, 5000.0).has_value());
}

TEST(Raster, NoDataCellsGiveNoElevationNearThem) {
  // Column 2 of row 1 is no-data: its centre is (1020, 2028).
  const auto raster = read_raster(write_grid("holed.asc", 6, 5, 8.0, 1000.0, 2000.0, 2));
  EXPECT_FALSE(raster.elevation_at(1021.0, 2027.0).has_value());
  EXPECT_FALSE(raster.elevation_at(1015.0, 2031.0).has_value()) << "a neighbour of the bilinear cell";
  const auto far = raster.elevation_at(1040.0, 2010.0);
  ASSERT_TRUE(far.has_value());
  EXPECT_NEAR(*far, plane(1040.0, 2010.0), 1e-9);
}

TEST(Raster, GeoTiffKeepsItsCoordinateSystem) {
  GDALAllRegister();
  const auto path = scratch("utm.tif");
  GDALDriverH driver = GDALGetDriverByName("GTiff");
  ASSERT_NE(driver, nullptr);
  GDALDatasetH dataset = GDALCreate(driver, path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
  ASSERT_NE(dataset, nullptr);
  double transform[6] = {500000.0, 2.0, 0.0, 3400000.0, 0.0, -2.0};
  GDALSetGeoTransform(dataset, transform);
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, 32648);
  char* wkt = nullptr;
  OSRExportToWkt(srs, &wkt);
  GDALSetProjection(dataset, wkt);
  CPLFree(wkt);
  OSRDestroySpatialReference(srs);
  float values[12];
  for (int k = 0; k < 12; ++k) values[k] = 1300.0f - static_cast<float>(k);
  ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(dataset, 1), GF_Write, 0, 0, 4, 3, values, 4, 3, GDT_Float32, 0, 0),
            CE_None);
  GDALClose(dataset);

  const auto raster = read_raster(path);
  std::cout << raster.describe() << "\n";
  EXPECT_EQ(raster.driver, "GTiff");
  EXPECT_NE(raster.crs.find("UTM zone 48N"), std::string::npos) << raster.crs;
  EXPECT_NE(raster.crs.find("EPSG:32648"), std::string::npos) << raster.crs;
  EXPECT_FALSE(raster.no_data.has_value());
  const auto z = raster.elevation_at(500001.0, 3399999.0);  // the first cell's centre
  ASSERT_TRUE(z.has_value());
  EXPECT_DOUBLE_EQ(*z, 1300.0);
}

TEST(Raster, FilesGdalCannotUseAreRefusedWithItsMessage) {
  const auto text = scratch("not_a_raster.asc");
  std::ofstream(text) << "distance,elevation\n0,100\n";
  try {
    (void)read_raster(text);
    FAIL() << "a CSV file read as a raster";
  } catch (const sabo::FileError& error) {
    const std::string message = error.what();
    std::cout << message << "\n";
    EXPECT_NE(message.find(text.string()), std::string::npos);
    EXPECT_NE(message.find("GDAL cannot open it"), std::string::npos);
    EXPECT_NE(message.find("Fix:"), std::string::npos);
  }
  EXPECT_THROW((void)read_raster(scratch("missing.tif")), sabo::FileError);
  EXPECT_THROW((void)read_raster(write_grid("one_row.asc", 4, 1, 8.0, 0.0, 0.0)), sabo::FileError);
}

}  // namespace
