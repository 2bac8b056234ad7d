// Gap filling of layer surfaces before differencing: the fill domain (trench
// outline), a membrane (Laplace) interpolation of the missing heights inside it,
// and the distance of every filled cell to measured data (its uncertainty).
#include "core/error.hpp"
#include "core/log.hpp"
#include "geometry/polygon.hpp"
#include "volume/connected_components.hpp"
#include "volume/distance_transform.hpp"
#include "volume/volume.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {
namespace {
using volume_detail::Components;
using volume_detail::connected_components;
using volume_detail::Connectivity;
using volume_detail::distance_transform;

constexpr double kInf = std::numeric_limits<double>::infinity();

// Exact squared Euclidean distance transform of one line (Felzenszwalb and
// Huttenlocher, "Distance transforms of sampled functions", 2012): d[q] =
// min_p (q - p)^2 + f[p], and site[q] = the minimising p; f = inf means "no site".
void distance_1d(const std::vector<double>& f, std::vector<double>& d, std::vector<int>& site) {
  const int n = int(f.size());
  std::vector<int> v(std::size_t(n) + 1);       // sites of the parabolas in the lower envelope
  std::vector<double> z(std::size_t(n) + 2);    // boundaries between them
  int k = -1;                                   // index of the last parabola
  for (int q = 0; q < n; ++q) {
    if (f[q] == kInf) continue;
    double s = -kInf;
    while (k >= 0) {
      const int p = v[k];
      s = ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * (q - p));
      if (s > z[k]) break;
      --k;
    }
    if (k < 0) s = -kInf;
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = kInf;
  }
  d.assign(n, kInf);
  site.assign(n, -1);
  if (k < 0) return;
  int e = 0;
  for (int q = 0; q < n; ++q) {
    while (z[e + 1] < q) ++e;
    d[q] = double(q - v[e]) * (q - v[e]) + f[v[e]];
    site[q] = v[e];
  }
}

// Cells of `mask` not 4-connected to the grid border through unset cells are set:
// the holes the mask encloses.
void fill_enclosed_holes(std::vector<std::uint8_t>& mask, int nx, int ny) {
  std::vector<std::uint8_t> unset(mask.size());
  for (std::size_t c = 0; c < mask.size(); ++c) unset[c] = !mask[c];
  const Components gaps = connected_components(unset, nx, ny, Connectivity::four);
  for (std::size_t k = 0; k < gaps.count(); ++k) {
    const bool open = std::any_of(gaps.begin(k), gaps.end(k), [&](std::size_t c) {
      const int i = int(c % nx), j = int(c / nx);
      return i == 0 || j == 0 || i + 1 == nx || j + 1 == ny;
    });
    if (!open)
      for (auto c = gaps.begin(k); c != gaps.end(k); ++c) mask[*c] = 1;
  }
}

// The fill domain on the grid (see GapFillOptions).
std::vector<std::uint8_t> fill_domain(const std::vector<LayerSurface>& layers, const RasterGrid& g,
                                      const VolumeOptions& o) {
  std::vector<std::uint8_t> domain(g.cells(), 0);
  if (!o.fill.outline.empty()) {
    for (std::size_t c = 0; c < g.cells(); ++c) {
      const Eigen::Vector2d p = g.centre(c);
      domain[c] = inside_polygon(o.fill.outline, p.x(), p.y());
    }
  } else {
    // Union of the measured cells, closed with a disc: dilation = within r of the
    // union, erosion = farther than r from what is outside the dilation.
    std::vector<std::uint8_t> data(g.cells(), 0);
    for (const auto& l : layers)
      for (std::size_t c = 0; c < g.cells(); ++c)
        if (std::isfinite(l.z.z[c]) && !l.filled(c)) data[c] = 1;
    const double r = o.fill.closing_m / g.cell;  // cells
    std::vector<double> d;
    distance_transform(data, g.width, g.height, d, nullptr);
    std::vector<std::uint8_t> beyond(g.cells(), 0);  // outside the dilation
    for (std::size_t c = 0; c < g.cells(); ++c) beyond[c] = d[c] > r;
    distance_transform(beyond, g.width, g.height, d, nullptr);  // inf when the dilation covers the grid
    for (std::size_t c = 0; c < g.cells(); ++c) domain[c] = data[c] || d[c] > r;
    fill_enclosed_holes(domain, g.width, g.height);
  }
  for (const auto& [unit, poly] : o.footprints)
    for (std::size_t c = 0; c < g.cells(); ++c) {
      const Eigen::Vector2d p = g.centre(c);
      if (inside_polygon(poly, p.x(), p.y())) domain[c] = 1;
    }
  return domain;
}

// Membrane fill of one layer inside the domain; returns the number of filled cells.
std::size_t fill_layer(LayerSurface& l, const std::vector<std::uint8_t>& domain, const RasterGrid& g) {
  const int nx = g.width, ny = g.height;
  const std::size_t n = g.cells();
  std::vector<std::uint8_t> known(n, 0);
  for (std::size_t c = 0; c < n; ++c) known[c] = std::isfinite(l.z.z[c]);
  // Unknowns: domain cells without a height, in components that touch a known cell.
  std::vector<std::uint8_t> missing(n, 0);
  for (std::size_t c = 0; c < n; ++c) missing[c] = domain[c] && !known[c];
  const Components gaps = connected_components(missing, nx, ny, Connectivity::four);
  std::vector<std::int64_t> index(n, -1);
  std::vector<std::size_t> unknowns;
  for (std::size_t k = 0; k < gaps.count(); ++k) {
    const bool anchored = std::any_of(gaps.begin(k), gaps.end(k), [&](std::size_t c) {
      const int i = int(c % nx), j = int(c / nx);
      return (i > 0 && known[c - 1]) || (i + 1 < nx && known[c + 1]) || (j > 0 && known[c - nx]) ||
             (j + 1 < ny && known[c + nx]);
    });
    if (!anchored) continue;  // no measured height around it: nothing to interpolate from
    for (auto c = gaps.begin(k); c != gaps.end(k); ++c) {
      index[*c] = std::int64_t(unknowns.size());
      unknowns.push_back(*c);
    }
  }
  if (unknowns.empty()) return 0;

  // Initial guess and uncertainty: the nearest measured height and its distance.
  std::vector<double> dist;
  std::vector<std::int64_t> nearest;
  distance_transform(known, nx, ny, dist, &nearest);

  // Discrete Laplace equation on the 4-neighbourhood: for an unknown cell,
  // sum over its neighbours in the domain or measured of (z_c - z_q) = 0; measured
  // neighbours go to the right-hand side, neighbours outside both are left out
  // (zero slope across the domain's border).
  const Eigen::Index m = Eigen::Index(unknowns.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(unknowns.size() * 5);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(m), x0(m);
  for (Eigen::Index r = 0; r < m; ++r) {
    const std::size_t c = unknowns[std::size_t(r)];
    const int i = int(c % nx), j = int(c / nx);
    const std::size_t nb[4] = {c - 1, c + 1, c - nx, c + nx};
    const bool ok[4] = {i > 0, i + 1 < nx, j > 0, j + 1 < ny};
    double diag = 0;
    for (int k = 0; k < 4; ++k) {
      if (!ok[k]) continue;
      const std::size_t q = nb[k];
      if (known[q]) {
        diag += 1;
        rhs[r] += l.z.z[q];
      } else if (index[q] >= 0) {
        diag += 1;
        triplets.emplace_back(r, Eigen::Index(index[q]), -1.0);
      }
    }
    triplets.emplace_back(r, r, diag);
    x0[r] = nearest[c] >= 0 ? l.z.z[std::size_t(nearest[c])] : 0.0;
  }
  Eigen::SparseMatrix<double> A(m, m);
  A.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
  cg.setTolerance(1e-9);
  cg.setMaxIterations(20000);
  cg.compute(A);
  const Eigen::VectorXd z = cg.solveWithGuess(rhs, x0);
  if (cg.info() != Eigen::Success)
    log::warn("volume: gap fill of layer {}: the membrane solver stopped after {} iterations (error {:.2e})", l.layer,
              cg.iterations(), cg.error());
  l.filled_distance_m.assign(n, 0.0f);
  for (Eigen::Index r = 0; r < m; ++r) {
    const std::size_t c = unknowns[std::size_t(r)];
    l.z.z[c] = z[r];
    l.filled_distance_m[c] = float(std::max(dist[c], 1.0) * g.cell);
  }
  log::debug("volume: layer {}: {} cells filled ({} CG iterations)", l.layer, unknowns.size(), cg.iterations());
  return unknowns.size();
}

}  // namespace

namespace volume_detail {
void distance_transform(const std::vector<std::uint8_t>& feature, int nx, int ny, std::vector<double>& dist,
                        std::vector<std::int64_t>* nearest) {
  const std::size_t n = std::size_t(nx) * ny;
  std::vector<double> col_d(n);
  std::vector<int> col_site(n);
  std::vector<double> f, d;
  std::vector<int> site;
  for (int i = 0; i < nx; ++i) {  // columns: nearest feature row in the same column
    f.assign(ny, kInf);
    for (int j = 0; j < ny; ++j)
      if (feature[std::size_t(j) * nx + i]) f[j] = 0;
    distance_1d(f, d, site);
    for (int j = 0; j < ny; ++j) {
      col_d[std::size_t(j) * nx + i] = d[j];
      col_site[std::size_t(j) * nx + i] = site[j];
    }
  }
  dist.assign(n, kInf);
  if (nearest) nearest->assign(n, -1);
  for (int j = 0; j < ny; ++j) {  // rows over the column distances
    f.assign(col_d.begin() + std::ptrdiff_t(j) * nx, col_d.begin() + std::ptrdiff_t(j + 1) * nx);
    distance_1d(f, d, site);
    for (int i = 0; i < nx; ++i) {
      const std::size_t c = std::size_t(j) * nx + i;
      if (site[i] < 0) continue;
      dist[c] = std::sqrt(d[i]);
      if (nearest) (*nearest)[c] = std::int64_t(col_site[std::size_t(j) * nx + site[i]]) * nx + site[i];
    }
  }
}

}  // namespace volume_detail

GapFillSummary fill_surface_gaps(std::vector<LayerSurface>& layers, const VolumeOptions& options) {
  options.validate();
  GapFillSummary out;
  if (layers.empty() || !options.fill.enabled) return out;
  const RasterGrid& g = layers.front().z.grid;
  for (const auto& l : layers) STRATA_CHECK(l.z.grid == g, "layer {} is not on the common grid", l.layer);
  const std::vector<std::uint8_t> domain = fill_domain(layers, g, options);
  const double cell_area = g.cell * g.cell;
  out.domain_area_m2 = double(std::count(domain.begin(), domain.end(), 1)) * cell_area;
  for (auto& l : layers) {
    std::size_t measured = 0;
    for (std::size_t c = 0; c < g.cells(); ++c) measured += domain[c] && std::isfinite(l.z.z[c]) && !l.filled(c);
    out.measured_area_m2[l.layer] = double(measured) * cell_area;
    out.filled_area_m2[l.layer] = double(fill_layer(l, domain, g)) * cell_area;
    log::info("volume: layer {}: {:.3f} m2 measured, {:.3f} m2 filled in a fill domain of {:.3f} m2", l.layer,
              out.measured_area_m2[l.layer], out.filled_area_m2[l.layer], out.domain_area_m2);
  }
  return out;
}

}  // namespace strata
