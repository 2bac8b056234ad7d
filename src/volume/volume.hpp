#pragma once
// Volumetric stratigraphy: layer surfaces on a common site grid, unit
// solids between them, their measures (volume, area, thickness, uncertainty), a
// closed mesh of each solid, and the check of the Harris matrix against geometry.
//
// Frames: every coordinate is the site frame (site CRS minus the site origin,
// metres, double) unless a name says "crs". Heights are site-frame z.
//
// A unit's solid is the space between the surface recorded when its top was
// exposed (its first layer) and the surface recorded after it was removed (the
// first later layer of another unit that has a height there), limited to where
// the unit was dug: where the two differ by more than a noise threshold, or
// inside a footprint polygon given by the user.
//
// Standard library, Eigen and the plain structs of dense/ only: OpenVDB lives in
// voxels.cpp, GDAL in section.cpp and the raster importer and exporter.
#include "dense/dense.hpp"  // DenseMesh
#include "geometry/raster.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace strata {

class HarrisMatrix;

// Bilinear height at (x, y) in the site frame from the four surrounding cell
// centres; when some of them are NaN, the nearest centre (NaN when it is NaN);
// NaN outside the raster.
double sample_height(const HeightRaster<double>& f, double x, double y);
// The heights resampled onto another grid with sample_height (no sigma).
HeightRaster<double> resample(const HeightRaster<double>& f, const RasterGrid& grid);

// One recorded surface state on the common grid.
struct LayerSurface {
  std::string layer;        // layer name, e.g. "L2"
  std::string unit;         // unit code of the layer (the unit whose top it shows)
  HeightRaster<double> z;   // metres, site frame, north-up; NaN where the surface is unknown
  std::string source;       // file it came from, for messages and details_json
  // Uncertainty of the surface, metres, one sigma:
  double noise_m = 0.003;   // per-cell random noise (dense surface vs sparse points)
  double vertical_rmse_m = 0;  // vertical georeference error (check or control RMSE z); 0 = unknown
  // Horizontal scale over which the reconstruction averaged the ground (one sigma
  // of an equivalent Gaussian: the stereo matching window on the ground), metres;
  // 0 = unknown (a surface from elsewhere). See UnitMeasures::smoothing_sigma_m3.
  double smoothing_m = 0;
  // Gap filling (fill_surface_gaps): per cell, 0 where the height was measured,
  // else the distance in metres to the nearest measured cell of this layer (the
  // height was interpolated). Empty: nothing was filled.
  std::vector<float> filled_distance_m;
  bool filled(std::size_t cell) const { return !filled_distance_m.empty() && filled_distance_m[cell] > 0; }
};

// Filling the gaps of a dense surface (trench sides, shadows, pit walls) before
// differencing, so that a unit's volume does not silently lose the area where one
// of its surfaces was not reconstructed.
//
// Where: the fill domain is the trench outline. Given (`outline`, or the unit
// footprints), it is those polygons; otherwise it is derived from the data: the
// union of every layer's measured cells, closed morphologically with a disc of
// radius `closing_m` (bridges ragged edges and bays narrower than 2 x closing_m;
// never grows beyond the convex hull of the data) and with its enclosed holes
// filled. Cells outside the domain are never filled: no extrapolation outward.
// How: a membrane (Laplace) fill: inside the domain the missing heights solve
// Laplace's equation with the measured heights around them as boundary values
// (zero slope across the domain's border), the smoothest surface through the
// surrounding known heights, as GDAL's FillNodata or a surveyor's interpolation
// would; a gap with no measured neighbour at all stays empty.
// Uncertainty: a filled height is off by up to `slope_error` x (distance to the
// nearest measured cell); summed linearly over a unit's filled cells (the error
// of one gap is one correlated error) and added in quadrature to sigma_V.
struct GapFillOptions {
  bool enabled = true;
  double closing_m = 0.25;      // metres: radius of the morphological closing of the data union
  double slope_error = 0.05;    // metres of height error per metre from measured data (5 %)
  double warn_fraction = 0.10;  // warn when more than this fraction of a unit's area was filled
  // Trench outline (limit of excavation) in site-frame XY, metres; empty: derived.
  std::vector<Eigen::Vector2d> outline;
};

// What fill_surface_gaps did.
struct GapFillSummary {
  double domain_area_m2 = 0;               // area of the fill domain
  std::map<std::string, double> filled_area_m2;     // per layer name
  std::map<std::string, double> measured_area_m2;   // per layer name, inside the domain
};

struct VolumeOptions {
  // Surfaces closer than this count as "not dug": metres. Above the noise of a
  // photogrammetric surface (2-3 mm), below any real deposit.
  double noise_threshold_m = 0.005;
  // Spatial correlation length of surface noise, metres: random errors average
  // over patches of this size, not over single cells (sigma_V formula below).
  // Used when no stable ground can say it (see use_stable_ground).
  double noise_correlation_m = 0.05;
  // Optional footprint per unit code: a polygon in site-frame XY (metres). Inside,
  // every cell with both surfaces counts (signed thickness: noise does not bias
  // the volume); outside, nothing. Without one, the significance test decides.
  std::map<std::string, std::vector<Eigen::Vector2d>> footprints;
  // Without a footprint, a unit's solid is the cells thicker than their level of
  // detection (see `confidence`), less isolated specks smaller than
  // `min_dug_area_m2` (noise), grown by up to `edge_growth_m` into adjacent cells
  // thicker than half their level, so the thin edges of a unit (a feather edge,
  // the foot of the trench side) are not chopped off.
  double min_dug_area_m2 = 0.0025;  // 5 x 5 cm
  // A region of significant cells counts only when its thickness averaged over
  // a square of this side still exceeds the level somewhere (hysteresis: the
  // noise patches of the ground around a trench do not), metres; 0 = off.
  double core_scale_m = 0.10;
  double edge_growth_m = 0.0;      // metres
  // The reported maximum thickness is this quantile of the dug cells' thickness
  // (the thickness exceeded over only 1 % of the unit's area): a dense surface
  // keeps a few outlier cells (wall faces, pit edges) whose single-cell maximum is
  // metres off; UnitMeasures::max_thickness_raw_m keeps that maximum.
  double max_thickness_quantile = 0.99;
  // Significance: a cell was dug where its thickness exceeds the level of
  // detection, z x sigma of the difference of its two surfaces (z the two-sided
  // normal quantile of `confidence`), and at least noise_threshold_m. The volume's
  // interval is stated at the same confidence.
  double confidence = 0.95;
  // Stable ground (the cells neither unit's solid touches, at least
  // `stable_buffer_m` from the dug area, where both surfaces were measured) judges
  // the stated sigmas, the surfaces' relative offset and the correlation distance
  // of their errors, when it covers at least `min_stable_area_m2`.
  bool use_stable_ground = true;
  // Without a trench outline, an interpolated cell may decide the extent only
  // this close to measured data, metres (beyond, only inside the closing of the
  // extent so found, by fill.closing_m, or in a hole it encloses).
  double reliable_fill_m = 0.05;
  // The local normal (thickness along it) is taken over this distance, metres.
  double normal_scale_m = 0.05;
  double stable_buffer_m = 0.10;
  double min_stable_area_m2 = 0.05;
  // The stable ground also judges the sigmas by coverage: the share of cells
  // within this distance, metres, where both surfaces were measured (the ragged
  // edge of a layer's photos is seen by few, grazing views). 0 = by stated sigma
  // only. 10 cm: a few matching windows at a layer's GSD, small beside a unit.
  double coverage_radius_m = 0.10;
  // An excavation only takes away: a layer measured significantly above an earlier
  // one is taken as wrong there (see build_unit_solids). Off for a site where
  // material is put back between recordings (backfill, a spoil heap in the area).
  bool surfaces_only_go_down = true;
  // Where height fields fold (check_folds): dug cells whose top or bottom is
  // steeper than fold_slope_deg, and every cell within fold_reach_m of them (the
  // ground under an overhang is flat in a height field), are integrated again
  // through the layers' voxel models.
  double fold_slope_deg = 60;
  double fold_reach_m = 0.05;
  GapFillOptions fill;

  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct UnitMeasures {
  double volume_m3 = 0;        // sum of thickness x cell area over dug cells
  double area_m2 = 0;          // horizontal area of the dug cells
  double mean_thickness_m = 0; // volume / area
  double min_thickness_m = 0;  // thinnest dug cell
  // Robust maximum: the VolumeOptions::max_thickness_quantile (99 %) quantile of
  // the dug cells' thickness, what tables and reports show as the maximum.
  double max_thickness_m = 0;
  double max_thickness_raw_m = 0;  // thickest single dug cell (dense outliers included)
  // One-sigma volume uncertainty, m3:
  //   sigma_V^2 = A^2 (g_top^2 + g_bottom^2) + A L^2 (n_top^2 + n_bottom^2)
  // g: vertical georeference error of each surface (a shift of the whole surface),
  // n: per-cell noise averaging over A / L^2 independent patches of side L.
  double volume_sigma_m3 = 0;
  std::size_t cells = 0;
  // Gap filling: area of the dug cells where the top or the bottom height was
  // interpolated, its fraction of the area, and its share of volume_sigma_m3 (m3).
  double filled_area_m2 = 0;
  double filled_fraction = 0;
  double fill_sigma_m3 = 0;

  // The interval and its parts (m3). volume_sigma_m3 is the quadrature sum of:
  // random (per-cell surface noise, correlated over correlation_m), systematic
  // (the surfaces' relative vertical offset over the whole area), fill (above),
  // smoothing (below) and extent (the volumes found with the level of detection halved and
  // doubled span where the edge lies; a uniform error over that span).
  double confidence = 0.95;
  double interval_low_m3 = 0, interval_high_m3 = 0;
  double random_sigma_m3 = 0, systematic_sigma_m3 = 0, extent_sigma_m3 = 0;
  // Smoothing (shape) part: a reconstruction that averages the ground over
  // LayerSurface::smoothing_m rounds convex edges down and fills concave corners
  // (the foot of a wall, the floor of a pit), and the stable ground around the
  // trench cannot see it. Its size is what smoothing each surface once more at
  // that scale moves the unit's volume, |sum over dug cells of
  // (G*top - top) - (G*bottom - bottom)| x cell area; kept as an uncertainty, not
  // applied as a correction (its sign does not hold for every unit).
  double smoothing_sigma_m3 = 0;
  double measured_volume_m3 = 0;  // over cells where both surfaces were measured
  double filled_volume_m3 = 0;    // over cells where one of them was interpolated
  std::string extent_method;      // "footprint", "significance", "significance within the outline"
  double median_lod_m = 0;        // median level of detection over the dug cells, metres
  // What the stable ground said (StableGround in significance.hpp); cells 0 = not used.
  double stable_area_m2 = 0;
  double stable_bias_m = 0;       // median top - bottom on stable ground
  double stable_nmad_m = 0;
  double stable_offset_spread_m = 0;  // spread of the offset between the four quadrants around the unit
  double noise_scale = 1;         // median factor applied to the dug cells' stated sigmas
  double correlation_m = 0;       // correlation distance used for the random part
  bool per_cell_sigma = false;    // the surfaces carried per-cell sigmas (fusion), else layer figures
  // Thickness along the local normal of the unit's mid-surface (steep faces;
  // slope over normal_scale_m): the mean and the p99 of thickness x cos(slope).
  double mean_normal_thickness_m = 0;
  double max_normal_thickness_m = 0;
  // The check against the voxel model where height fields fold (check_folds):
  // over the fold cells (steep dug cells and those within fold_reach_m), the
  // volume between the two surfaces as height fields and as integrated through
  // both layers' voxel models (signed distances along vertical lines; where a
  // voxel was not observed, the height field). fold_checked is false when a layer
  // has no voxel model (a DTM from elsewhere) or nothing is steep.
  // The voxel models' figure replaces the height fields' there (volume_m3
  // includes the difference), known to about half the difference: the sixth part
  // of the interval, fold_sigma_m3 = |difference| / 2 (docs/volume.md, measured).
  bool fold_checked = false;
  double fold_area_m2 = 0;
  double fold_height_field_m3 = 0;
  double fold_voxel_m3 = 0;
  double fold_sigma_m3 = 0;
  double fold_difference_m3() const { return fold_voxel_m3 - fold_height_field_m3; }
  // One line: how sure the figure is and what would make it surer.
  std::string advice;
};

// The solid of one unit on the common grid: heights where the unit was dug, NaN
// elsewhere (top and bottom are NaN together).
struct UnitSolid {
  std::string unit;                         // unit code
  std::string top_layer;                    // layer whose surface is the top
  std::vector<std::string> bottom_layers;   // layers that gave the bottom somewhere
  HeightRaster<double> top, bottom;         // metres, site frame, north-up
  UnitMeasures measures;

  bool dug(std::size_t cell) const { return top.z[cell] == top.z[cell]; }  // not NaN
  double thickness(std::size_t cell) const { return top.z[cell] - bottom.z[cell]; }
};

// Fills the gaps of every layer surface inside the fill domain (see
// GapFillOptions; the unit footprints belong to the domain too) and records the
// filled cells in LayerSurface::filled_distance_m. All layers on one grid.
GapFillSummary fill_surface_gaps(std::vector<LayerSurface>& layers, const VolumeOptions& options);

// Builds the solid of every unit that has a layer and a later surface below it,
// in the order of the units' first layers. `layers` is in capture order, all on
// one grid. Units whose layer is the last (not dug yet) have no solid.
std::vector<UnitSolid> build_unit_solids(const std::vector<LayerSurface>& layers,
                                         const VolumeOptions& options);

// Volume sigma from its parts in quadrature, the interval at m.confidence, and the
// advice line (what would make the figure surer). After any part changed.
void settle_interval(UnitMeasures& m);

// The check of every solid against the voxel model where height fields fold (see
// UnitMeasures::fold_*): corrects volume_m3, mean and measured volume, interval. `level_sets` maps layer names to their surface.vdb; a
// solid whose top or bottom layer has none is left unchecked. Reads each file once.
void check_folds(std::vector<UnitSolid>& solids, const std::vector<LayerSurface>& layers,
                 const std::map<std::string, std::filesystem::path>& level_sets, const VolumeOptions& options);

// Closed triangle mesh of a solid (site frame): top and bottom surfaces through
// the cell corners (corner height = mean of the adjacent dug cells, so it is a
// trapezoid-rule surface, not the raster's flat cells) and vertical walls on the
// boundary of the dug area. Cells touching only diagonally get separate corner
// vertices so that the mesh stays 2-manifold. Outward faces counter-clockwise.
DenseMesh unit_solid_mesh(const UnitSolid& solid);

// ---- Harris matrix against geometry

struct CheckOptions {
  double tolerance_m = 0.01;    // a height difference below this is no contradiction
  // A contradiction is a contiguous area: 8-connected cells where the later top
  // lies lower by more than tolerance_m, reported when a region covers at least
  // this much (0.02 m2, 200 cm2: about 14 x 14 cm, a patch an excavator can find
  // and check with a trowel; 800 cells of 5 mm). Smaller regions are outlier
  // spikes of a dense surface (single cells to a few cm2 along wall faces and pit
  // edges on the example) and are counted as ignored, never dropped silently.
  double min_area_m2 = 0.02;
  // The depth of a region is this quantile of the height difference over its
  // cells, not its single worst cell (itself often an outlier spike).
  double depth_quantile = 0.95;

  void validate() const;  // InputError naming the field
};

// A recorded relation "later above earlier" that the geometry contradicts: where
// both units are present, the later unit's top lies below the earlier unit's top
// over at least one region of CheckOptions::min_area_m2.
struct StratigraphicConflict {
  std::string later, earlier;   // unit codes: the matrix says `later` is above `earlier`
  // Over the reported region with the largest robust depth: its depth_quantile of
  // how far `later` lies below `earlier` (metres), its deepest cell (metres) and
  // that cell's place (site frame XY).
  double amount_m = 0;
  double max_amount_m = 0;
  Eigen::Vector2d where = Eigen::Vector2d::Zero();
  double depth_quantile = 0.95;  // the quantile amount_m is
  double area_m2 = 0;           // horizontal area of the reported regions, m2
  std::size_t regions = 0;      // regions of at least min_area_m2
  // Regions of this pair below min_area_m2: how many, their area (m2) and the
  // largest height difference in them (metres).
  std::size_t ignored_regions = 0;
  double ignored_area_m2 = 0;
  double ignored_max_amount_m = 0;
  std::string describe(const Eigen::Vector3d& site_origin) const;  // one line, CRS coordinates
  std::string describe_ignored() const;  // one line for a pair with only small regions
};

struct StratigraphicCheck {
  std::vector<StratigraphicConflict> conflicts;  // regions >= min area; largest amount first
  std::vector<StratigraphicConflict> ignored;    // pairs whose every region was below the min area
  std::size_t ignored_regions() const;           // over all pairs
  double ignored_area_m2() const;                // m2, over all pairs
};

// For every pair of units with geometry where the matrix says one is later
// (above, cuts, fills, abuts, transitively), compares their tops where both are
// present. A unit is present where its solid is; a unit with a layer but no
// solid (not dug yet) is present wherever its layer has a surface.
StratigraphicCheck check_stratigraphy(const HarrisMatrix& matrix, const std::vector<LayerSurface>& layers,
                                      const std::vector<UnitSolid>& solids, const CheckOptions& options);

}  // namespace strata
