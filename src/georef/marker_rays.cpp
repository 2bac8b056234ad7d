#include "georef/marker_rays.hpp"

#include "core/error.hpp"
#include "core/statistics.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace strata {

void MarkerRayOptions::validate() const {
  auto fail = [](const char* name, double v, const char* rule) {
    throw InputError(fmt::format("marker ray option {} must be {}, got {}", name, rule, v));
  };
  if (!(min_angle_deg >= 0 && min_angle_deg < 90)) fail("min_angle_deg", min_angle_deg, "in [0, 90)");
  if (!(click_sigma_px > 0)) fail("click_sigma_px", click_sigma_px, "> 0");
  if (!(agree_factor > 1)) fail("agree_factor", agree_factor, "> 1");
  if (!(min_gate_px >= 0)) fail("min_gate_px", min_gate_px, ">= 0");
  if (!(max_relative_dispersion > 0)) fail("max_relative_dispersion", max_relative_dispersion, "> 0");
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kRadToDeg = 57.29577951308232;
// Pairs tried for the robust start: all of them up to this many (45 rays: 990 pairs),
// an even subsample beyond.
constexpr std::size_t kMaxPairs = 2500;
// Rounds of the point / dispersion / agreeing-set iteration; it settles in 2-4.
constexpr int kMaxRounds = 12;

struct View {
  const Camera* camera;
  Eigen::Vector2d pixel;
  Eigen::Vector2d normalised;  // undistorted
  Eigen::Vector3d centre;
  Eigen::Vector3d direction;   // unit, world
};

double error_px(const View& v, const Eigen::Vector3d& X) {
  const auto p = v.camera->project(X);
  return p ? (*p - v.pixel).norm() : kInf;
}

// Ground size of a pixel at X (depth / focal), frame units per pixel.
double footprint(const View& v, const Eigen::Vector3d& X) {
  const double depth = v.camera->pose.to_camera(X).z();
  return depth > 0 ? depth / v.camera->intrinsics.fx : 0.0;
}

// Closest point between two rays; empty when they are (nearly) parallel or the point
// lies behind either camera.
std::optional<Eigen::Vector3d> midpoint(const View& a, const View& b) {
  const Eigen::Vector3d w = a.centre - b.centre;
  const double d = a.direction.dot(b.direction);
  const double den = 1.0 - d * d;
  if (den < 1e-12) return std::nullopt;
  const double ta = (d * b.direction.dot(w) - a.direction.dot(w)) / den;
  const double tb = (b.direction.dot(w) - d * a.direction.dot(w)) / den;
  if (ta <= 0 || tb <= 0) return std::nullopt;
  return 0.5 * ((a.centre + ta * a.direction) + (b.centre + tb * b.direction));
}

double angle_deg(const View& a, const View& b, const Eigen::Vector3d& X) {
  const Eigen::Vector3d ra = (X - a.centre).normalized(), rb = (X - b.centre).normalized();
  return std::acos(std::clamp(ra.dot(rb), -1.0, 1.0)) * kRadToDeg;
}

// Object-space miss of ray i at X: reprojection error times the ground size of a pixel.
double miss(const View& v, const Eigen::Vector3d& X) {
  const double e = error_px(v, X);
  return std::isfinite(e) ? e * footprint(v, X) : kInf;
}

// The h-th smallest miss over all rays (least median of squares when h = n / 2).
double order_score(const std::vector<View>& views, const Eigen::Vector3d& X, std::size_t h) {
  std::vector<double> m;
  m.reserve(views.size());
  for (const auto& v : views) m.push_back(miss(v, X));
  return kth_smallest(m, h - 1);
}

std::optional<Eigen::Vector3d> robust_start(const std::vector<View>& views, double min_angle_deg) {
  const std::size_t n = views.size();
  const std::size_t h = std::max<std::size_t>(2, (n + 1) / 2);
  const std::size_t pairs = n * (n - 1) / 2;
  const std::size_t stride = std::max<std::size_t>(1, pairs / kMaxPairs);
  std::optional<Eigen::Vector3d> best;
  double best_score = kInf;
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j, ++k) {
      if (k % stride) continue;
      const auto X = midpoint(views[i], views[j]);
      if (!X || angle_deg(views[i], views[j], *X) < min_angle_deg) continue;
      const double score = order_score(views, *X, h);
      if (score < best_score) {
        best_score = score;
        best = X;
      }
    }
  }
  return best;
}

// Weighted least squares point for fixed cameras (Gauss-Newton on the undistorted
// reprojection in pixels; the lens model only rescales residuals locally).
Eigen::Vector3d refine_point(const std::vector<View>& views, const std::vector<double>& weight,
                             Eigen::Vector3d X) {
  for (int it = 0; it < 10; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < views.size(); ++i) {
      if (weight[i] <= 0) continue;
      const auto& cam = *views[i].camera;
      const Eigen::Vector3d Xc = cam.pose.to_camera(X);
      if (Xc.z() <= 1e-12) continue;
      const double fx = cam.intrinsics.fx, fy = cam.intrinsics.fy, z = Xc.z();
      const Eigen::Vector2d r(fx * (Xc.x() / z - views[i].normalised.x()),
                              fy * (Xc.y() / z - views[i].normalised.y()));
      Eigen::Matrix<double, 2, 3> Jc;
      Jc << fx / z, 0, -fx * Xc.x() / (z * z), 0, fy / z, -fy * Xc.y() / (z * z);
      const Eigen::Matrix<double, 2, 3> J = Jc * cam.pose.R;
      H += weight[i] * J.transpose() * J;
      g += weight[i] * J.transpose() * r;
    }
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) break;
    X += step;
    if (step.norm() < 1e-12 * (1.0 + X.norm())) break;
  }
  return X;
}

// Dispersion s >= 0 such that sum e_i^2 / (c^2 + (s / g_i)^2) = 2 n - 3 over the
// agreeing rays (the chi-square matches its degrees of freedom); 0 when the clicks
// alone explain the misfit.
double fit_dispersion(const std::vector<double>& e, const std::vector<double>& g, double c, double cut) {
  // The agreeing rays are those within `cut` sigma: a 2D normal error cut there keeps
  // (1 - (1 + k^2/2) e^{-k^2/2}) / (1 - e^{-k^2/2}) of its mean square (0.949 at k = 3),
  // so the expected chi-square of the kept rays is that fraction of 2 n - 3.
  const double tail = std::exp(-0.5 * cut * cut);
  const double kept_fraction = (1.0 - (1.0 + 0.5 * cut * cut) * tail) / (1.0 - tail);
  const double dof = (2.0 * double(e.size()) - 3.0) * kept_fraction;
  if (dof <= 0) return 0;
  auto chi2 = [&](double s) {
    double sum = 0;
    for (std::size_t i = 0; i < e.size(); ++i) {
      const double sp = g[i] > 0 ? s / g[i] : 0;
      sum += e[i] * e[i] / (c * c + sp * sp);
    }
    return sum;
  };
  if (chi2(0) <= dof) return 0;
  double lo = 0, hi = 0;
  for (std::size_t i = 0; i < e.size(); ++i) hi = std::max(hi, e[i] * g[i]);
  hi = std::max(hi * 4, 1e-12);
  for (int it = 0; it < 80; ++it) {
    const double mid = 0.5 * (lo + hi);
    (chi2(mid) > dof ? lo : hi) = mid;
  }
  return hi;
}

}  // namespace

MarkerRayFit fit_marker_rays(const std::vector<Camera>& cameras, const std::vector<Eigen::Vector2d>& pixels,
                             const MarkerRayOptions& options) {
  STRATA_CHECK(cameras.size() == pixels.size());
  MarkerRayFit fit;
  const std::size_t n = cameras.size();
  fit.rays.resize(n);
  for (auto& r : fit.rays) r.error_px = kInf;
  if (n < 2) return fit;
  std::vector<View> views;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d xn = cameras[i].intrinsics.to_normalised(pixels[i]);
    const Eigen::Vector3d dir = cameras[i].pose.R.transpose() * Eigen::Vector3d(xn.x(), xn.y(), 1.0);
    views.push_back({&cameras[i], pixels[i], xn, cameras[i].pose.centre(), dir.normalized()});
  }
  const auto start = robust_start(views, options.min_angle_deg);
  if (!start) return fit;

  const double c = options.click_sigma_px;
  Eigen::Vector3d X = *start;
  // Initial scale from the h-th smallest miss (the same order statistic the start was
  // chosen by, so up to half the rays may be gross): the miss is the length of a 2D
  // error across the ray, whose median is 1.1774 sigma for a normal error per axis.
  const std::size_t h = std::max<std::size_t>(2, (n + 1) / 2);
  std::vector<double> misses;
  for (const auto& v : views) misses.push_back(miss(v, X));
  // With few rays the chosen order statistic is biased low (the start was picked to
  // make it small): Rousseeuw & Leroy's (1987) small-sample factor 1 + 5 / (n - p), with
  // p = 3 unknowns, widens it (3.5 x for 5 rays, 1.2 x for 30), capped for n <= 4.
  const double small_sample = n > 4 ? 1.0 + 5.0 / double(n - 3) : 6.0;
  double s = small_sample * kth_smallest(misses, h - 1) / 1.1774;
  std::vector<char> agrees(n, 0), previous;
  for (int round = 0; round < kMaxRounds; ++round) {
    std::vector<double> weight(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const double g = footprint(views[i], X);
      const double e = error_px(views[i], X);
      const double sigma = std::hypot(c, g > 0 ? s / g : 0.0);
      agrees[i] = g > 0 && e <= std::max(options.agree_factor * sigma, options.min_gate_px);
      weight[i] = agrees[i] ? 1.0 / (sigma * sigma) : 0.0;
    }
    if (std::count(agrees.begin(), agrees.end(), 1) < 2) break;
    if (agrees == previous) break;
    previous = agrees;
    X = refine_point(views, weight, X);
    std::vector<double> e, g;
    for (std::size_t i = 0; i < n; ++i) {
      if (!agrees[i]) continue;
      e.push_back(error_px(views[i], X));
      g.push_back(footprint(views[i], X));
    }
    s = fit_dispersion(e, g, c, options.agree_factor);
  }

  fit.X = X;
  fit.dispersion = s;
  double sum2 = 0, sum_g = 0, sum_depth = 0;
  for (std::size_t i = 0; i < n; ++i) {
    auto& r = fit.rays[i];
    r.error_px = error_px(views[i], X);
    r.footprint = footprint(views[i], X);
    r.sigma_px = std::hypot(c, r.footprint > 0 ? s / r.footprint : 0.0);
    r.agrees = r.footprint > 0 && r.error_px <= std::max(options.agree_factor * r.sigma_px, options.min_gate_px);
    if (!r.agrees) continue;
    ++fit.agreeing;
    sum2 += r.error_px * r.error_px;
    sum_g += r.footprint;
    sum_depth += r.footprint * cameras[i].intrinsics.fx;
    for (std::size_t j = 0; j < i; ++j) {
      if (fit.rays[j].agrees) fit.max_angle_deg = std::max(fit.max_angle_deg, angle_deg(views[i], views[j], X));
    }
  }
  if (fit.agreeing > 0) {
    fit.rmse_px = std::sqrt(sum2 / fit.agreeing);
    fit.mean_footprint = sum_g / fit.agreeing;
    fit.mean_depth = sum_depth / fit.agreeing;
  }
  fit.too_dispersed = fit.mean_depth > 0 && s > options.max_relative_dispersion * fit.mean_depth;
  fit.ok = fit.agreeing >= 2 && fit.max_angle_deg >= options.min_angle_deg && X.allFinite() && !fit.too_dispersed;
  return fit;
}

}  // namespace strata
