#include "products/dtm.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>

namespace strata {

void DtmOptions::validate() const {
  if (!(cell_m > 0) || cell_m > 10) {
    throw InputError(fmt::format("products.dtm: cell_m must be in (0, 10] metres, got {}", cell_m));
  }
  if (!(fill_gap_m >= 0) || fill_gap_m > 1) {
    throw InputError(fmt::format("products.dtm: fill_gap_m must be in [0, 1] metres, got {}", fill_gap_m));
  }
  if (!(margin_m >= 0)) {
    throw InputError(fmt::format("products.dtm: margin_m must be >= 0 metres, got {}", margin_m));
  }
}

std::size_t fill_small_gaps(Dtm& dtm, double fill_gap_m) {
  const RasterGrid& g = dtm.grid;
  const int r = int(std::floor(fill_gap_m / g.cell));
  if (r < 1) return 0;
  // One pass over the original values (filled cells do not feed others, so a hole
  // can never grow from its own interpolation).
  const std::vector<float> src = dtm.z;
  std::size_t filled = 0;
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      if (std::isfinite(src[g.index(col, row)])) continue;
      double sum = 0, wsum = 0;
      int quadrants = 0;  // bit q set when quadrant q has a measured cell
      for (int dr = -r; dr <= r; ++dr) {
        const int rr = row + dr;
        if (rr < 0 || rr >= g.height) continue;
        for (int dc = -r; dc <= r; ++dc) {
          const int cc = col + dc;
          if (cc < 0 || cc >= g.width || dr * dr + dc * dc > r * r) continue;
          const float z = src[g.index(cc, rr)];
          if (!std::isfinite(z)) continue;
          const double w = 1.0 / double(dr * dr + dc * dc);  // inverse squared distance
          sum += w * z;
          wsum += w;
          // Quadrants around the cell (the axes count for both sides they touch).
          if (dc >= 0 && dr < 0) quadrants |= 1;
          if (dc > 0 && dr >= 0) quadrants |= 2;
          if (dc <= 0 && dr > 0) quadrants |= 4;
          if (dc < 0 && dr <= 0) quadrants |= 8;
        }
      }
      if (std::popcount(unsigned(quadrants)) < 3) continue;  // an edge, not a hole
      dtm.z[g.index(col, row)] = float(sum / wsum);
      ++filled;
    }
  }
  return filled;
}

Dtm build_dtm(const std::filesystem::path& vdb, const DtmOptions& options) {
  options.validate();
  const LevelSetInfo info = read_level_set_info(vdb);
  if (!(info.max.x() > info.min.x()) || !(info.max.y() > info.min.y())) {
    throw ProcessingError(fmt::format("products.dtm: {}: the level set has no active voxels", vdb.string()));
  }
  const double c = options.cell_m;
  // Snap the box outward to whole cells so that exports of different layers share
  // pixel edges and GRASS/QGIS can stack them without resampling.
  const double x0 = std::floor((info.min.x() - options.margin_m) / c) * c;
  const double y0 = std::floor((info.min.y() - options.margin_m) / c) * c;
  const double x1 = std::ceil((info.max.x() + options.margin_m) / c) * c;
  const double y1 = std::ceil((info.max.y() + options.margin_m) / c) * c;
  const int nx = int(std::lround((x1 - x0) / c));
  const int ny = int(std::lround((y1 - y0) / c));
  if (double(nx) * double(ny) > 4e8) {
    throw InputError(fmt::format("products.dtm: {} x {} cells at {} m is too large; use a coarser cell", nx,
                                 ny, c));
  }
  const RasterGrid grid{.x_min = x0, .y_max = y0 + ny * c, .cell = c, .width = nx, .height = ny};
  Dtm dtm = convert_raster<float>(sample_top_surface(vdb, grid));
  fill_small_gaps(dtm, options.fill_gap_m);
  return dtm;
}

DtmStatistics dtm_statistics(const Dtm& dtm, double z_offset) {
  DtmStatistics s;
  double sum = 0, sum2 = 0, lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (float z : dtm.z) {
    if (!std::isfinite(z)) continue;
    const double v = double(float(double(z) + z_offset));  // what the Float32 file holds
    ++s.valid_cells;
    sum += v;
    sum2 += v * v;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (s.valid_cells == 0) return s;
  const double n = double(s.valid_cells);
  s.min = lo;
  s.max = hi;
  s.mean = sum / n;
  s.stddev = std::sqrt(std::max(0.0, sum2 / n - s.mean * s.mean));
  s.area_m2 = n * dtm.grid.cell * dtm.grid.cell;
  return s;
}

std::vector<Eigen::Vector3f> dtm_normals(const Dtm& dtm) {
  const RasterGrid& g = dtm.grid;
  std::vector<Eigen::Vector3f> n(g.cells(), Eigen::Vector3f::UnitZ());
  auto slope = [&](float zm, float z0, float zp) -> double {
    // d z / d step from whichever neighbours exist (central, else one-sided).
    if (std::isfinite(zm) && std::isfinite(zp)) return 0.5 * (double(zp) - double(zm));
    if (std::isfinite(zp)) return double(zp) - double(z0);
    if (std::isfinite(zm)) return double(z0) - double(zm);
    return 0.0;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      const float z0 = dtm.at(c, r);
      if (!std::isfinite(z0)) continue;
      const float zw = c > 0 ? dtm.at(c - 1, r) : nan, ze = c + 1 < g.width ? dtm.at(c + 1, r) : nan;
      const float zn = r > 0 ? dtm.at(c, r - 1) : nan, zs = r + 1 < g.height ? dtm.at(c, r + 1) : nan;
      const double dzdx = slope(zw, z0, ze) / g.cell;
      const double dzdy = slope(zs, z0, zn) / g.cell;  // rows run north to south
      n[g.index(c, r)] = Eigen::Vector3f(float(-dzdx), float(-dzdy), 1.0f).normalized();
    }
  }
  return n;
}

}  // namespace strata
