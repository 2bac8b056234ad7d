// Level of detection and stable-ground statistics of surface differences.
#include "volume/significance.hpp"

#include "core/statistics.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numbers>

namespace strata::volume_detail {
namespace {

constexpr double kMadToSigma = 1.4826;
// Standardised differences beyond this are clipped before the variogram: a few
// outlier cells (spikes of a dense surface) must not set the correlation.
constexpr double kClip = 4.0;
// Bins of stated sigma for the heteroscedastic factor, and the cells a bin needs.
constexpr std::size_t kSigmaBins = 8;
constexpr std::size_t kMinCellsPerBin = 500;
// Upper edges of the bins of coverage (share of measured cells around a cell).
// Fixed, not of equal count: most stable cells are fully covered (coverage 1,
// all tied) and the ragged edge, the few cells this is for, must get bins of its
// own. A bin short of kMinCellsPerBin joins the next, better covered one.
constexpr double kCoverageEdges[] = {0.5, 0.7, 0.85, 0.95};

double nmad_of(const std::vector<double>& v, double centre) {
  std::vector<double> dev;
  dev.reserve(v.size());
  for (double x : v) dev.push_back(std::abs(x - centre));
  return kMadToSigma * median(std::move(dev));
}

// Sum of the values within `r` cells (square neighbourhood) of every cell:
// running sums along rows, then along columns. Shared by dilate() and box_mean().
std::vector<double> window_sums(const std::vector<double>& in, int nx, int ny, int r) {
  std::vector<double> rows(in.size()), out(in.size());
  auto pass = [r](const std::vector<double>& from, std::vector<double>& to, int len, int lines, std::ptrdiff_t stride,
                  std::ptrdiff_t line_stride) {
    for (int l = 0; l < lines; ++l) {
      const std::ptrdiff_t base = l * line_stride;
      double acc = 0;
      for (int k = 0; k < std::min(r, len); ++k) acc += from[std::size_t(base + k * stride)];
      for (int k = 0; k < len; ++k) {
        if (k + r < len) acc += from[std::size_t(base + (k + r) * stride)];
        if (k - r - 1 >= 0) acc -= from[std::size_t(base + (k - r - 1) * stride)];
        to[std::size_t(base + k * stride)] = acc;
      }
    }
  };
  pass(in, rows, nx, ny, 1, nx);
  pass(rows, out, ny, nx, nx, 1);
  return out;
}

}  // namespace

double correlation_area_m2(double correlation_m) { return std::numbers::pi * correlation_m * correlation_m; }

double two_sided_normal_quantile(double confidence) {
  STRATA_CHECK(confidence > 0 && confidence < 1, "confidence {} is not in (0, 1)", confidence);
  // P(|N| <= z) = erf(z / sqrt 2): increasing in z, found by bisection.
  double lo = 0, hi = 40;
  for (int it = 0; it < 200 && hi - lo > 1e-12; ++it) {
    const double mid = 0.5 * (lo + hi);
    (std::erf(mid / std::numbers::sqrt2) < confidence ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

std::vector<std::uint8_t> dilate(const std::vector<std::uint8_t>& mask, int nx, int ny, int radius_cells) {
  if (radius_cells <= 0) return mask;
  const std::vector<double> count = window_sums(std::vector<double>(mask.begin(), mask.end()), nx, ny, radius_cells);
  std::vector<std::uint8_t> out(mask.size());
  for (std::size_t c = 0; c < mask.size(); ++c) out[c] = count[c] > 0.5;
  return out;
}

std::vector<double> box_mean(const std::vector<double>& values, int nx, int ny, int radius_cells) {
  const std::size_t n = values.size();
  std::vector<double> finite_values(n, 0), ones(n, 0);
  for (std::size_t c = 0; c < n; ++c)
    if (std::isfinite(values[c])) finite_values[c] = values[c], ones[c] = 1;
  const std::vector<double> sum = window_sums(finite_values, nx, ny, radius_cells);
  const std::vector<double> count = window_sums(ones, nx, ny, radius_cells);
  std::vector<double> mean(n, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t c = 0; c < n; ++c)
    if (count[c] > 0.5) mean[c] = sum[c] / count[c];
  return mean;
}

namespace {

// Separable convolution with a symmetric kernel (k[0] the centre), rows then
// columns; cells beyond the grid count as zero.
std::vector<double> convolve(const std::vector<double>& v, int nx, int ny, const std::vector<double>& k) {
  const int r = int(k.size()) - 1;
  std::vector<double> rows(v.size(), 0), out(v.size(), 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      double acc = 0;
      for (int d = -r; d <= r; ++d)
        if (i + d >= 0 && i + d < nx) acc += k[std::size_t(std::abs(d))] * v[std::size_t(j) * nx + (i + d)];
      rows[std::size_t(j) * nx + i] = acc;
    }
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      double acc = 0;
      for (int d = -r; d <= r; ++d)
        if (j + d >= 0 && j + d < ny) acc += k[std::size_t(std::abs(d))] * rows[std::size_t(j + d) * nx + i];
      out[std::size_t(j) * nx + i] = acc;
    }
  return out;
}

}  // namespace

std::vector<double> smoothing_residual(const HeightRaster<double>& z, double sigma_m) {
  const std::size_t n = z.z.size();
  std::vector<double> residual(n, std::numeric_limits<double>::quiet_NaN());
  if (!(sigma_m > 0) || n == 0) return residual;
  const double s = sigma_m / z.grid.cell;  // cells
  const int r = std::max(1, int(std::ceil(3 * s)));
  std::vector<double> k(std::size_t(r) + 1);
  double total = 0;
  for (int d = 0; d <= r; ++d) total += (d ? 2 : 1) * (k[std::size_t(d)] = std::exp(-0.5 * d * d / (s * s)));
  for (double& w : k) w /= total;
  std::vector<double> values(n, 0), ones(n, 0);
  for (std::size_t c = 0; c < n; ++c)
    if (std::isfinite(z.z[c])) values[c] = z.z[c], ones[c] = 1;
  const std::vector<double> sum = convolve(values, z.grid.width, z.grid.height, k);
  const std::vector<double> weight = convolve(ones, z.grid.width, z.grid.height, k);
  for (std::size_t c = 0; c < n; ++c)
    if (ones[c] > 0 && weight[c] >= 0.5) residual[c] = sum[c] / weight[c] - z.z[c];
  return residual;
}

double FactorBins::operator()(double x, double fallback) const {
  if (at.empty()) return fallback;
  if (!(x > at.front())) return factor.front();  // NaN x too: the end bin
  if (x >= at.back()) return factor.back();
  const auto it = std::upper_bound(at.begin(), at.end(), x);
  const std::size_t k = std::size_t(it - at.begin());
  const double span = at[k] - at[k - 1];
  const double w = span > 0 ? (x - at[k - 1]) / span : 0.0;
  return (1 - w) * factor[k - 1] + w * factor[k];
}

double StableGround::factor(double stated_sigma_m, double coverage) const {
  const double f = by_sigma(stated_sigma_m, scale);
  return std::isfinite(coverage) ? f * by_coverage(coverage, 1.0) : f;
}

namespace {

// The cells that may judge: stable, with a difference and a stated sigma; in grid order.
std::vector<std::size_t> judging_cells(const std::vector<double>& difference, const std::vector<double>& sigma,
                                       const std::vector<std::uint8_t>& stable) {
  std::vector<std::size_t> cells;
  for (std::size_t c = 0; c < stable.size(); ++c)
    if (stable[c] && std::isfinite(difference[c]) && sigma[c] > 0) cells.push_back(c);
  return cells;
}

// How much the offset varies around the unit: the standard deviation of the
// medians of the four quadrants about the judging cells' centroid. A warp or tilt
// of one surface against the other shows as a spread of these; the unit inside
// may see any of them. 0 when fewer than two quadrants hold enough cells.
double offset_spread(const std::vector<std::size_t>& cells, const std::vector<double>& difference, const RasterGrid& grid,
                     std::size_t min_cells) {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (std::size_t c : cells) centroid += grid.centre(c);
  centroid /= double(cells.size());
  std::vector<double> quadrant[4];
  for (std::size_t c : cells) {
    const Eigen::Vector2d p = grid.centre(c);
    quadrant[(p.x() > centroid.x() ? 1 : 0) + (p.y() > centroid.y() ? 2 : 0)].push_back(difference[c]);
  }
  std::vector<double> medians;
  for (auto& q : quadrant)
    if (q.size() >= std::max<std::size_t>(min_cells / 4, 2)) medians.push_back(median(q));
  if (medians.size() < 2) return 0;
  double mean = 0, var = 0;
  for (double m : medians) mean += m / double(medians.size());
  for (double m : medians) var += (m - mean) * (m - mean) / double(medians.size() - 1);
  return std::sqrt(var);
}

// The factor per bin of stated sigma: each bin's median stated sigma and the NMAD
// of its differences about the bias over that median.
FactorBins factor_by_sigma(const std::vector<std::size_t>& cells, const std::vector<double>& difference,
                           const std::vector<double>& sigma, double bias_m) {
  std::vector<std::pair<double, double>> by_sigma;  // (stated sigma, difference - bias)
  for (std::size_t c : cells) by_sigma.emplace_back(sigma[c], difference[c] - bias_m);
  // By stated sigma only: within equal sigmas the cells keep their grid order
  // (sorting by the difference too would split a bin's spread between bins).
  std::stable_sort(by_sigma.begin(), by_sigma.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  FactorBins bins_out;
  const std::size_t bins = std::min<std::size_t>(kSigmaBins, by_sigma.size() / kMinCellsPerBin);
  std::size_t hi = 0;
  for (std::size_t b = 0; b < bins && hi < by_sigma.size(); ++b) {
    // A bin never splits equal sigmas (with one stated sigma everywhere, bins of
    // equal count would be bands of rows, the first one's factor taken for all).
    const std::size_t lo = hi;
    hi = std::max(lo + 1, (b + 1) * by_sigma.size() / bins);
    while (hi < by_sigma.size() && by_sigma[hi].first == by_sigma[hi - 1].first) ++hi;
    std::vector<double> stated, dev;
    for (std::size_t k = lo; k < hi; ++k) {
      stated.push_back(by_sigma[k].first);
      dev.push_back(by_sigma[k].second);
    }
    const double median_sigma = median(stated);
    bins_out.at.push_back(median_sigma);
    bins_out.factor.push_back(nmad_of(dev, 0.0) / median_sigma);
  }
  return bins_out;
}

// Of the differences standardised by the sigma bins, the factor per bin of
// coverage (fixed edges, kCoverageEdges); none when it says nothing the sigma
// bins did not (one bin, or a bin without spread).
FactorBins factor_by_coverage(const std::vector<std::size_t>& cells, const std::vector<double>& difference,
                              const std::vector<double>& sigma, const std::vector<double>& coverage,
                              const StableGround& s) {
  constexpr std::size_t kBins = std::size(kCoverageEdges) + 1;
  std::vector<double> cov[kBins], dev[kBins];
  for (std::size_t c : cells) {
    if (!std::isfinite(coverage[c])) continue;
    const double scaled = s.by_sigma(sigma[c], s.scale) * sigma[c];
    if (!(scaled > 0)) continue;  // noise-free surfaces (synthetic truth): nothing to judge
    const std::size_t b = std::size_t(std::upper_bound(std::begin(kCoverageEdges), std::end(kCoverageEdges),
                                                       coverage[c]) - std::begin(kCoverageEdges));
    cov[b].push_back(coverage[c]);
    dev[b].push_back((difference[c] - s.bias_m) / scaled);
  }
  FactorBins bins;
  for (std::size_t b = 0; b < kBins; ++b) {
    if (cov[b].size() < kMinCellsPerBin && b + 1 < kBins) {  // too few: into the next bin
      cov[b + 1].insert(cov[b + 1].end(), cov[b].begin(), cov[b].end());
      dev[b + 1].insert(dev[b + 1].end(), dev[b].begin(), dev[b].end());
      continue;
    }
    if (cov[b].size() < kMinCellsPerBin) continue;
    bins.at.push_back(median(cov[b]));
    bins.factor.push_back(nmad_of(dev[b], 0.0));
  }
  const bool spread =
      std::all_of(bins.factor.begin(), bins.factor.end(), [](double f) { return std::isfinite(f) && f > 0; });
  if (bins.at.size() < 2 || !spread) return {};
  return bins;
}

// Correlation of the standardised differences `u` (NaN off the judging cells),
// scaled to unit spread by the ground's factors and clipped, along rows and
// columns at growing lags: rho(h) = 1 - gamma(h) / variance; the correlation
// distance L is where rho falls to 1/e. `fallback_m` when it cannot be read.
double correlation_length(std::vector<double> u, const StableGround& s, const std::vector<double>& sigma,
                          const std::vector<double>& coverage, const RasterGrid& grid, double fallback_m) {
  const std::size_t n = grid.cells();
  double var = 0;
  std::size_t count = 0;
  for (std::size_t c = 0; c < n; ++c)
    if (double& x = u[c]; std::isfinite(x)) {
      const double f = s.factor(sigma[c], coverage.size() == n ? coverage[c] : std::nan(""));
      x = f > 0 ? std::clamp(x / f, -kClip, kClip) : 0.0;
      var += x * x;
      ++count;
    }
  var /= double(count);
  const int lags[] = {1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256};
  double prev_h = 0, prev_rho = 1;
  for (int h : lags) {
    if (h >= std::max(grid.width, grid.height)) break;
    double sum = 0;
    std::size_t pairs = 0;
    for (int j = 0; j < grid.height; ++j)
      for (int i = 0; i < grid.width; ++i) {
        const double a = u[std::size_t(j) * grid.width + i];
        if (!std::isfinite(a)) continue;
        if (i + h < grid.width) {
          const double b = u[std::size_t(j) * grid.width + i + h];
          if (std::isfinite(b)) sum += (a - b) * (a - b), ++pairs;
        }
        if (j + h < grid.height) {
          const double b = u[std::size_t(j + h) * grid.width + i];
          if (std::isfinite(b)) sum += (a - b) * (a - b), ++pairs;
        }
      }
    if (pairs < 100 || !(var > 0)) break;
    const double rho = 1 - 0.5 * sum / double(pairs) / var;
    if (rho < std::exp(-1.0)) {
      const double t = (prev_rho - std::exp(-1.0)) / std::max(prev_rho - rho, 1e-12);
      return (prev_h + t * (h - prev_h)) * grid.cell;
    }
    prev_h = h;
    prev_rho = rho;
  }
  return prev_h > 0 ? prev_h * grid.cell : fallback_m;  // correlated beyond the longest lag read
}

}  // namespace

StableGround judge_stable_ground(const std::vector<double>& difference, const std::vector<double>& sigma,
                                 const std::vector<std::uint8_t>& stable, const std::vector<double>& coverage,
                                 const RasterGrid& grid, std::size_t min_cells, double fallback_correlation_m) {
  StableGround s;
  s.correlation_m = fallback_correlation_m;
  const std::size_t n = grid.cells();
  const std::vector<std::size_t> cells = judging_cells(difference, sigma, stable);
  std::vector<double> d;
  for (std::size_t c : cells) d.push_back(difference[c]);
  s.cells = cells.size();
  s.area_m2 = double(s.cells) * grid.cell * grid.cell;
  if (s.cells < std::max<std::size_t>(min_cells, 2)) return s;
  s.used = true;
  s.bias_m = median(d);
  s.nmad_m = nmad_of(d, s.bias_m);
  s.offset_spread_m = offset_spread(cells, difference, grid, min_cells);
  // Standardised differences: the stated sigmas' judge.
  std::vector<double> u(n, std::numeric_limits<double>::quiet_NaN()), z;
  for (std::size_t c : cells) {
    u[c] = (difference[c] - s.bias_m) / sigma[c];
    z.push_back(u[c]);
  }
  s.scale = nmad_of(z, 0.0);
  if (!(s.scale > 0)) s.scale = 0;  // noise-free surfaces (synthetic truth)
  s.by_sigma = factor_by_sigma(cells, difference, sigma, s.bias_m);
  if (coverage.size() == n && !s.by_sigma.at.empty())
    s.by_coverage = factor_by_coverage(cells, difference, sigma, coverage, s);
  if (s.scale > 0) s.correlation_m = correlation_length(std::move(u), s, sigma, coverage, grid, s.correlation_m);
  const double corr_area = std::max(grid.cell * grid.cell, correlation_area_m2(s.correlation_m));
  s.bias_se_m = s.nmad_m * std::sqrt(std::min(1.0, corr_area / s.area_m2));
  return s;
}

}  // namespace strata::volume_detail
