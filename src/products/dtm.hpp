#pragma once
// Digital terrain model of a layer: the uppermost fused surface seen from above,
// on a north-up grid.
//
// Frames: see geometry/raster.hpp.
#include "dense/dense.hpp"
#include "geometry/raster.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <limits>
#include <vector>

namespace strata {

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
