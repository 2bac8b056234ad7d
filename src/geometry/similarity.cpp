#include "geometry/similarity.hpp"

#include "core/error.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <random>

namespace strata {

Similarity3 Similarity3::inverse() const {
  Similarity3 inv;
  inv.scale = 1.0 / scale;
  inv.R = R.transpose();
  inv.t = -inv.scale * (inv.R * t);
  return inv;
}

double planar_spread_ratio(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 2) return 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= double(points.size());
  Eigen::MatrixXd centred(points.size(), 3);
  for (std::size_t i = 0; i < points.size(); ++i) centred.row(i) = (points[i] - mean).transpose();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred);
  const auto s = svd.singularValues();
  return s(0) > 0 ? s(1) / s(0) : 0.0;
}

namespace {

// Umeyama's least-squares fit, with or without the scale.
Similarity3 fit_umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                        double min_spread_ratio, bool with_scale) {
  STRATA_CHECK(src.size() == dst.size());
  if (src.size() < 3) {
    throw InputError(fmt::format(
        "a similarity needs at least 3 control markers, {} given", src.size()));
  }
  const double spread = std::min(planar_spread_ratio(src), planar_spread_ratio(dst));
  if (spread < min_spread_ratio) {
    throw InputError(fmt::format(
        "the control markers are (nearly) collinear (spread ratio {:.4f} < {}): "
        "the rotation about their line is undetermined; add a marker off that line",
        spread, min_spread_ratio));
  }
  Eigen::Matrix3Xd a(3, src.size()), b(3, dst.size());
  for (std::size_t i = 0; i < src.size(); ++i) {
    a.col(i) = src[i];
    b.col(i) = dst[i];
  }
  const Eigen::Matrix4d T = Eigen::umeyama(a, b, with_scale);
  Similarity3 s;
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  s.scale = with_scale ? std::cbrt(sR.determinant()) : 1.0;
  s.R = sR / s.scale;
  s.t = T.topRightCorner<3, 1>();
  return s;
}

}  // namespace

Similarity3 fit_similarity(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                           double min_spread_ratio) {
  return fit_umeyama(src, dst, min_spread_ratio, true);
}

Similarity3 fit_rigid(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                      double min_spread_ratio) {
  return fit_umeyama(src, dst, min_spread_ratio, false);
}

Similarity3 fit_similarity_weighted(const std::vector<Eigen::Vector3d>& src,
                                    const std::vector<Eigen::Vector3d>& dst,
                                    const std::vector<Eigen::Vector3d>& sigma,
                                    double min_spread_ratio) {
  STRATA_CHECK(src.size() == dst.size() && sigma.size() == src.size());
  for (const auto& sg : sigma) {
    if (!(sg.minCoeff() > 0) || !sg.allFinite()) {
      throw InputError(fmt::format("a weighted similarity needs every sigma > 0, got ({}, {}, {})",
                                   sg.x(), sg.y(), sg.z()));
    }
  }
  Similarity3 s = fit_similarity(src, dst, min_spread_ratio);
  // Gauss-Newton on the whitened residuals r_i = W_i (s R x_i + t - y_i), W = diag(1/sigma),
  // with the updates s <- s exp(d_s), R <- exp([w]x) R, t <- t + d_t:
  //   dr/d(d_s) = W s R x,  dr/dw = -W [s R x]x,  dr/dt = W.
  constexpr int kMaxIterations = 50;
  constexpr double kStepTolerance = 1e-12;  // relative, on every update
  for (int it = 0; it < kMaxIterations; ++it) {
    Eigen::Matrix<double, 7, 7> JtJ = Eigen::Matrix<double, 7, 7>::Zero();
    Eigen::Matrix<double, 7, 1> Jtr = Eigen::Matrix<double, 7, 1>::Zero();
    for (std::size_t i = 0; i < src.size(); ++i) {
      const Eigen::Vector3d w = sigma[i].cwiseInverse();
      const Eigen::Vector3d sRx = s.scale * (s.R * src[i]);
      const Eigen::Vector3d r = (sRx + s.t - dst[i]).cwiseProduct(w);
      Eigen::Matrix<double, 3, 7> J;
      J.col(0) = sRx;
      Eigen::Matrix3d cross;
      cross << 0, -sRx.z(), sRx.y(), sRx.z(), 0, -sRx.x(), -sRx.y(), sRx.x(), 0;
      J.block<3, 3>(0, 1) = -cross;
      J.block<3, 3>(0, 4) = Eigen::Matrix3d::Identity();
      J = w.asDiagonal() * J;
      JtJ += J.transpose() * J;
      Jtr += J.transpose() * r;
    }
    const Eigen::Matrix<double, 7, 1> d = JtJ.ldlt().solve(-Jtr);
    if (!d.allFinite()) break;  // (numerically) singular: keep the current estimate
    s.scale *= std::exp(d(0));
    const Eigen::Vector3d w = d.segment<3>(1);
    if (w.norm() > 0) s.R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * s.R;
    s.t += d.segment<3>(4);
    if (d.cwiseAbs().maxCoeff() < kStepTolerance * std::max(1.0, s.t.norm())) break;
  }
  return s;
}

namespace {

// Residuals of every pair under `s`, and which lie within their gate.
RobustSimilarity score(const Similarity3& s, const std::vector<Eigen::Vector3d>& src,
                       const std::vector<Eigen::Vector3d>& dst, const std::vector<double>& gate_m) {
  RobustSimilarity r;
  r.fit = s;
  r.inlier.assign(src.size(), false);
  r.residual_m.resize(src.size());
  double sum2 = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    r.residual_m[i] = (s.apply(src[i]) - dst[i]).norm();
    if (r.residual_m[i] <= gate_m[i]) {
      r.inlier[i] = true;
      ++r.inliers;
      sum2 += r.residual_m[i] * r.residual_m[i];
    }
  }
  r.rms_m = r.inliers > 0 ? std::sqrt(sum2 / double(r.inliers)) : 0.0;
  return r;
}

bool better(const RobustSimilarity& a, const RobustSimilarity& b) {
  return a.inliers != b.inliers ? a.inliers > b.inliers : a.rms_m < b.rms_m;
}

// The triples to try: all of them when there are at most `max_triples`, else that
// many drawn with `seed`.
std::vector<std::array<std::size_t, 3>> triples(std::size_t n, std::size_t max_triples, std::uint64_t seed) {
  std::vector<std::array<std::size_t, 3>> out;
  if (n * (n - 1) * (n - 2) / 6 <= max_triples) {
    for (std::size_t a = 0; a < n; ++a)
      for (std::size_t b = a + 1; b < n; ++b)
        for (std::size_t c = b + 1; c < n; ++c) out.push_back({a, b, c});
    return out;
  }
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  while (out.size() < max_triples) {
    const std::size_t a = pick(rng), b = pick(rng), c = pick(rng);
    if (a != b && b != c && a != c) out.push_back({a, b, c});
  }
  return out;
}

// The hypothesise-and-verify fit shared by the marker similarity and the RGB-D rigid
// RANSAC: each triple proposes a fit (Umeyama, with or without the scale), the one
// that brings the most pairs within their gates wins (ties: the smaller RMS), then
// least squares on its inliers, re-gated until the set no longer changes. Empty when
// no well-spread triple brings 3 pairs within their gates.
std::optional<RobustSimilarity> robust_umeyama(const std::vector<Eigen::Vector3d>& src,
                                               const std::vector<Eigen::Vector3d>& dst,
                                               const std::vector<double>& gate_m, bool with_scale,
                                               std::size_t max_triples, std::uint64_t seed,
                                               double min_spread_ratio) {
  std::optional<RobustSimilarity> best;
  for (const auto& t : triples(src.size(), max_triples, seed)) {
    const std::vector<Eigen::Vector3d> a = {src[t[0]], src[t[1]], src[t[2]]};
    const std::vector<Eigen::Vector3d> b = {dst[t[0]], dst[t[1]], dst[t[2]]};
    if (std::min(planar_spread_ratio(a), planar_spread_ratio(b)) < min_spread_ratio) continue;
    RobustSimilarity r = score(fit_umeyama(a, b, min_spread_ratio, with_scale), src, dst, gate_m);
    if (!best || better(r, *best)) best = std::move(r);
  }
  if (!best || best->inliers < 3) return std::nullopt;
  for (int round = 0; round < 10; ++round) {  // at most a few rounds in practice
    std::vector<Eigen::Vector3d> a, b;
    for (std::size_t i = 0; i < src.size(); ++i) {
      if (!best->inlier[i]) continue;
      a.push_back(src[i]);
      b.push_back(dst[i]);
    }
    if (std::min(planar_spread_ratio(a), planar_spread_ratio(b)) < min_spread_ratio) break;
    RobustSimilarity r = score(fit_umeyama(a, b, min_spread_ratio, with_scale), src, dst, gate_m);
    const bool same = r.inlier == best->inlier;
    if (r.inliers < 3) break;
    best = std::move(r);
    if (same) break;
  }
  return best;
}

}  // namespace

RobustSimilarity fit_similarity_robust(const std::vector<Eigen::Vector3d>& src,
                                       const std::vector<Eigen::Vector3d>& dst, double gate_m,
                                       double min_spread_ratio) {
  STRATA_CHECK(src.size() == dst.size());
  STRATA_CHECK(gate_m > 0);
  if (src.size() < 3)
    throw InputError(fmt::format("a similarity needs at least 3 point pairs, {} given", src.size()));
  constexpr std::size_t kMaxTriples = 20000;
  std::optional<RobustSimilarity> best = robust_umeyama(src, dst, std::vector<double>(src.size(), gate_m), true,
                                                        kMaxTriples, 0x5EED5u, min_spread_ratio);
  if (!best)
    throw InputError(fmt::format("no three of the {} point pairs agree on one similarity within {:.0f} mm (or "
                                 "they lie on a line)",
                                 src.size(), 1000 * gate_m));
  return *best;
}

void RigidRansacOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("rigid RANSAC: {} must be {}", field, what));
  };
  need(hypotheses >= 1, "hypotheses", ">= 1");
  need(min_spread_ratio > 0 && min_spread_ratio < 1, "min_spread_ratio", "in (0, 1)");
}

std::optional<RobustSimilarity> fit_rigid_ransac(const std::vector<Eigen::Vector3d>& src,
                                                 const std::vector<Eigen::Vector3d>& dst,
                                                 const std::vector<double>& gate_m, const RigidRansacOptions& options) {
  options.validate();
  STRATA_CHECK(src.size() == dst.size() && gate_m.size() == src.size());
  for (double g : gate_m) STRATA_CHECK(g > 0, "gate {}", g);
  if (src.size() < 3) return std::nullopt;
  return robust_umeyama(src, dst, gate_m, false, std::size_t(options.hypotheses), options.seed,
                        options.min_spread_ratio);
}

}  // namespace strata
