#pragma once
// Internal to src/volume: the statistics that make a surface difference a
// measurement (Wheaton et al. 2010, DEMs of difference; Rolstad et al. 2009 and
// Hugonnet et al. 2022, errors estimated on stable terrain):
// - the two-sided normal quantile of a confidence level (the level of detection
//   is z x sigma of the difference);
// - the ground that did not change between two surfaces (around the unit, where
//   neither surface was interpolated) as the judge of their stated uncertainty:
//   its median difference is the surfaces' relative offset, the spread of its
//   standardised differences scales the per-cell sigmas, and its variogram gives
//   the distance over which their errors are correlated.
#include "volume/volume.hpp"

#include <cstdint>
#include <vector>

namespace strata::volume_detail {

// z with P(|N(0,1)| <= z) = confidence, for confidence in (0, 1).
double two_sided_normal_quantile(double confidence);

// The area over which errors correlated over `correlation_m` (the distance at
// which their correlation falls to 1/e) act as one: the integral of a Gaussian
// correlation model over the plane, pi L^2. (An exponential model would give
// 2 pi L^2; the errors of fused depth maps are smooth over their matching
// windows, which the Gaussian model describes better.)
double correlation_area_m2(double correlation_m);

// A factor on the stated sigma as a function of one predictor of quality, read in
// bins of the stable ground: linear between the bins' medians `at`, the end bins'
// factor beyond them; `fallback` when there are no bins.
struct FactorBins {
  std::vector<double> at, factor;
  double operator()(double x, double fallback) const;
};

// What the stable ground between a unit's top and bottom surfaces says.
struct StableGround {
  std::size_t cells = 0;       // cells used
  double area_m2 = 0;
  double bias_m = 0;           // median of top - bottom: their relative vertical offset
  double bias_se_m = 0;        // its standard error (correlated cells, see below)
  double offset_spread_m = 0;  // standard deviation of the four quadrants' medians about the unit
  double nmad_m = 0;           // 1.4826 x median absolute deviation of the differences
  double scale = 1;            // NMAD of (difference - bias) / stated sigma: >1 = sigmas too small
  // The same, as a function of two predictors of quality (heteroscedasticity,
  // standardised one predictor after the other, as Hugonnet et al. 2022 do):
  // - by_sigma: the stable cells in bins of equal count by stated sigma, each
  //   bin's median stated sigma and NMAD / that median;
  // - by_coverage: what is left, by the share of measured cells around the cell
  //   (the ragged edge of a layer's photo coverage, seen by few and grazing
  //   views, disagrees more than its stated sigma says): each bin's median
  //   coverage and the NMAD of the differences standardised by by_sigma.
  FactorBins by_sigma, by_coverage;
  // The factor for a cell of this stated sigma and coverage (NaN coverage: the
  // coverage factor is 1).
  double factor(double stated_sigma_m, double coverage) const;
  double correlation_m = 0;    // e-folding distance of the standardised differences' correlation
  bool used = false;           // enough cells to judge (else the georeference figures are used)
};

// `difference`: top - bottom per cell (NaN where unknown); `sigma`: the stated
// one-sigma of that difference per cell; `stable`: the cells that may serve
// (both surfaces measured, not dug, away from the dug area); `coverage`: the
// share of measured cells around each cell, 0-1 (empty: not judged). Needs
// `min_cells`; `fallback_correlation_m` is kept when the variogram cannot be read.
StableGround judge_stable_ground(const std::vector<double>& difference, const std::vector<double>& sigma,
                                 const std::vector<std::uint8_t>& stable, const std::vector<double>& coverage,
                                 const RasterGrid& grid, std::size_t min_cells, double fallback_correlation_m);

// Mean of the finite values within `radius_cells` (square neighbourhood) of
// every cell; NaN where there is none.
std::vector<double> box_mean(const std::vector<double>& values, int nx, int ny, int radius_cells);

// G * z - z per cell: the change of a height field smoothed once more by an
// isotropic Gaussian of `sigma_m` (normalised over the finite cells, kernel to 3
// sigma); NaN where z is NaN or less than half the kernel's weight is known.
std::vector<double> smoothing_residual(const HeightRaster<double>& z, double sigma_m);
// Sets every cell within `radius_cells` (square neighbourhood) of a set cell.
std::vector<std::uint8_t> dilate(const std::vector<std::uint8_t>& mask, int nx, int ny, int radius_cells);

}  // namespace strata::volume_detail
