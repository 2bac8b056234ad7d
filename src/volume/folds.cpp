// The unit solids checked against the voxel model where height fields fold
// (check_folds in volume.hpp).
//
// A height field holds one height per cell: at a vertical face it takes some
// height between the face's top and foot, and under an overhang (a lip of a pit
// undercut by the digging, a stone standing proud of the section) it sees only the
// top. The layers' fused level sets (surface.vdb) hold the ground in 3D. Over the
// cells where a unit's surfaces are steep, and those within reach of them, each
// cell is integrated again along vertical lines through both level sets: the
// length of ground on each line (linear between the signed distances of
// consecutive samples) where the voxels were observed, the height field's
// where they were not (so an unseen space counts as the height field says, never
// as empty). The difference of the two lengths, less the height fields'
// difference, is what the voxel model adds to or takes from the solid there.
#include "core/log.hpp"
#include "volume/significance.hpp"
#include "volume/volume.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>

namespace strata {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool finite(double v) { return std::isfinite(v); }

// Length of ground along one vertical line sampled at z0 + k dz (k < n): linear
// between consecutive signed distances where both were observed, else from the
// height field's height h (ground below it).
double ground_length(const double* d, int n, double z0, double dz, double h) {
  double length = 0;
  for (int k = 0; k + 1 < n; ++k) {
    const double a = d[k], b = d[k + 1];
    if (finite(a) && finite(b)) {
      if (a < 0 && b < 0) {
        length += dz;
      } else if (a < 0 || b < 0) {
        const double t = a / (a - b);  // where the distance crosses zero, 0..1
        length += a < 0 ? t * dz : (1 - t) * dz;
      }
    } else {
      length += std::clamp(h - (z0 + k * dz), 0.0, dz);
    }
  }
  return length;
}

// Steepest slope (rise over run) of a height field at a cell: central
// differences, one-sided next to NaN cells; 0 where no neighbour is known. (The
// derivative along the rows runs southwards: only its magnitude counts.)
double slope_at(const HeightRaster<double>& f, int col, int row) {
  const RasterGrid& g = f.grid;
  auto at = [&](int c, int r) { return c < 0 || r < 0 || c >= g.width || r >= g.height ? kNaN : f.at(c, r); };
  const double z = at(col, row);
  if (!finite(z)) return 0;
  auto derivative = [&](double lo, double hi) {
    if (finite(lo) && finite(hi)) return (hi - lo) / (2 * g.cell);
    if (finite(hi)) return (hi - z) / g.cell;
    if (finite(lo)) return (z - lo) / g.cell;
    return 0.0;
  };
  const double gx = derivative(at(col - 1, row), at(col + 1, row));
  const double gy = derivative(at(col, row - 1), at(col, row + 1));
  return std::hypot(gx, gy);
}

// Minimum (sign -1: maximum) of the finite values within `radius` cells (square
// neighbourhood), separably; NaN where there is none.
std::vector<double> window_extreme(const std::vector<double>& v, int nx, int ny, int radius, double sign) {
  auto pass = [&](const std::vector<double>& in, bool rows) {
    std::vector<double> out(in.size(), kNaN);
    const int len = rows ? nx : ny, lines = rows ? ny : nx;
    for (int line = 0; line < lines; ++line)
      for (int p = 0; p < len; ++p) {
        double best = kNaN;
        for (int q = std::max(0, p - radius); q <= std::min(len - 1, p + radius); ++q) {
          const double x = in[rows ? std::size_t(line) * nx + q : std::size_t(q) * nx + line];
          if (finite(x) && (!finite(best) || sign * x < sign * best)) best = x;
        }
        out[rows ? std::size_t(line) * nx + p : std::size_t(p) * nx + line] = best;
      }
    return out;
  };
  return pass(pass(v, true), false);
}

struct FoldSums {
  double height_field_m3 = 0;  // the dug cells' thickness x area
  double difference_m3 = 0;    // what the voxel model adds
  std::size_t cells = 0;
  void add(const FoldSums& o) {
    height_field_m3 += o.height_field_m3;
    difference_m3 += o.difference_m3;
    cells += o.cells;
  }
};

// The index of the layer whose surface gives `z` at cell c, preferring `hint`;
// -1 when none does.
int layer_giving(const std::vector<LayerSurface>& layers, std::size_t c, double z, int hint) {
  if (hint >= 0 && layers[std::size_t(hint)].z.z[c] == z) return hint;
  for (std::size_t q = 0; q < layers.size(); ++q)
    if (layers[q].z.z[c] == z) return int(q);
  return -1;
}

void check_solid(UnitSolid& s, const std::vector<LayerSurface>& layers,
                 const std::vector<const LevelSetProbe*>& probes, const VolumeOptions& options) {
  const RasterGrid& grid = layers.front().z.grid;
  const int nx = grid.width, ny = grid.height;
  const std::size_t n = grid.cells();
  const double cell_area = grid.cell * grid.cell;
  const int top_hint = int(std::find_if(layers.begin(), layers.end(),
                                        [&](const LayerSurface& l) { return l.layer == s.top_layer; }) -
                           layers.begin());
  // Per dug cell, the layers that give its top and bottom; the commonest bottom
  // stands for the cells around that were not dug.
  std::vector<int> top_of(n, -1), bottom_of(n, -1);
  std::vector<std::size_t> bottom_count(layers.size(), 0);
  std::vector<std::uint8_t> steep(n, 0);
  const double steep_slope = std::tan(options.fold_slope_deg * std::numbers::pi / 180);
  for (std::size_t c = 0; c < n; ++c) {
    if (!s.dug(c)) continue;
    top_of[c] = layer_giving(layers, c, s.top.z[c], top_hint);
    bottom_of[c] = layer_giving(layers, c, s.bottom.z[c], top_hint + 1);
    if (top_of[c] < 0 || bottom_of[c] < 0) continue;
    ++bottom_count[std::size_t(bottom_of[c])];
    const int col = int(c % nx), row = int(c / nx);
    steep[c] = std::max(slope_at(layers[std::size_t(top_of[c])].z, col, row),
                        slope_at(layers[std::size_t(bottom_of[c])].z, col, row)) > steep_slope;
  }
  const int usual_bottom = int(std::max_element(bottom_count.begin(), bottom_count.end()) - bottom_count.begin());
  UnitMeasures& m = s.measures;
  if (top_hint >= int(layers.size()) || bottom_count[std::size_t(usual_bottom)] == 0) return;
  const int reach = int(std::ceil(options.fold_reach_m / grid.cell - 1e-9));
  const std::vector<std::uint8_t> region = volume_detail::dilate(steep, nx, ny, reach);

  // The layers of every fold cell; the heights the vertical lines must span.
  std::vector<std::size_t> cells;
  std::vector<double> top_z(n, kNaN), bottom_z(n, kNaN);
  for (std::size_t c = 0; c < n; ++c) {
    if (!region[c]) continue;
    if (top_of[c] < 0) {
      top_of[c] = top_hint;
      bottom_of[c] = usual_bottom;
    }
    top_z[c] = layers[std::size_t(top_of[c])].z.z[c];
    bottom_z[c] = layers[std::size_t(bottom_of[c])].z.z[c];
    if (probes[std::size_t(top_of[c])] && probes[std::size_t(bottom_of[c])] && finite(top_z[c]) &&
        finite(bottom_z[c]))
      cells.push_back(c);
  }
  if (cells.empty()) return;
  // Lines reach from the lowest bottom to the highest top within fold_reach_m
  // (the foot of a pit under an overhang lies below the overhang's cells), plus
  // the truncation band either side.
  const std::vector<double> low = window_extreme(bottom_z, nx, ny, reach, 1.0);
  const std::vector<double> high = window_extreme(top_z, nx, ny, reach, -1.0);

  const FoldSums sums = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, cells.size()), FoldSums{},
      [&](const tbb::blocked_range<std::size_t>& r, FoldSums acc) {
        std::vector<double> dt, db;
        for (std::size_t q = r.begin(); q != r.end(); ++q) {
          const std::size_t c = cells[q];
          const LevelSetProbe& pt = *probes[std::size_t(top_of[c])];
          const LevelSetProbe& pb = *probes[std::size_t(bottom_of[c])];
          const double voxel = std::min(pt.voxel_size_m(), pb.voxel_size_m());
          const double band = std::max(pt.truncation_m(), pb.truncation_m());
          const double z0 = std::min(low[c], bottom_z[c]) - band;
          const double z1 = std::max(high[c], top_z[c]) + band;
          const int steps = std::max(1, int(std::ceil((z1 - z0) / voxel)));
          const double span = steps * voxel;
          dt.resize(std::size_t(steps) + 1);
          db.resize(std::size_t(steps) + 1);
          // Sub-lines at the voxel spacing, so a face inside the cell is seen.
          const int sub = std::max(1, int(std::ceil(grid.cell / voxel - 1e-9)));
          const Eigen::Vector2d centre = grid.centre(c);
          double voxel_thickness = 0;
          for (int u = 0; u < sub; ++u)
            for (int v = 0; v < sub; ++v) {
              const double px = centre.x() + ((u + 0.5) / sub - 0.5) * grid.cell;
              const double py = centre.y() + ((v + 0.5) / sub - 0.5) * grid.cell;
              pt.column(px, py, z0, voxel, steps + 1, dt.data());
              pb.column(px, py, z0, voxel, steps + 1, db.data());
              voxel_thickness += ground_length(dt.data(), steps + 1, z0, voxel, top_z[c]) -
                                 ground_length(db.data(), steps + 1, z0, voxel, bottom_z[c]);
            }
          voxel_thickness /= double(sub * sub);
          const double field_thickness =
              std::clamp(top_z[c] - z0, 0.0, span) - std::clamp(bottom_z[c] - z0, 0.0, span);
          acc.difference_m3 += (voxel_thickness - field_thickness) * cell_area;
          if (s.dug(c)) acc.height_field_m3 += s.thickness(c) * cell_area;
          ++acc.cells;
        }
        return acc;
      },
      [](FoldSums a, const FoldSums& b) {
        a.add(b);
        return a;
      });
  m.fold_checked = true;
  m.fold_area_m2 = double(sums.cells) * cell_area;
  m.fold_height_field_m3 = sums.height_field_m3;
  m.fold_voxel_m3 = sums.height_field_m3 + sums.difference_m3;
  // The voxel models hold the ground where a height field folds: their figure
  // stands there. What it is known to: half the difference (measured on the
  // full-size example, docs/volume.md "Where height fields fold").
  m.volume_m3 += sums.difference_m3;
  m.measured_volume_m3 += sums.difference_m3;
  if (m.area_m2 > 0) m.mean_thickness_m = m.volume_m3 / m.area_m2;
  m.fold_sigma_m3 = 0.5 * std::abs(sums.difference_m3);
  settle_interval(m);
  log::info("volume: unit {}: {:.2f} m2 where the surfaces fold: {:.4f} m3 as height fields, {:.4f} m3 through the "
            "voxel models ({:+.4f} m3, {:+.2f} % of the unit)",
            s.unit, m.fold_area_m2, m.fold_height_field_m3, m.fold_voxel_m3, m.fold_difference_m3(),
            m.volume_m3 > 0 ? 100 * m.fold_difference_m3() / m.volume_m3 : 0.0);
}

}  // namespace

void check_folds(std::vector<UnitSolid>& solids, const std::vector<LayerSurface>& layers,
                 const std::map<std::string, std::filesystem::path>& level_sets, const VolumeOptions& options) {
  if (layers.empty()) return;
  // Each level set is read once and dropped after the last solid that needs it.
  std::vector<std::unique_ptr<LevelSetProbe>> open(layers.size());
  std::vector<std::size_t> last_use(layers.size(), 0);
  auto index_of = [&](const std::string& name) {
    return std::size_t(std::find_if(layers.begin(), layers.end(), [&](const auto& l) { return l.layer == name; }) -
                       layers.begin());
  };
  for (std::size_t k = 0; k < solids.size(); ++k) {
    if (const std::size_t t = index_of(solids[k].top_layer); t < layers.size()) last_use[t] = k;
    for (const auto& b : solids[k].bottom_layers)
      if (const std::size_t q = index_of(b); q < layers.size()) last_use[q] = k;
  }
  for (std::size_t k = 0; k < solids.size(); ++k) {
    std::vector<const LevelSetProbe*> probes(layers.size(), nullptr);
    std::vector<std::string> uses = solids[k].bottom_layers;
    uses.push_back(solids[k].top_layer);
    for (const auto& name : uses) {
      const std::size_t q = index_of(name);
      const auto path = level_sets.find(name);
      if (q >= layers.size() || path == level_sets.end()) continue;
      if (!open[q]) open[q] = std::make_unique<LevelSetProbe>(path->second);
      probes[q] = open[q].get();
    }
    check_solid(solids[k], layers, probes, options);
    for (std::size_t q = 0; q < layers.size(); ++q)
      if (last_use[q] <= k) open[q].reset();
  }
}

}  // namespace strata
