#pragma once
// 3D similarity transforms (scale, rotation, translation): the georeference of a
// reconstruction onto surveyed markers.
#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <vector>

namespace strata {

struct Similarity3 {
  double scale = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return scale * (R * x) + t; }
  Similarity3 inverse() const;
};

// Least-squares similarity mapping src[i] onto dst[i] (Umeyama 1991, through
// Eigen::umeyama). Throws InputError when fewer than 3 points are given or
// they are (near-)collinear: `min_spread_ratio` is the smallest singular value of
// the centred point set relative to the largest, below which the rotation about
// the line through them is undetermined.
Similarity3 fit_similarity(const std::vector<Eigen::Vector3d>& src,
                           const std::vector<Eigen::Vector3d>& dst,
                           double min_spread_ratio = 0.02);

// The same without the scale (scale = 1): a rigid motion, for an instrument that
// measures in metres (a laser scanner).
Similarity3 fit_rigid(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                      double min_spread_ratio = 0.02);

// Weighted least-squares similarity with a standard deviation per point and axis:
// minimises sum_i sum_a ((s R src_i + t - dst_i)_a / sigma_i,a)^2 by Gauss-Newton
// (7 parameters: log-scale, a rotation increment, translation) from the Umeyama fit.
// A large sigma on an axis lets that coordinate count for little: markers surveyed
// in plan only (heights unknown) get a large height sigma and then fix the plan
// position, scale and azimuth, while the level of the block rests on the weak
// height prior. Same refusals as fit_similarity; every sigma must be > 0.
Similarity3 fit_similarity_weighted(const std::vector<Eigen::Vector3d>& src,
                                    const std::vector<Eigen::Vector3d>& dst,
                                    const std::vector<Eigen::Vector3d>& sigma,
                                    double min_spread_ratio = 0.02);

// A similarity fitted to pairs that may hold blunders (a target given another's name,
// a disturbed marker). Every triple of pairs (all of them up to 20,000 triples, else
// as many drawn with a fixed seed) proposes a fit; the one that brings the most pairs
// within `gate_m` of their partner wins (ties: the smaller RMS over them), then a
// least-squares fit on those inliers, re-gated until the set no longer changes.
// Throws InputError when fewer than 3 pairs are given, or no well-spread triple
// (planar_spread_ratio >= min_spread_ratio) brings 3 pairs within the gate.
struct RobustSimilarity {
  Similarity3 fit;
  std::vector<bool> inlier;         // per pair
  std::vector<double> residual_m;   // |fit(src_i) - dst_i| per pair, metres
  std::size_t inliers = 0;
  double rms_m = 0;                 // over the inliers, metres
};
RobustSimilarity fit_similarity_robust(const std::vector<Eigen::Vector3d>& src,
                                       const std::vector<Eigen::Vector3d>& dst, double gate_m,
                                       double min_spread_ratio = 0.02);

// A rigid motion (scale 1) fitted to 3D point pairs of which many are wrong: matched
// image features back-projected through two depth frames (Arun et al. 1987 / Umeyama
// 1991 inside RANSAC, Fischler & Bolles 1981, as Almeida et al. and the RGB-D SLAM
// systems start frame-to-frame tracking). Each pair has its own gate, metres (the
// depth noise k z^2 grows with the range, so a far pair is allowed more). The same
// hypothesise-and-verify as fit_similarity_robust: up to `hypotheses` triples (all
// of them when there are fewer), the one bringing the most pairs within their gates,
// then least squares on those inliers, re-gated until the set is stable.
struct RigidRansacOptions {
  int hypotheses = 1000;          // triples tried; 1000 finds a clean triple at 30 % inliers (p = 1 - 1e-12)
  std::uint64_t seed = 0x5EED5u;  // of the triples drawn: the fit is deterministic
  double min_spread_ratio = 0.02; // triples (and inlier sets) flatter than this are skipped
  void validate() const;          // throws InputError naming the field
};
// Empty when fewer than 3 pairs are given or no well-spread triple brings 3 pairs
// within their gates. `fit.scale` is 1.
std::optional<RobustSimilarity> fit_rigid_ransac(const std::vector<Eigen::Vector3d>& src,
                                                 const std::vector<Eigen::Vector3d>& dst,
                                                 const std::vector<double>& gate_m,
                                                 const RigidRansacOptions& options = {});

// Ratio of the second to the first singular value of a centred point set:
// 0 for collinear points, about 1 for well spread ones.
double planar_spread_ratio(const std::vector<Eigen::Vector3d>& points);

}  // namespace strata
