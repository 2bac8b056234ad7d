#pragma once
// Digital terrain model of a layer: the uppermost fused surface seen from above,
// on a north-up grid.
//
// Frames: grids live in the site frame (site CRS minus the site origin, metres).
// Heights are stored as Float32 site-frame values (design.md allows Float32 in
// rasters expressed in the local frame); writers add the origin back.
#include "dense/dense.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <limits>
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
};

// Heights in metres (site frame), row-major north-up; NaN where there is no surface.
struct Dtm {
  RasterGrid grid;
  std::vector<float> z;
  // Height uncertainty per cell, metres, one sigma, same layout (NaN where
  // unknown, and on cells filled by fill_small_gaps); empty: none.
  std::vector<float> sigma;

  float at(int col, int row) const { return z[grid.index(col, row)]; }
  bool valid(int col, int row) const { return std::isfinite(at(col, row)); }
};

struct DtmOptions {
  double cell_m = 0.005;  // metres; 5 mm is about the dense GSD of a 24 Mpx photo at 1.5 m
  double margin_m = 0;    // metres added around the level set's active box
  // Holes no wider than about twice this (metres) are filled by inverse-distance
  // interpolation when measured cells surround them (3 of 4 quadrants within this
  // distance): the speckle a few voxels wide between fused observations, not the
  // unseen areas, which stay nodata. 0 = no filling.
  double fill_gap_m = 0.015;
  // Throws InputError naming the first invalid field.
  void validate() const;
};

// Samples the top surface of a fused level set (.vdb written by the dense stage) on
// a grid whose edges are whole multiples of the cell in the site frame (and so in
// the CRS, because the site origin is rounded to 100 m / 1 m).
Dtm build_dtm(const std::filesystem::path& vdb, const DtmOptions& options);

// Fills small enclosed holes of a DTM in place (see DtmOptions::fill_gap_m); returns
// the number of cells filled.
std::size_t fill_small_gaps(Dtm& dtm, double fill_gap_m);

// The same grid as a dense HeightField (cell centres, y up) turned north-up.
Dtm dtm_from_height_field(const HeightField& hf);

// Statistics of the heights as a GIS reads them back: each valid cell's absolute
// height rounded to Float32 (z + z_offset), so that GRASS/QGIS statistics of the
// exported file agree to float precision.
struct DtmStatistics {
  std::size_t valid_cells = 0;
  double min = std::numeric_limits<double>::quiet_NaN();  // metres
  double max = std::numeric_limits<double>::quiet_NaN();
  double mean = std::numeric_limits<double>::quiet_NaN();
  double stddev = std::numeric_limits<double>::quiet_NaN();
  double area_m2 = 0;  // valid cells x cell^2
};
DtmStatistics dtm_statistics(const Dtm& dtm, double z_offset = 0);

// Unit surface normals per cell from central differences of the heights (one-sided
// at holes and edges; straight up where both neighbours are missing).
std::vector<Eigen::Vector3f> dtm_normals(const Dtm& dtm);

}  // namespace strata
