#pragma once
// Rasters in the site frame: a north-up grid of square cells, as GIS rasters are,
// and the values on it. Plain data: the GeoTIFF reader (importers/raster) and
// writer (exporters/raster) take and return these.
//
// Frames: grids live in the site frame (site CRS minus the site origin, metres).
// Heights may be Float32 site-frame values (Float32 only in rasters expressed in
// the local frame); writers add the origin back.
#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace strata {

// A north-up raster grid in the site frame. Column c covers
// [x_min + c*cell, x_min + (c+1)*cell]; row r covers [y_max - (r+1)*cell, y_max - r*cell].
// The GeoTIFF geotransform is {E0 + x_min, cell, 0, N0 + y_max, 0, -cell}.
struct RasterGrid {
  double x_min = 0;  // metres, site frame: west edge of column 0
  double y_max = 0;  // metres, site frame: north edge of row 0
  double cell = 0;   // metres
  int width = 0;     // columns
  int height = 0;    // rows

  double x_centre(int col) const { return x_min + (col + 0.5) * cell; }
  double y_centre(int row) const { return y_max - (row + 0.5) * cell; }
  double x_max() const { return x_min + width * cell; }
  double y_min() const { return y_max - height * cell; }
  std::size_t cells() const { return std::size_t(width) * std::size_t(height); }
  std::size_t index(int col, int row) const { return std::size_t(row) * std::size_t(width) + std::size_t(col); }
  // The centre of the cell at index(col, row).
  Eigen::Vector2d centre(std::size_t index) const {
    return {x_centre(int(index % std::size_t(width))), y_centre(int(index / std::size_t(width)))};
  }
  bool operator==(const RasterGrid&) const = default;

  // The grid of width x height cells whose south-west cell has its centre at (x0, y0).
  static RasterGrid from_south_west_centre(double x0, double y0, double cell, int width, int height) {
    return {x0 - 0.5 * cell, y0 + (height - 0.5) * cell, cell, width, height};
  }
};

// Heights (or another length: a thickness) in metres on a grid, row-major north-up;
// NaN where there is no surface. T is float for rasters as files hold them, double
// for computations on them.
template <class T>
struct HeightRaster {
  RasterGrid grid;
  std::vector<T> z;
  // Height uncertainty per cell, metres, one sigma, same layout (NaN where
  // unknown); empty: none.
  std::vector<T> sigma;

  // A raster of NaN heights (no sigma) on `g`.
  static HeightRaster empty(const RasterGrid& g) {
    return {g, std::vector<T>(g.cells(), std::numeric_limits<T>::quiet_NaN()), {}};
  }
  T at(int col, int row) const { return z[grid.index(col, row)]; }
  T& at(int col, int row) { return z[grid.index(col, row)]; }
  bool valid(int col, int row) const { return std::isfinite(at(col, row)); }
  bool has_sigma() const { return sigma.size() == z.size() && !z.empty(); }
};

// A layer's digital terrain model as its GeoTIFF holds it.
using Dtm = HeightRaster<float>;

// The same raster in another value type (float <-> double), cell by cell.
template <class To, class From>
HeightRaster<To> convert_raster(const HeightRaster<From>& r) {
  HeightRaster<To> out;
  out.grid = r.grid;
  out.z.assign(r.z.begin(), r.z.end());
  out.sigma.assign(r.sigma.begin(), r.sigma.end());
  return out;
}

// RGBA image on a site-frame grid; alpha 0 where nothing was seen.
struct RgbaRaster {
  RasterGrid grid;
  std::vector<std::uint8_t> rgba;  // row-major north-up, 4 bytes per cell
};

// Where a site-frame grid sits in the real world.
struct RasterGeoreference {
  std::string crs_wkt;                               // WKT of the site CRS (describe_crs().wkt)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // site origin E, N, Z (metres)
};

// No-data value of height files: a finite number, because some GIS tools (and
// GRASS r.in.gdal) treat NaN inconsistently.
constexpr double kDtmNoData = -9999.0;

}  // namespace strata
