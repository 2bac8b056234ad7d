// Unit solids from layer surfaces: height-field differencing on the common grid,
// measures, closed meshes, and the Harris-matrix check.
#include "core/error.hpp"
#include "core/log.hpp"
#include "geometry/polygon.hpp"
#include "core/statistics.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "volume/connected_components.hpp"
#include "volume/significance.hpp"
#include "volume/volume.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>

namespace strata {
namespace {

using volume_detail::Components;
using volume_detail::connected_components;
using volume_detail::Connectivity;
using volume_detail::dilate;
using volume_detail::StableGround;
using volume_detail::two_sided_normal_quantile;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// The least factor the stable ground may apply to the stated per-cell sigmas
// (the full-size example measured 0.29-0.41 per bin: fused sigmas run high).
constexpr double kMinNoiseScale = 0.25;

bool finite(double v) { return std::isfinite(v); }

// The regions of cells where `sign` x thickness exceeds the level, in
// 8-connected regions of at least min_dug_area_m2 that hold a core (hysteresis,
// as Canny's edges: a cell whose thickness averaged over core_scale_m still
// exceeds its level; noise makes patches a few cm across that pass the per-cell
// test and vanish when averaged over 10 cm, while a deposit keeps its mean).
// Returns the mask; with `volumes`, each kept region's cells and volume (m3).
struct KeptRegion {
  std::vector<std::size_t> cells;
  double volume_m3 = 0;
};
std::vector<std::uint8_t> significant_regions(const std::vector<double>& t, const std::vector<double>& lod,
                                              const RasterGrid& g, const VolumeOptions& o, double sign,
                                              std::vector<KeptRegion>* kept = nullptr) {
  const std::size_t n = g.cells();
  const int nx = g.width, ny = g.height;
  std::vector<double> st(n);
  for (std::size_t c = 0; c < n; ++c) st[c] = sign * t[c];
  std::vector<std::uint8_t> mask(n, 0);
  for (std::size_t c = 0; c < n; ++c) mask[c] = st[c] > lod[c];  // false for NaN
  const std::size_t min_cells = std::size_t(std::ceil(o.min_dug_area_m2 / (g.cell * g.cell)));
  const int core_radius = int(std::lround(0.5 * o.core_scale_m / g.cell));
  const std::vector<double> mean = core_radius > 0 ? volume_detail::box_mean(st, nx, ny, core_radius) : st;
  const Components regions = connected_components(mask, nx, ny, Connectivity::eight);
  for (std::size_t k = 0; k < regions.count(); ++k) {
    const bool keep = regions.size(k) >= std::max<std::size_t>(min_cells, 1) &&
                      std::any_of(regions.begin(k), regions.end(k), [&](std::size_t c) { return mean[c] > lod[c]; });
    if (!keep) {
      for (auto c = regions.begin(k); c != regions.end(k); ++c) mask[*c] = 0;
    } else if (kept) {
      KeptRegion r{{regions.begin(k), regions.end(k)}, 0.0};
      for (std::size_t c : r.cells) r.volume_m3 += st[c] * g.cell * g.cell;
      kept->push_back(std::move(r));
    }
  }
  return mask;
}

// Where a unit without a footprint was dug, from its thickness per cell (NaN where
// a surface is missing) and its level of detection per cell: significant_regions,
// less the regions no larger than what noise makes (below), grown by up to
// edge_growth_m into 4-adjacent cells thicker than half their level (the thin
// edges the level would chop off; about one sigma, so noise does not grow it).
// The null: noise makes regions of either sign alike, an excavation only
// positive ones; so with `null_from_negative`, a positive region whose volume is
// no larger than the largest negative region's is noise (that bound is at most 1 %
// of the largest positive region's volume, so one raised feature, a spoil heap,
// cannot take away a unit's real parts).
std::vector<std::uint8_t> dug_cells(const std::vector<double>& t, const std::vector<double>& lod, const RasterGrid& g,
                                    const VolumeOptions& o, bool null_from_negative = false) {
  const std::size_t n = g.cells();
  const int nx = g.width, ny = g.height;
  std::vector<KeptRegion> positive, negative;
  std::vector<std::uint8_t> dug = significant_regions(t, lod, g, o, +1, null_from_negative ? &positive : nullptr);
  if (null_from_negative) {
    significant_regions(t, lod, g, o, -1, &negative);
    if (!positive.empty() && !negative.empty()) {
      auto by_volume = [](const KeptRegion& a, const KeptRegion& b) { return a.volume_m3 < b.volume_m3; };
      const double bound =
          std::min(std::max_element(negative.begin(), negative.end(), by_volume)->volume_m3,
                   0.01 * std::max_element(positive.begin(), positive.end(), by_volume)->volume_m3);
      for (const KeptRegion& r : positive)
        if (r.volume_m3 <= bound)
          for (std::size_t c : r.cells) dug[c] = 0;
    }
  }
  const int steps = int(std::floor(o.edge_growth_m / g.cell + 1e-9));
  std::vector<std::size_t> front, next;
  for (std::size_t c = 0; c < n; ++c)
    if (dug[c]) front.push_back(c);
  for (int step = 0; step < steps && !front.empty(); ++step) {
    next.clear();
    for (std::size_t c : front) {
      const int i = int(c % nx), j = int(c / nx);
      const std::size_t nb[4] = {c - 1, c + 1, c - nx, c + nx};
      const bool ok[4] = {i > 0, i + 1 < nx, j > 0, j + 1 < ny};
      for (int k = 0; k < 4; ++k)
        if (ok[k] && !dug[nb[k]] && t[nb[k]] > 0.5 * lod[nb[k]]) {
          dug[nb[k]] = 1;
          next.push_back(nb[k]);
        }
    }
    front.swap(next);
  }
  return dug;
}

// Adds to `dug` the holes it encloses (8-connected dug cells around, not
// reaching the grid's border) that hold no measured cell: a gap of the surfaces
// in the middle of a unit belongs to it; an island where both surfaces were
// measured and agree (a stone left standing) does not.
void add_unmeasured_holes(std::vector<std::uint8_t>& dug, const std::vector<double>& t,
                          const std::vector<std::uint8_t>& measured, const RasterGrid& g) {
  std::vector<std::uint8_t> open(dug.size());
  for (std::size_t c = 0; c < dug.size(); ++c) open[c] = !dug[c];
  const Components holes = connected_components(open, g.width, g.height, Connectivity::four);
  for (std::size_t k = 0; k < holes.count(); ++k) {
    const bool keep_out = std::any_of(holes.begin(k), holes.end(k), [&](std::size_t c) {
      const int i = int(c % std::size_t(g.width)), j = int(c / std::size_t(g.width));
      return measured[c] || !std::isfinite(t[c]) || i == 0 || j == 0 || i + 1 == g.width || j + 1 == g.height;
    });
    if (!keep_out)
      for (auto c = holes.begin(k); c != holes.end(k); ++c) dug[*c] = 1;
  }
}

// Per layer, the cells (measured or reliably filled) that lie above the last
// earlier layer known there by more than the level of detection of the two (stated sigmas, at least
// noise_threshold_m), in regions significant_regions keeps (as large as a dug
// region must be, with a core: chance cells of noise are not flagged): an
// excavation's surfaces only go down. Empty for the first layer, and for all
// when options.surfaces_only_go_down is off.
// A layer's height sigma per cell, metres: the fused surface's where it has one,
// else the layer's noise; an interpolated cell adds slope_error x its distance to
// measured data to its layer's median sigma.
class CellSigma {
 public:
  CellSigma(const std::vector<LayerSurface>& layers, double slope_error)
      : layers_(layers), slope_error_(slope_error), base_(layers.size()) {
    for (std::size_t k = 0; k < layers.size(); ++k) {
      std::vector<double> v;
      if (layers[k].z.has_sigma())
        for (std::size_t c = 0; c < layers[k].z.z.size(); ++c)
          if (finite(layers[k].z.sigma[c]) && !layers[k].filled(c)) v.push_back(layers[k].z.sigma[c]);
      base_[k] = v.empty() ? layers[k].noise_m : nearest_rank_quantile(v, 0.5);
    }
  }
  double operator()(std::size_t k, std::size_t c) const {
    const LayerSurface& l = layers_[k];
    if (l.filled(c)) return std::hypot(base_[k], slope_error_ * l.filled_distance_m[c]);
    if (l.z.has_sigma() && finite(l.z.sigma[c])) return l.z.sigma[c];
    return l.noise_m;
  }

 private:
  const std::vector<LayerSurface>& layers_;
  double slope_error_;
  std::vector<double> base_;  // per layer: median stated sigma of its measured cells
};

std::vector<std::vector<std::uint8_t>> risen_cells(const std::vector<LayerSurface>& layers, const RasterGrid& grid,
                                                   const CellSigma& cell_sigma, const VolumeOptions& options) {
  std::vector<std::vector<std::uint8_t>> risen(layers.size());
  if (!options.surfaces_only_go_down) return risen;
  const double zq = two_sided_normal_quantile(options.confidence);
  const std::size_t n = grid.cells();
  for (std::size_t k = 1; k < layers.size(); ++k) {
    const LayerSurface& l = layers[k];
    std::vector<double> rise(n, kNaN), lod(n, kNaN);
    std::vector<int> below(n, -1);
    // Measured, or filled no further than reliable_fill_m from measured cells (as
    // for deciding an extent: a ragged surface is mostly that).
    auto reliable = [&](const LayerSurface& s, std::size_t c) {
      return std::isfinite(s.z.z[c]) && (!s.filled(c) || s.filled_distance_m[c] <= options.reliable_fill_m);
    };
    for (std::size_t c = 0; c < n; ++c) {
      if (!reliable(l, c)) continue;
      for (std::size_t j = k; j-- > 0;) {
        const LayerSurface& e = layers[j];
        if (!reliable(e, c)) continue;
        rise[c] = l.z.z[c] - e.z.z[c];
        lod[c] = std::max(options.noise_threshold_m, zq * std::hypot(cell_sigma(k, c), cell_sigma(j, c)));
        below[c] = int(j);
        break;
      }
    }
    risen[k] = significant_regions(rise, lod, grid, options, +1);
    std::size_t count = 0;
    std::string names;
    for (std::size_t c = 0; c < n; ++c)
      if (risen[k][c]) {
        ++count;
        const std::string& e = layers[std::size_t(below[c])].layer;
        if (names.find(e) == std::string::npos) names += (names.empty() ? "" : ", ") + e;
      }
    if (count > 0)
      log::info("volume: layer {}: {:.3f} m2 measured above an earlier surface ({}) by more than their level of "
                "detection: an excavation only goes down, so these cells do not decide an extent",
                l.layer, double(count) * grid.cell * grid.cell, names);
  }
  return risen;
}

// One line: how sure a unit's volume is, and what would make it surer (the
// largest part of its uncertainty decides).
std::string volume_advice(const UnitMeasures& m) {
  const bool extent_from_data = m.extent_method == "significance";
  const double half = m.interval_high_m3 - m.volume_m3;
  std::string line = fmt::format("+/- {:.4f} m3 ({:.1f} %) at {:.0f} %", half,
                                 m.volume_m3 > 0 ? 100 * half / m.volume_m3 : 0.0, 100 * m.confidence);
  const double parts[] = {m.random_sigma_m3, m.systematic_sigma_m3, m.fill_sigma_m3, m.extent_sigma_m3,
                          m.smoothing_sigma_m3, m.fold_sigma_m3};
  const int largest = int(std::max_element(std::begin(parts), std::end(parts)) - std::begin(parts));
  switch (largest) {
    case 0:
      return line + fmt::format("; mostly the surfaces' own noise (level of detection {:.1f} mm): more, closer, "
                                "overlapping photos would make it surer", 1000 * m.median_lod_m);
    case 1:
      if (m.stable_area_m2 > 0)
        return line + fmt::format("; mostly the registration of its two surfaces (they differ by {:+.1f} mm on "
                                  "undisturbed ground): more markers or check markers would make it surer",
                                  1000 * m.stable_bias_m);
      return line + "; mostly the registration of its two surfaces, with no undisturbed ground to compare them on: "
                    "photograph some ground around the trench in every layer, or add check markers";
    case 2:
      return line + fmt::format("; mostly the gaps ({:.3f} m2 of its top or bottom interpolated): photos of the gaps "
                                "would make it surer", m.filled_area_m2);
    case 4:
      return line + "; mostly the reconstruction's rounding of edges and corners (walls, pit sides, steps): "
                    "closer photos, a finer ground sampling, would make it surer";
    case 5:
      return line + fmt::format("; mostly where its surfaces fold (walls, overhangs: the voxel models add {:+.4f} m3 "
                                "to the height fields there): photos looking straight at the faces would make it "
                                "surer", m.fold_difference_m3());
    default:
      return line + (extent_from_data ? "; mostly where its edge lies: a survey of the limit of excavation "
                                        "(--outline or --footprint) would make it surer"
                                      : "; mostly where its edge lies (thin deposits near the level of detection)");
  }
}

}  // namespace

void settle_interval(UnitMeasures& m) {
  const double z = two_sided_normal_quantile(m.confidence);
  m.volume_sigma_m3 = std::sqrt(m.random_sigma_m3 * m.random_sigma_m3 + m.systematic_sigma_m3 * m.systematic_sigma_m3 +
                                m.fill_sigma_m3 * m.fill_sigma_m3 + m.extent_sigma_m3 * m.extent_sigma_m3 +
                                m.smoothing_sigma_m3 * m.smoothing_sigma_m3 + m.fold_sigma_m3 * m.fold_sigma_m3);
  m.interval_low_m3 = m.volume_m3 - z * m.volume_sigma_m3;
  m.interval_high_m3 = m.volume_m3 + z * m.volume_sigma_m3;
  m.advice = volume_advice(m);
}

double sample_height(const HeightRaster<double>& f, double x, double y) {
  const RasterGrid& g = f.grid;
  if (g.width <= 0 || g.height <= 0) return kNaN;
  // Column and row in cell-centre units; rows grow southwards.
  const double u = (x - g.x_min) / g.cell - 0.5, v = (g.y_max - y) / g.cell - 0.5;
  if (u < -0.5 || v < -0.5 || u > g.width - 0.5 || v > g.height - 0.5) return kNaN;
  const int c0 = std::clamp(int(std::floor(u)), 0, std::max(g.width - 2, 0));
  const int r0 = std::clamp(int(std::floor(v)), 0, std::max(g.height - 2, 0));
  const int c1 = std::min(c0 + 1, g.width - 1), r1 = std::min(r0 + 1, g.height - 1);
  const double tu = std::clamp(u - c0, 0.0, 1.0), tv = std::clamp(v - r0, 0.0, 1.0);
  const double z00 = f.at(c0, r0), z10 = f.at(c1, r0), z01 = f.at(c0, r1), z11 = f.at(c1, r1);
  if (finite(z00) && finite(z10) && finite(z01) && finite(z11))
    return (1 - tv) * ((1 - tu) * z00 + tu * z10) + tv * ((1 - tu) * z01 + tu * z11);
  // At the edge of the known surface: the nearest centre, never an extrapolation
  // across a gap. Half-way between two rows, the northern one.
  const int cn = std::clamp(int(std::lround(u)), 0, g.width - 1);
  const int rn = std::clamp(int(std::ceil(v - 0.5)), 0, g.height - 1);
  return f.at(cn, rn);
}

HeightRaster<double> resample(const HeightRaster<double>& f, const RasterGrid& grid) {
  HeightRaster<double> out = HeightRaster<double>::empty(grid);
  for (int row = 0; row < grid.height; ++row)
    for (int col = 0; col < grid.width; ++col) out.at(col, row) = sample_height(f, grid.x_centre(col), grid.y_centre(row));
  return out;
}

void VolumeOptions::validate() const {
  if (!(noise_threshold_m >= 0 && noise_threshold_m <= 0.5))
    throw InputError(fmt::format("volume options: noise_threshold_m = {} is not in 0..0.5 m", noise_threshold_m));
  if (!(noise_correlation_m > 0 && noise_correlation_m <= 10))
    throw InputError(fmt::format("volume options: noise_correlation_m = {} is not in (0, 10] m", noise_correlation_m));
  if (!(min_dug_area_m2 >= 0 && min_dug_area_m2 <= 1))
    throw InputError(fmt::format("volume options: min_dug_area_m2 = {} is not in 0..1 m2", min_dug_area_m2));
  if (!(edge_growth_m >= 0 && edge_growth_m <= 0.5))
    throw InputError(fmt::format("volume options: edge_growth_m = {} is not in 0..0.5 m", edge_growth_m));
  if (!(max_thickness_quantile > 0 && max_thickness_quantile <= 1))
    throw InputError(
        fmt::format("volume options: max_thickness_quantile = {} is not in (0, 1]", max_thickness_quantile));
  if (!(confidence >= 0.5 && confidence <= 0.9999))
    throw InputError(fmt::format("volume options: confidence = {} is not in 0.5..0.9999", confidence));
  if (!(stable_buffer_m >= 0 && stable_buffer_m <= 5))
    throw InputError(fmt::format("volume options: stable_buffer_m = {} is not in 0..5 m", stable_buffer_m));
  if (!(core_scale_m >= 0 && core_scale_m <= 5))
    throw InputError(fmt::format("volume options: core_scale_m = {} is not in 0..5 m", core_scale_m));
  if (!(reliable_fill_m >= 0 && reliable_fill_m <= 10))
    throw InputError(fmt::format("volume options: reliable_fill_m = {} is not in 0..10 m", reliable_fill_m));
  if (!(normal_scale_m > 0 && normal_scale_m <= 5))
    throw InputError(fmt::format("volume options: normal_scale_m = {} is not in (0, 5] m", normal_scale_m));
  if (!(fold_slope_deg > 0 && fold_slope_deg < 90))
    throw InputError(fmt::format("volume options: fold_slope_deg = {} is not in (0, 90) degrees", fold_slope_deg));
  if (!(fold_reach_m >= 0 && fold_reach_m <= 1))
    throw InputError(fmt::format("volume options: fold_reach_m = {} is not in 0..1 m", fold_reach_m));
  if (!(coverage_radius_m >= 0 && coverage_radius_m <= 5))
    throw InputError(fmt::format("volume options: coverage_radius_m = {} is not in 0..5 m", coverage_radius_m));
  if (!(min_stable_area_m2 >= 0 && min_stable_area_m2 <= 1000))
    throw InputError(fmt::format("volume options: min_stable_area_m2 = {} is not in 0..1000 m2", min_stable_area_m2));
  if (!(fill.closing_m >= 0 && fill.closing_m <= 10))
    throw InputError(fmt::format("volume options: fill.closing_m = {} is not in 0..10 m", fill.closing_m));
  if (!(fill.slope_error >= 0 && fill.slope_error <= 10))
    throw InputError(fmt::format("volume options: fill.slope_error = {} is not in 0..10", fill.slope_error));
  if (!(fill.warn_fraction >= 0 && fill.warn_fraction <= 1))
    throw InputError(fmt::format("volume options: fill.warn_fraction = {} is not in 0..1", fill.warn_fraction));
  if (!fill.outline.empty() && fill.outline.size() < 3)
    throw InputError(fmt::format("volume options: the trench outline has {} vertices, a polygon needs 3",
                                 fill.outline.size()));
  for (const auto& [unit, poly] : footprints)
    if (poly.size() < 3)
      throw InputError(fmt::format("volume options: footprint of unit {} has {} vertices, a polygon needs 3",
                                   unit, poly.size()));
}

namespace {

using Polygon = std::vector<Eigen::Vector2d>;

// The layers a unit's solid lies between, as indices into the layers: its own
// (the first is its top) and the later layers of other units.
struct UnitLayers {
  std::vector<std::size_t> own, later;
};

UnitLayers unit_layers(const std::vector<LayerSurface>& layers, const std::string& unit) {
  UnitLayers u;
  std::size_t first = layers.size();
  for (std::size_t k = 0; k < layers.size(); ++k) {
    if (layers[k].unit == unit) {
      u.own.push_back(k);
      first = std::min(first, k);
    } else if (first < layers.size()) {
      u.later.push_back(k);
    }
  }
  return u;
}

// Per cell, a unit's top and bottom surface and what their difference is worth.
struct UnitDifference {
  std::vector<std::size_t> later;       // indices into the layers: the later layers of other units
  std::vector<int> top_of, bottom_of;   // per cell: index into the layers; into `later` for the bottom; -1 none
  std::vector<double> t;                // thickness, metres (NaN where a surface is missing)
  std::vector<double> sigma_d;          // stated one-sigma of top - bottom, random part, metres
  std::vector<std::uint8_t> measured;   // both surfaces measured (not interpolated)
  // The thickness where the extent may be decided from the data alone: both
  // surfaces measured, or interpolated no further than reliable_fill_m from
  // measured data (a fill across the trench edge mixes the trench floor into the
  // ground around it), and the top did not rise above an earlier surface.
  std::vector<double> eligible_t;
  std::vector<std::uint8_t> trusted;    // measured, and the top did not rise above an earlier surface
  bool per_cell = true;                 // every top and bottom had per-cell sigmas

  std::size_t top_layer(std::size_t c) const { return std::size_t(top_of[c]); }
  std::size_t bottom_layer(std::size_t c) const { return later[std::size_t(bottom_of[c])]; }
};

// Per cell, the top (first own layer with a height) and the bottom (first later
// layer of another unit with a height), and the thickness between them.
UnitDifference pair_surfaces(const std::vector<LayerSurface>& layers, const UnitLayers& u, std::size_t n) {
  UnitDifference d;
  d.later = u.later;
  d.top_of.assign(n, -1);
  d.bottom_of.assign(n, -1);
  d.t.assign(n, kNaN);
  for (std::size_t c = 0; c < n; ++c) {
    for (std::size_t k : u.own)
      if (finite(layers[k].z.z[c])) {
        d.top_of[c] = int(k);
        break;
      }
    if (d.top_of[c] < 0) continue;
    for (std::size_t q = 0; q < u.later.size(); ++q)
      if (finite(layers[u.later[q]].z.z[c])) {
        d.bottom_of[c] = int(q);
        break;
      }
    if (d.bottom_of[c] >= 0) d.t[c] = layers[d.top_layer(c)].z.z[c] - layers[d.bottom_layer(c)].z.z[c];
  }
  return d;
}

// The stated sigma of each cell's difference, which cells were measured, and
// which may decide the extent (see UnitDifference).
void judge_cells(UnitDifference& d, const std::vector<LayerSurface>& layers, const CellSigma& cell_sigma,
                 const std::vector<std::vector<std::uint8_t>>& risen, const VolumeOptions& options) {
  const std::size_t n = d.t.size();
  d.sigma_d.assign(n, kNaN);
  d.measured.assign(n, 0);
  for (std::size_t c = 0; c < n; ++c) {
    if (!finite(d.t[c])) continue;
    const LayerSurface& top = layers[d.top_layer(c)];
    const LayerSurface& bottom = layers[d.bottom_layer(c)];
    d.per_cell = d.per_cell && top.z.has_sigma() && bottom.z.has_sigma();
    d.sigma_d[c] = std::hypot(cell_sigma(d.top_layer(c), c), cell_sigma(d.bottom_layer(c), c));
    d.measured[c] = !top.filled(c) && !bottom.filled(c);
  }
  d.eligible_t = d.t;
  for (std::size_t c = 0; c < n; ++c) {
    if (d.measured[c] || !finite(d.t[c])) continue;
    const LayerSurface& top = layers[d.top_layer(c)];
    const LayerSurface& bottom = layers[d.bottom_layer(c)];
    const double dist = std::max(top.filled(c) ? double(top.filled_distance_m[c]) : 0.0,
                                 bottom.filled(c) ? double(bottom.filled_distance_m[c]) : 0.0);
    if (dist > options.reliable_fill_m) d.eligible_t[c] = kNaN;
  }
  d.trusted = d.measured;
  for (std::size_t c = 0; c < n; ++c)
    if (const auto& r = risen[std::size_t(std::max(d.top_of[c], 0))]; d.top_of[c] >= 0 && !r.empty() && r[c]) {
      d.trusted[c] = 0;
      d.eligible_t[c] = kNaN;
    }
}

// The squared relative vertical offset of the surfaces from the georeference
// (check-marker RMSE z: a shift of each surface), averaged over the cells with a
// thickness; m2.
double georeference_offset2(const UnitDifference& d, const std::vector<LayerSurface>& layers) {
  double g_top2 = 0, g_bot2 = 0;
  std::size_t k = 0;
  for (std::size_t c = 0; c < d.t.size(); ++c)
    if (finite(d.t[c])) {
      g_top2 += std::pow(layers[d.top_layer(c)].vertical_rmse_m, 2);
      g_bot2 += std::pow(layers[d.bottom_layer(c)].vertical_rmse_m, 2);
      ++k;
    }
  return k > 0 ? (g_top2 + g_bot2) / double(k) : 0.0;
}

// Where a unit was dug and the figures that decided it.
struct Extent {
  std::vector<double> factor;     // per cell, on the stated sigma (from the stable ground once judged)
  double offset2 = 0;             // squared relative offset of the surfaces, m2
  std::vector<double> lod;        // level of detection per cell, metres
  std::vector<std::uint8_t> dug;  // per cell
  StableGround ground;
};

// The level of detection per cell: z x sigma of the difference (the two surfaces'
// per-cell sigmas, scaled, and their relative offset), at least the threshold.
std::vector<double> detection_levels(const UnitDifference& d, const Extent& e, const VolumeOptions& options) {
  const double z = two_sided_normal_quantile(options.confidence);
  std::vector<double> lod(d.t.size(), kNaN);
  for (std::size_t c = 0; c < lod.size(); ++c)
    if (finite(d.sigma_d[c]))
      lod[c] = std::max(options.noise_threshold_m, z * std::sqrt(std::pow(e.factor[c] * d.sigma_d[c], 2) + e.offset2));
  return lod;
}

// The cells dug at these levels of detection: inside the footprint when there is
// one; else the significant cells, within the trench outline when there is one.
std::vector<std::uint8_t> where_dug(const UnitDifference& d, const std::vector<double>& lod, const Polygon* footprint,
                                    const RasterGrid& grid, const VolumeOptions& options) {
  const std::size_t n = d.t.size();
  const auto inside = [&](const Polygon& poly, std::size_t c) {
    const Eigen::Vector2d p = grid.centre(c);
    return inside_polygon(poly, p.x(), p.y());
  };
  std::vector<std::uint8_t> dug(n, 0);
  if (footprint) {
    for (std::size_t c = 0; c < n; ++c) dug[c] = finite(d.t[c]) && inside(*footprint, c);
    return dug;
  }
  if (!options.fill.outline.empty()) {
    dug = dug_cells(d.t, lod, grid, options);
    // Nothing was dug outside the limit of excavation: noise or clutter on the
    // ground around the trench is not a deposit.
    for (std::size_t c = 0; c < n; ++c)
      if (dug[c] && !inside(options.fill.outline, c)) dug[c] = 0;
    return dug;
  }
  // Without the limit, the extent is what the measurements show: cells where both
  // surfaces were measured or reliably filled (near measured data), then the holes
  // it encloses that hold no measurement (a gap in the middle).
  dug = dug_cells(d.eligible_t, lod, grid, options, true);
  // Interpolated cells beyond that distance join where they are significant
  // inside the morphological closing of that extent (a gap straddling the unit's
  // edge closes as the edge runs on), or in a hole it encloses.
  const int r = int(std::ceil(options.fill.closing_m / grid.cell - 1e-9));
  std::vector<std::uint8_t> closed = dilate(dug, grid.width, grid.height, r);
  for (auto& x : closed) x = !x;
  closed = dilate(closed, grid.width, grid.height, r);
  for (std::size_t c = 0; c < n; ++c)
    if (!closed[c] && !dug[c] && !d.measured[c] && d.t[c] > lod[c]) dug[c] = 1;
  add_unmeasured_holes(dug, d.t, d.trusted, grid);
  return dug;
}

// The share of cells within coverage_radius_m where both surfaces were measured:
// low at the ragged edge of a layer's photo coverage. Empty when not asked for.
std::vector<double> measured_coverage(const UnitDifference& d, const RasterGrid& grid, const VolumeOptions& options) {
  if (!(options.coverage_radius_m > 0)) return {};
  std::vector<double> ones(d.measured.size());
  for (std::size_t c = 0; c < ones.size(); ++c) ones[c] = d.measured[c] ? 1.0 : 0.0;
  return volume_detail::box_mean(ones, grid.width, grid.height,
                                 std::max(1, int(std::lround(options.coverage_radius_m / grid.cell))));
}

void log_stable_ground(const std::string& unit, const StableGround& ground) {
  std::string bins, coverage_bins;
  for (std::size_t b = 0; b < ground.by_sigma.at.size(); ++b)
    bins += fmt::format(" {:.1f} mm x {:.2f}", 1000 * ground.by_sigma.at[b], ground.by_sigma.factor[b]);
  for (std::size_t b = 0; b < ground.by_coverage.at.size(); ++b)
    coverage_bins += fmt::format(" {:.0f} % x {:.2f}", 100 * ground.by_coverage.at[b], ground.by_coverage.factor[b]);
  log::debug("volume: unit {}: stable ground {:.2f} m2, offset {:+.2f} mm (quadrants +/- {:.2f}), NMAD {:.2f} "
             "mm, L {:.1f} mm; stated sigma -> factor:{}; coverage -> factor:{}",
             unit, ground.area_m2, 1000 * ground.bias_m, 1000 * ground.offset_spread_m, 1000 * ground.nmad_m,
             1000 * ground.correlation_m, bins, coverage_bins.empty() ? " (one bin)" : coverage_bins);
}

// The stable ground (measured, away from the dug area) judges the stated sigmas,
// the offset and the correlation; the extent is found again with what it says,
// twice (the dug area moves the stable ground).
void judge_by_stable_ground(Extent& e, const UnitDifference& d, const Polygon* footprint, const RasterGrid& grid,
                            const VolumeOptions& options, const std::string& unit) {
  const std::size_t n = d.t.size();
  const int buffer = int(std::ceil(options.stable_buffer_m / grid.cell - 1e-9));
  const std::vector<double> coverage = measured_coverage(d, grid, options);
  const std::size_t min_cells = std::size_t(std::ceil(options.min_stable_area_m2 / (grid.cell * grid.cell)));
  for (int pass = 0; pass < 2; ++pass) {
    const std::vector<std::uint8_t> near = dilate(e.dug, grid.width, grid.height, buffer);
    std::vector<std::uint8_t> stable(n, 0);
    // (Risen cells stay: leaving out cells chosen by their difference would bias
    // the judge of that very difference.)
    for (std::size_t c = 0; c < n; ++c) stable[c] = d.measured[c] && !near[c];
    e.ground = volume_detail::judge_stable_ground(d.t, d.sigma_d, stable, coverage, grid, min_cells,
                                                  options.noise_correlation_m);
    if (!e.ground.used) break;
    // Never believe the surfaces more than four times as good as they state: the
    // stable ground lies around the trench, not in it.
    for (std::size_t c = 0; c < n; ++c)
      if (finite(d.sigma_d[c]))
        e.factor[c] = std::max(e.ground.factor(d.sigma_d[c], coverage.empty() ? kNaN : coverage[c]), kMinNoiseScale);
    log_stable_ground(unit, e.ground);
    const StableGround& g = e.ground;
    e.offset2 = g.bias_m * g.bias_m + g.bias_se_m * g.bias_se_m + g.offset_spread_m * g.offset_spread_m;
    e.lod = detection_levels(d, e, options);
    e.dug = where_dug(d, e.lod, footprint, grid, options);
  }
}

// Where the unit was dug: first at the levels the georeference figures give, then
// as the stable ground judges them.
Extent find_extent(const UnitDifference& d, const std::vector<LayerSurface>& layers, const Polygon* footprint,
                   const RasterGrid& grid, const VolumeOptions& options, const std::string& unit) {
  Extent e;
  e.factor.assign(d.t.size(), 1.0);
  e.offset2 = georeference_offset2(d, layers);
  e.lod = detection_levels(d, e, options);
  e.dug = where_dug(d, e.lod, footprint, grid, options);
  e.ground.correlation_m = options.noise_correlation_m;
  if (options.use_stable_ground) judge_by_stable_ground(e, d, footprint, grid, options, unit);
  return e;
}

// The slope of the mid-surface of the dug cells (half-way between top and
// bottom), along the grid over up to `reach` dug cells either side: the normal at
// the scale of normal_scale_m, not of one noisy cell.
class MidSurface {
 public:
  MidSurface(const UnitDifference& d, const Extent& e, const std::vector<LayerSurface>& layers, const RasterGrid& grid,
             double normal_scale_m)
      : d_(d), e_(e), layers_(layers), grid_(grid),
        reach_(std::max(1, int(std::lround(0.5 * normal_scale_m / grid.cell)))) {}

  // cos of the mid-surface's slope at dug cell c (gy runs southwards, along the
  // rows: only its square counts).
  double cos_slope(std::size_t c) const {
    const int col = int(c % grid_.width), row = int(c / grid_.width);
    const double gx = slope(col, row, 1, 0), gy = slope(col, row, 0, 1);
    return 1 / std::sqrt(1 + gx * gx + gy * gy);
  }

 private:
  double at(int col, int row) const {  // NaN off the dug cells
    if (col < 0 || row < 0 || col >= grid_.width || row >= grid_.height) return kNaN;
    const std::size_t c = grid_.index(col, row);
    return e_.dug[c] ? 0.5 * (layers_[d_.top_layer(c)].z.z[c] + layers_[d_.bottom_layer(c)].z.z[c]) : kNaN;
  }
  double slope(int col, int row, int dc, int dr) const {
    int a = 0, b = 0;
    while (a < reach_ && finite(at(col + (a + 1) * dc, row + (a + 1) * dr))) ++a;
    while (b < reach_ && finite(at(col - (b + 1) * dc, row - (b + 1) * dr))) ++b;
    if (a + b == 0) return 0.0;
    return (at(col + a * dc, row + a * dr) - at(col - b * dc, row - b * dr)) / ((a + b) * grid_.cell);
  }

  const UnitDifference& d_;
  const Extent& e_;
  const std::vector<LayerSurface>& layers_;
  const RasterGrid& grid_;
  int reach_;
};

// Sums over a unit's dug cells, for its measures.
struct DugSums {
  std::vector<std::size_t> bottom_count;  // per later layer: the cells it is the bottom of
  double fill_error = 0;     // m3: sum over filled cells of slope_error x distance x cell area
  double random2 = 0;        // sum over dug cells of cell area x (scaled sigma of the difference)^2
  double normal_sum = 0;     // m3: sum of thickness x cos(slope) x cell area
  double smoothing_sum = 0;  // m3: sum of the change of thickness under one more smoothing x cell area
  std::size_t filled_cells = 0;
  std::vector<double> thickness, normal_thickness, lods, factors;  // of every dug cell
};

// The solid's heights on its dug cells, its volume, count and thickness range,
// and the sums the rest of its measures come from.
DugSums sum_dug_cells(UnitSolid& s, const UnitDifference& d, const Extent& e, const std::vector<LayerSurface>& layers,
                      const std::vector<std::vector<double>>& smoothing, const RasterGrid& grid,
                      const VolumeOptions& options) {
  const double cell_area = grid.cell * grid.cell;
  const MidSurface mid(d, e, layers, grid, options.normal_scale_m);
  DugSums sums;
  sums.bottom_count.assign(d.later.size(), 0);
  UnitMeasures& m = s.measures;
  m.min_thickness_m = std::numeric_limits<double>::infinity();
  m.max_thickness_raw_m = -std::numeric_limits<double>::infinity();
  for (std::size_t c = 0; c < d.t.size(); ++c) {
    if (!e.dug[c]) continue;
    const LayerSurface& top = layers[d.top_layer(c)];
    const LayerSurface& bottom = layers[d.bottom_layer(c)];
    const double t = d.t[c];
    s.top.z[c] = top.z.z[c];
    s.bottom.z[c] = bottom.z.z[c];
    ++sums.bottom_count[std::size_t(d.bottom_of[c])];
    ++m.cells;
    m.volume_m3 += t * cell_area;
    (d.measured[c] ? m.measured_volume_m3 : m.filled_volume_m3) += t * cell_area;
    m.min_thickness_m = std::min(m.min_thickness_m, t);
    m.max_thickness_raw_m = std::max(m.max_thickness_raw_m, t);
    sums.thickness.push_back(t);
    sums.lods.push_back(e.lod[c]);
    sums.random2 += cell_area * std::pow(e.factor[c] * d.sigma_d[c], 2);
    sums.factors.push_back(e.factor[c]);
    const double cos_slope = mid.cos_slope(c);
    sums.normal_sum += t * cos_slope * cell_area;
    sums.normal_thickness.push_back(t * cos_slope);
    const auto& st = smoothing[d.top_layer(c)];
    const auto& sb = smoothing[d.bottom_layer(c)];
    if (!st.empty() && !sb.empty() && finite(st[c]) && finite(sb[c])) sums.smoothing_sum += (st[c] - sb[c]) * cell_area;
    if (top.filled(c) || bottom.filled(c)) {
      ++sums.filled_cells;
      const double dt = top.filled(c) ? top.filled_distance_m[c] : 0.0;
      const double db = bottom.filled(c) ? bottom.filled_distance_m[c] : 0.0;
      sums.fill_error += options.fill.slope_error * std::hypot(dt, db) * cell_area;
    }
  }
  return sums;
}

// Where the edge lies: the volume found with the level halved and doubled spans
// the choice; one sigma of a uniform error over that span, m3.
double extent_sigma(const UnitDifference& d, const Extent& e, const RasterGrid& grid, const VolumeOptions& options) {
  const double cell_area = grid.cell * grid.cell;
  auto volume_at = [&](double factor) {
    std::vector<double> l = e.lod;
    for (double& x : l) x *= factor;
    const std::vector<std::uint8_t> dug = where_dug(d, l, nullptr, grid, options);
    double v = 0;
    for (std::size_t c = 0; c < dug.size(); ++c)
      if (dug[c]) v += d.t[c] * cell_area;
    return v;
  };
  return std::abs(volume_at(0.5) - volume_at(2.0)) / (2 * std::sqrt(3.0));
}

// The measures of a solid whose dug cells are summed: area, thicknesses, and the
// parts of its volume's uncertainty.
void settle_measures(UnitSolid& s, DugSums& sums, const UnitDifference& d, const Extent& e, const Polygon* footprint,
                     const RasterGrid& grid, const VolumeOptions& options) {
  const double cell_area = grid.cell * grid.cell;
  UnitMeasures& m = s.measures;
  m.confidence = options.confidence;
  m.extent_method = footprint                     ? "footprint"
                    : options.fill.outline.empty() ? "significance"
                                                   : "significance within the outline";
  m.per_cell_sigma = d.per_cell;
  m.noise_scale = sums.factors.empty() ? 1.0 : nearest_rank_quantile(sums.factors, 0.5);
  m.correlation_m = e.ground.correlation_m;
  if (e.ground.used) {
    m.stable_area_m2 = e.ground.area_m2;
    m.stable_bias_m = e.ground.bias_m;
    m.stable_nmad_m = e.ground.nmad_m;
    m.stable_offset_spread_m = e.ground.offset_spread_m;
  }
  if (m.cells == 0) {
    m.min_thickness_m = m.max_thickness_raw_m = 0;
    log::warn("volume: unit {}: no cell differs significantly ({:.0f} %) between {} and the later surfaces", s.unit,
              100 * options.confidence, s.top_layer);
    return;
  }
  const double nc = double(m.cells);
  m.area_m2 = nc * cell_area;
  m.mean_thickness_m = m.volume_m3 / m.area_m2;
  m.max_thickness_m = nearest_rank_quantile(sums.thickness, options.max_thickness_quantile);
  m.mean_normal_thickness_m = sums.normal_sum / m.area_m2;
  m.max_normal_thickness_m = nearest_rank_quantile(sums.normal_thickness, options.max_thickness_quantile);
  m.median_lod_m = nearest_rank_quantile(sums.lods, 0.5);
  m.filled_area_m2 = double(sums.filled_cells) * cell_area;
  m.filled_fraction = m.filled_area_m2 / m.area_m2;
  m.fill_sigma_m3 = sums.fill_error;
  // Random errors are correlated over about pi L^2 (Gaussian model), at least one
  // cell, at most the unit.
  const double corr_area = std::clamp(volume_detail::correlation_area_m2(m.correlation_m), cell_area, m.area_m2);
  m.random_sigma_m3 = std::sqrt(corr_area * sums.random2);
  m.systematic_sigma_m3 = m.area_m2 * std::sqrt(e.offset2);
  if (!footprint) m.extent_sigma_m3 = extent_sigma(d, e, grid, options);
  m.smoothing_sigma_m3 = std::abs(sums.smoothing_sum);
  settle_interval(m);
  if (m.filled_fraction > options.fill.warn_fraction)
    log::warn("volume: unit {}: {:.0f} % of its area ({:.3f} of {:.3f} m2) has an interpolated top or bottom "
              "(gaps in the dense surfaces); its volume is uncertain by +/- {:.4f} m3",
              s.unit, 100 * m.filled_fraction, m.filled_area_m2, m.area_m2, m.volume_sigma_m3);
}

// The solid of one unit that has later surfaces.
UnitSolid unit_solid(const std::string& unit, const UnitLayers& u, const std::vector<LayerSurface>& layers,
                     const CellSigma& cell_sigma, const std::vector<std::vector<std::uint8_t>>& risen,
                     const std::vector<std::vector<double>>& smoothing, const RasterGrid& grid,
                     const VolumeOptions& options) {
  const auto it = options.footprints.find(unit);
  const Polygon* footprint = it != options.footprints.end() ? &it->second : nullptr;
  UnitSolid s;
  s.unit = unit;
  s.top_layer = layers[u.own.front()].layer;
  s.top = HeightRaster<double>::empty(grid);
  s.bottom = HeightRaster<double>::empty(grid);
  UnitDifference d = pair_surfaces(layers, u, grid.cells());
  judge_cells(d, layers, cell_sigma, risen, options);
  const Extent e = find_extent(d, layers, footprint, grid, options, unit);
  DugSums sums = sum_dug_cells(s, d, e, layers, smoothing, grid, options);
  for (std::size_t q = 0; q < d.later.size(); ++q)
    if (sums.bottom_count[q] > 0) s.bottom_layers.push_back(layers[d.later[q]].layer);
  settle_measures(s, sums, d, e, footprint, grid, options);
  return s;
}

}  // namespace

std::vector<UnitSolid> build_unit_solids(const std::vector<LayerSurface>& layers, const VolumeOptions& options) {
  options.validate();
  if (layers.empty()) return {};
  const RasterGrid& grid = layers.front().z.grid;
  for (const auto& l : layers) STRATA_CHECK(l.z.grid == grid, "layer {} is not on the common grid", l.layer);
  // Units in the order of their first layer.
  std::vector<std::string> units;
  for (const auto& l : layers)
    if (std::find(units.begin(), units.end(), l.unit) == units.end()) units.push_back(l.unit);
  const CellSigma cell_sigma(layers, options.fill.slope_error);
  // Each layer's change under one more smoothing at its own scale (the shape part
  // of the interval); empty where the scale is unknown.
  std::vector<std::vector<double>> smoothing(layers.size());
  for (std::size_t k = 0; k < layers.size(); ++k)
    if (layers[k].smoothing_m > 0) smoothing[k] = volume_detail::smoothing_residual(layers[k].z, layers[k].smoothing_m);
  // An excavation only takes away: where a layer was measured above the last
  // earlier layer measured there by more than their level of detection (stated
  // sigmas), it is wrong there (a reconstruction's error at the ragged edge of its
  // photos) or shows something put down since (spoil, a bucket, a board). Such a
  // cell may not decide the extent of the unit whose top it is, nor fill a hole of it.
  const std::vector<std::vector<std::uint8_t>> risen = risen_cells(layers, grid, cell_sigma, options);
  std::vector<UnitSolid> solids;
  for (const auto& unit : units) {
    const UnitLayers u = unit_layers(layers, unit);
    if (u.later.empty()) {
      log::debug("volume: unit {} has no later surface (not dug yet): no solid", unit);
      continue;
    }
    solids.push_back(unit_solid(unit, u, layers, cell_sigma, risen, smoothing, grid, options));
  }
  return solids;
}

// ---- closed mesh ------------------------------------------------------------------

DenseMesh unit_solid_mesh(const UnitSolid& solid) {
  const RasterGrid& grid = solid.top.grid;
  const int nx = grid.width, ny = grid.height;
  const double h = grid.cell;
  // Here j counts cells from the southern edge (row ny - 1 - j), so that j, as y,
  // grows northwards and the quadrants and corners below go counter-clockwise.
  auto top = [&](int i, int j) { return solid.top.at(i, ny - 1 - j); };
  auto bottom = [&](int i, int j) { return solid.bottom.at(i, ny - 1 - j); };
  auto dug = [&](int i, int j) {
    return i >= 0 && j >= 0 && i < nx && j < ny && finite(top(i, j));
  };
  DenseMesh mesh;
  // Corner (ci, cj) lies between cells (ci-1..ci, cj-1..cj). Around a corner the
  // dug cells form one or two groups (two only for a diagonal pair); each group
  // gets its own top and bottom vertex. Quadrant q: 0 SW, 1 SE, 2 NE, 3 NW.
  // Vertex index per (corner, quadrant): -1 until created.
  const std::size_t ncorners = std::size_t(nx + 1) * std::size_t(ny + 1);
  std::vector<std::array<int, 4>> top_vertex(ncorners, {-1, -1, -1, -1});
  std::vector<std::array<int, 4>> bottom_vertex(ncorners, {-1, -1, -1, -1});
  constexpr int kDi[4] = {-1, 0, 0, -1}, kDj[4] = {-1, -1, 0, 0};
  for (int cj = 0; cj <= ny; ++cj)
    for (int ci = 0; ci <= nx; ++ci) {
      std::array<bool, 4> d;
      for (int q = 0; q < 4; ++q) d[q] = dug(ci + kDi[q], cj + kDj[q]);
      // Group id per quadrant: quadrants q and q+1 (cyclic) share an edge.
      std::array<int, 4> group{-1, -1, -1, -1};
      int groups = 0;
      for (int q = 0; q < 4; ++q) {
        if (!d[q] || group[q] >= 0) continue;
        group[q] = groups;
        for (int step : {1, 3}) {  // walk both ways around the corner
          int r = q;
          while (true) {
            const int next = (r + step) % 4;
            if (!d[next] || group[next] >= 0) break;
            group[next] = groups;
            r = next;
          }
        }
        ++groups;
      }
      const std::size_t corner = std::size_t(cj) * std::size_t(nx + 1) + ci;
      for (int g = 0; g < groups; ++g) {
        double zt = 0, zb = 0;
        int n = 0;
        for (int q = 0; q < 4; ++q)
          if (group[q] == g) {
            zt += top(ci + kDi[q], cj + kDj[q]);
            zb += bottom(ci + kDi[q], cj + kDj[q]);
            ++n;
          }
        const double x = grid.x_min + ci * h, y = grid.y_min() + cj * h;
        const int vt = int(mesh.vertices.size());
        mesh.vertices.emplace_back(x, y, zt / n);
        mesh.vertices.emplace_back(x, y, zb / n);
        for (int q = 0; q < 4; ++q)
          if (group[q] == g) {
            top_vertex[corner][q] = vt;
            bottom_vertex[corner][q] = vt + 1;
          }
      }
    }
  // Corners of cell (i, j), counter-clockwise seen from above: SW, SE, NE, NW; the
  // cell is quadrant NE of its SW corner, NW of its SE corner, SW of its NE corner
  // and SE of its NW corner.
  auto corner_index = [&](int ci, int cj) { return std::size_t(cj) * std::size_t(nx + 1) + ci; };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (!dug(i, j)) continue;
      const std::array<std::size_t, 4> corners{corner_index(i, j), corner_index(i + 1, j),
                                               corner_index(i + 1, j + 1), corner_index(i, j + 1)};
      constexpr int kQuadrant[4] = {2, 3, 0, 1};
      std::array<int, 4> t, b;
      for (int k = 0; k < 4; ++k) {
        t[k] = top_vertex[corners[k]][kQuadrant[k]];
        b[k] = bottom_vertex[corners[k]][kQuadrant[k]];
      }
      // Top faces outward = up: counter-clockwise from above. Bottom: reversed.
      mesh.faces.push_back({t[0], t[1], t[2]});
      mesh.faces.push_back({t[0], t[2], t[3]});
      mesh.faces.push_back({b[0], b[2], b[1]});
      mesh.faces.push_back({b[0], b[3], b[2]});
      // Walls on edges towards undug neighbours. Edge k goes from corner k to k+1
      // (counter-clockwise seen from above), outward to the right of that direction.
      constexpr int kNi[4] = {0, 1, 0, -1}, kNj[4] = {-1, 0, 1, 0};  // S, E, N, W neighbours
      for (int k = 0; k < 4; ++k) {
        if (dug(i + kNi[k], j + kNj[k])) continue;
        const int k1 = (k + 1) % 4;
        mesh.faces.push_back({b[k], b[k1], t[k1]});
        mesh.faces.push_back({b[k], t[k1], t[k]});
      }
    }
  return mesh;
}

// ---- Harris matrix against geometry ---------------------------------------------

void CheckOptions::validate() const {
  if (!(tolerance_m >= 0 && tolerance_m <= 1))
    throw InputError(fmt::format("check options: tolerance_m = {} is not in 0..1 m", tolerance_m));
  if (!(min_area_m2 >= 0 && min_area_m2 <= 100))
    throw InputError(fmt::format("check options: min_area_m2 = {} is not in 0..100 m2", min_area_m2));
  if (!(depth_quantile > 0 && depth_quantile <= 1))
    throw InputError(fmt::format("check options: depth_quantile = {} is not in (0, 1]", depth_quantile));
}

std::string StratigraphicConflict::describe(const Eigen::Vector3d& site_origin) const {
  std::string s = fmt::format(
      "conflict: {} is recorded above {} but lies {:.3f} m below it ({:.0f}th percentile; at most {:.3f} m, at E "
      "{:.2f} N {:.2f}) over {:.3f} m2 in {} region{}",
      later, earlier, amount_m, 100 * depth_quantile, max_amount_m, where.x() + site_origin.x(),
      where.y() + site_origin.y(), area_m2, regions, regions == 1 ? "" : "s");
  if (ignored_regions > 0)
    s += fmt::format("; {} smaller region{} ({:.4f} m2) ignored", ignored_regions, ignored_regions == 1 ? "" : "s",
                     ignored_area_m2);
  return s;
}

std::string StratigraphicConflict::describe_ignored() const {
  return fmt::format("ignored: {} lies below {} (recorded above it) by up to {:.3f} m, but only in {} region{} "
                     "smaller than the minimum area ({:.4f} m2 in all)",
                     later, earlier, ignored_max_amount_m, ignored_regions, ignored_regions == 1 ? "" : "s",
                     ignored_area_m2);
}

std::size_t StratigraphicCheck::ignored_regions() const {
  std::size_t n = 0;
  for (const auto* list : {&conflicts, &ignored})
    for (const auto& c : *list) n += c.ignored_regions;
  return n;
}

double StratigraphicCheck::ignored_area_m2() const {
  double a = 0;
  for (const auto* list : {&conflicts, &ignored})
    for (const auto& c : *list) a += c.ignored_area_m2;
  return a;
}

StratigraphicCheck check_stratigraphy(const HarrisMatrix& matrix, const std::vector<LayerSurface>& layers,
                                      const std::vector<UnitSolid>& solids, const CheckOptions& options) {
  options.validate();
  StratigraphicCheck out;
  if (layers.empty()) return out;
  // Each unit with geometry: its top and where it is present.
  struct Presence {
    std::string unit;
    const HeightRaster<double>* top = nullptr;  // NaN where absent
  };
  std::vector<Presence> units;
  for (const auto& s : solids) units.push_back({s.unit, &s.top});
  for (const auto& l : layers) {
    const bool known = std::any_of(units.begin(), units.end(), [&](const Presence& p) { return p.unit == l.unit; });
    if (!known) units.push_back({l.unit, &l.z});  // not dug: its (first) layer surface
  }
  const RasterGrid& g = layers.front().z.grid;
  const double cell_area = g.cell * g.cell;
  // A region counts from this many cells (at least one).
  const std::size_t min_cells =
      std::max<std::size_t>(1, std::size_t(std::ceil(options.min_area_m2 / cell_area - 1e-9)));
  std::vector<double> depth(g.cells());
  std::vector<std::uint8_t> below(g.cells());
  std::vector<double> values;
  for (const auto& a : units)
    for (const auto& b : units) {
      if (a.unit == b.unit) continue;
      bool later = false;
      try {
        later = matrix.later_than(a.unit, b.unit);
      } catch (const Error&) {
        continue;  // a layer's unit unknown to the matrix: nothing recorded
      }
      if (!later) continue;
      STRATA_CHECK(a.top->z.size() == g.cells() && b.top->z.size() == g.cells(), "units {} and {} are not on one grid",
                   a.unit, b.unit);
      // Where the later unit's top lies below the earlier one's by more than the
      // tolerance, and by how much (metres).
      for (std::size_t c = 0; c < g.cells(); ++c) {
        depth[c] = b.top->z[c] - a.top->z[c];
        below[c] = depth[c] > options.tolerance_m;  // false for NaN
      }
      const Components regions = connected_components(below, g.width, g.height, Connectivity::eight);
      if (regions.count() == 0) continue;
      StratigraphicConflict c;
      c.later = a.unit;
      c.earlier = b.unit;
      c.depth_quantile = options.depth_quantile;
      for (std::size_t k = 0; k < regions.count(); ++k) {
        values.clear();
        std::size_t deepest = *regions.begin(k);
        for (auto q = regions.begin(k); q != regions.end(k); ++q) {
          values.push_back(depth[*q]);
          if (depth[*q] > depth[deepest]) deepest = *q;
        }
        const double area = double(values.size()) * cell_area;
        if (values.size() < min_cells) {  // an outlier spike, not a contiguous contradiction
          ++c.ignored_regions;
          c.ignored_area_m2 += area;
          c.ignored_max_amount_m = std::max(c.ignored_max_amount_m, depth[deepest]);
          continue;
        }
        const double robust = nearest_rank_quantile(values, options.depth_quantile);
        log::debug("check: {} below {}: region of {:.4f} m2, {:.0f}th percentile {:.3f} m, deepest {:.3f} m", a.unit,
                   b.unit, area, 100 * options.depth_quantile, robust, depth[deepest]);
        ++c.regions;
        c.area_m2 += area;
        if (robust > c.amount_m) {
          c.amount_m = robust;
          c.max_amount_m = depth[deepest];
          c.where = g.centre(deepest);
        }
      }
      (c.regions > 0 ? out.conflicts : out.ignored).push_back(c);
    }
  std::sort(out.conflicts.begin(), out.conflicts.end(),
            [](const auto& x, const auto& y) { return x.amount_m > y.amount_m; });
  return out;
}

}  // namespace strata
