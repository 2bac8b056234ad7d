#pragma once
// Photo coverage of a layer's plan: how many registered photos see each part of
// the trench, and at what ground resolution. Eigen and std only, so that the
// rules and their tests need no database or image library.
//
// Frames: site frame (site CRS minus the site origin, metres), north-up plan grid.
#include "geometry/camera.hpp"
#include "geometry/raster.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace strata {

// A north-up plan grid over the trench; cells whose height is NaN lie outside the
// recorded area and are ignored.
struct CoverageMap : RasterGrid {
  std::vector<float> z;      // metres, site frame, row-major; NaN outside the area
  std::vector<int> count;    // registered photos that see the cell centre
  std::vector<float> gsd_m;  // finest ground sampling distance among them, metres/pixel; NaN when unseen

  bool inside(std::size_t i) const;  // height known
  std::size_t area_cells() const;
};

// Plan grid from heights on a regular north-up grid (a DTM, possibly decimated).
CoverageMap coverage_grid(double x_min, double y_max, double cell, int width, int height, std::vector<float> z);

// Plan grid over the sparse points: the extent between their 2nd and 98th
// percentiles in x and y (so that stray points far off do not stretch it), at most
// `max_cells` cells along the longer side; each cell's height is the median of its
// points, and empty cells take the median of the nearest filled cells, because the
// trench floor is continuous even where few points were matched.
CoverageMap coverage_grid_from_points(const std::vector<Eigen::Vector3d>& points, int max_cells);

// Counts, for every cell centre, the cameras whose image contains its projection
// (in front of the camera, inside the frame), and the finest GSD among them
// (depth / focal length: fronto-parallel approximation). Occlusion is ignored: a
// trench floor seen from its edges is close to a height field.
void count_coverage(CoverageMap& map, const std::vector<Camera>& cameras);

// Where in the trench a part lies: the recorded area's bounding box cut into 3 x 3
// sectors, named as a field team would ("north-east corner", "west edge", "centre").
struct Sector {
  std::string name;                // "north-east corner"
  std::vector<std::string> sides;  // compass sides it touches, east/west first: {"east", "north"}
};
Sector sector_of(int sx, int sy);  // sx 0..2 west->east, sy 0..2 south->north

// A sector where too many cells fall short (too few photos, or too coarse).
struct CoverageShortfall {
  Sector sector;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // of the short cells, site frame
  int cells = 0;               // short cells in the sector
  double fraction = 0;         // of the sector's recorded cells
  double area_m2 = 0;
  int min_count = 0;           // fewest photos seeing any short cell
  double worst_gsd_m = 0;      // coarsest finest-GSD among the short cells, metres/pixel
};

// Sectors in which at least `min_fraction` of the recorded cells are seen by fewer
// than `min_photos` photos.
std::vector<CoverageShortfall> find_coverage_gaps(const CoverageMap& map, int min_photos, double min_fraction);
// Sectors in which at least `min_fraction` of the cells seen by some photo are
// seen only at a GSD coarser than `max_gsd_m` (metres per pixel).
std::vector<CoverageShortfall> find_low_resolution(const CoverageMap& map, double max_gsd_m, double min_fraction);

// Which side of the trench to photograph a shortfall from: of the sides the
// sector touches, the one with the fewest cameras in the ring around the trench
// (cameras whose bearing from the trench centre lies within 45 degrees of that
// side), because a thin stretch of the ring is what usually leaves a corner
// unseen. Empty for the centre (photograph it from straight above).
std::string side_to_photograph(const CoverageShortfall& gap, const std::vector<Eigen::Vector2d>& camera_centres,
                               const Eigen::Vector2d& trench_centre);

}  // namespace strata
