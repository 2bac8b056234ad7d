#include "geometry/icp.hpp"

#include "core/error.hpp"

#include <Eigen/Eigenvalues>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <unordered_map>
#include <unordered_set>

namespace strata {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

std::int64_t cell_key(const Eigen::Vector3i& c) {
  // 21 bits an axis: +-1e6 cells, 10 km at 1 cm.
  constexpr std::int64_t kBias = 1 << 20, kMask = (1 << 21) - 1;
  return ((c.x() + kBias) & kMask) | (((c.y() + kBias) & kMask) << 21) | (((c.z() + kBias) & kMask) << 42);
}

// The cell of a coarser grid, k cells a side, that holds cell `c`.
Eigen::Vector3i floor_div(const Eigen::Vector3i& c, int k) {
  auto f = [k](int v) { return v >= 0 ? v / k : -((-v + k - 1) / k); };
  return {f(c.x()), f(c.y()), f(c.z())};
}

// Points binned in cubes of `cell` metres: the neighbours within one cell of a query.
class VoxelHash {
 public:
  VoxelHash(const std::vector<Eigen::Vector3d>& points, double cell) : points_(points), cell_(cell) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3i c = cell_of(points[i]);
      cells_[cell_key(c)].push_back(int(i));
      blocks_.insert(cell_key(block_of(c)));
    }
  }
  // Index of the nearest point within `radius`, or -1: shells of cells outwards from
  // the query's, stopping once the next shell cannot hold a nearer point. A wide
  // search first asks the blocks (kBlock cells a side) under the radius's box: a query
  // with nothing near (a part of a frame the model has not seen yet) costs a few
  // lookups instead of every cell of the box, and finds the same answer.
  int nearest(const Eigen::Vector3d& q, double radius) const {
    int best = -1;
    double best_d2 = radius * radius;
    const Eigen::Vector3i c = cell_of(q);
    const int shells = int(std::ceil(radius / cell_));
    if (shells >= kBlock && !any_block_near(q, radius)) return -1;
    for (int k = 0; k <= shells; ++k) {
      for (int dz = -k; dz <= k; ++dz)
        for (int dy = -k; dy <= k; ++dy)
          for (int dx = -k; dx <= k; ++dx) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != k) continue;  // the shell only
            // A cell whose box is no nearer than the best point so far cannot hold a
            // nearer one: skipped without a lookup (most of the 26 round a close match).
            if (box_distance2(q, c, {dx, dy, dz}) >= best_d2) continue;
            auto it = cells_.find(cell_key(c + Eigen::Vector3i(dx, dy, dz)));
            if (it == cells_.end()) continue;
            for (int i : it->second) {
              const double d2 = (points_[i] - q).squaredNorm();
              if (d2 < best_d2) best_d2 = d2, best = i;
            }
          }
      if (best >= 0 && std::sqrt(best_d2) <= k * cell_) break;
    }
    return best;
  }
  // Every point in the 27 cells around the query's (all within one cell of it).
  template <class F>
  void visit(const Eigen::Vector3d& q, F&& f) const {
    const Eigen::Vector3i c = cell_of(q);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          auto it = cells_.find(cell_key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (int i : it->second) f(i);
        }
  }

 private:
  static constexpr int kBlock = 4;  // cells a block side
  Eigen::Vector3i cell_of(const Eigen::Vector3d& p) const { return (p / cell_).array().floor().cast<int>(); }
  static Eigen::Vector3i block_of(const Eigen::Vector3i& c) { return floor_div(c, kBlock); }
  // Squared distance from q (in cell c) to the box of the cell at offset d from c.
  double box_distance2(const Eigen::Vector3d& q, const Eigen::Vector3i& c, const Eigen::Vector3i& d) const {
    double sum = 0;
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0) continue;
      const double gap = d[a] > 0 ? (c[a] + d[a]) * cell_ - q[a] : q[a] - (c[a] + d[a] + 1) * cell_;
      if (gap > 0) sum += gap * gap;
    }
    return sum;
  }
  // Whether a block holding points meets the box of +-radius (plus a cell) about q.
  bool any_block_near(const Eigen::Vector3d& q, double radius) const {
    const Eigen::Vector3d pad = Eigen::Vector3d::Constant(radius + cell_);
    const Eigen::Vector3i lo = block_of(cell_of(q - pad)), hi = block_of(cell_of(q + pad));
    for (int z = lo.z(); z <= hi.z(); ++z)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int x = lo.x(); x <= hi.x(); ++x)
          if (blocks_.count(cell_key(Eigen::Vector3i(x, y, z)))) return true;
    return false;
  }
  const std::vector<Eigen::Vector3d>& points_;
  double cell_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
  std::unordered_set<std::int64_t> blocks_;  // blocks holding a point
};

Eigen::Vector3d centroid(const std::vector<Eigen::Vector3d>& p) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (const auto& x : p) s += x;
  return p.empty() ? s : Eigen::Vector3d(s / double(p.size()));
}

// exp of a rotation vector (Rodrigues).
Eigen::Matrix3d rotation_of(const Eigen::Vector3d& w) {
  const double a = w.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

struct Pair {
  int source, target;
  double residual;  // metres, signed, along the target normal
};

// The source points' nearest target points within the gate, minus the trimmed share.
std::vector<Pair> correspondences(const std::vector<Eigen::Vector3d>& moved, const OrientedPoints& target,
                                  const VoxelHash& grid, double gate, double trim_share) {
  std::vector<Pair> pairs;
  pairs.reserve(moved.size());
  for (std::size_t i = 0; i < moved.size(); ++i) {
    const int j = grid.nearest(moved[i], gate);
    if (j < 0) continue;
    pairs.push_back({int(i), j, target.normals[j].dot(moved[i] - target.points[j])});
  }
  const auto keep = std::size_t(std::ceil(double(pairs.size()) * (1.0 - trim_share)));
  if (keep < pairs.size()) {
    std::nth_element(pairs.begin(), pairs.begin() + long(keep), pairs.end(),
                     [](const Pair& a, const Pair& b) { return std::abs(a.residual) < std::abs(b.residual); });
    pairs.resize(keep);
  }
  return pairs;
}

}  // namespace

void IcpOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("icp: {} must be {}", field, what));
  };
  need(max_iterations > 0, "max_iterations", "> 0");
  need(max_correspondence_m > 0, "max_correspondence_m", "> 0 (metres)");
  need(min_correspondence_m > 0 && min_correspondence_m <= max_correspondence_m, "min_correspondence_m",
       "> 0 and <= max_correspondence_m (metres)");
  need(gate_rms_factor > 0, "gate_rms_factor", "> 0");
  need(huber_m > 0, "huber_m", "> 0 (metres)");
  need(trim_share >= 0 && trim_share < 1, "trim_share", "in [0, 1)");
  need(converged_step_m > 0, "converged_step_m", "> 0 (metres)");
  need(min_support_share > 0 && min_support_share < 1, "min_support_share", "in (0, 1)");
}

VoxelMeans::VoxelMeans(double voxel_m) : voxel_(voxel_m) { STRATA_CHECK(voxel_m > 0, "voxel size must be > 0"); }

void VoxelMeans::add(const Eigen::Vector3d& p) {
  auto [it, fresh] = cells_.try_emplace(cell_key((p / voxel_).array().floor().cast<int>()), Eigen::Vector3d::Zero(), 0);
  auto& c = it->second;
  c.first += p;
  ++c.second;
}

std::vector<Eigen::Vector3d> VoxelMeans::points() const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(cells_.size());
  for (const auto& [key, c] : cells_) out.push_back(c.first / double(c.second));
  return out;
}

std::vector<Eigen::Vector3d> voxel_subsample(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  VoxelMeans cells(voxel_m);  // ordered: a deterministic result
  for (const auto& p : points) cells.add(p);
  return cells.points();
}

namespace {

constexpr int kMinNeighbours = 5;  // a plane through fewer is noise

// The normal at `p` by principal components of the points within `radius_m` of it,
// which `visit(f)` hands to f (and perhaps more, farther ones); turned to face +z.
// Empty with fewer than kMinNeighbours.
template <class Visit>
std::optional<Eigen::Vector3d> pca_normal(const Eigen::Vector3d& p, double radius_m, Visit&& visit) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  int n = 0;
  visit([&](const Eigen::Vector3d& q) {
    const Eigen::Vector3d d = q - p;
    if (d.squaredNorm() > radius_m * radius_m) return;
    mean += d;
    scatter += d * d.transpose();
    ++n;
  });
  if (n < kMinNeighbours) return std::nullopt;
  mean /= n;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter / n - mean * mean.transpose());
  Eigen::Vector3d normal = eig.eigenvectors().col(0);  // smallest eigenvalue first
  if (normal.z() < 0) normal = -normal;
  return normal;
}

Eigen::Vector3i key_cell(std::int64_t key) {  // the inverse of cell_key
  constexpr std::int64_t kBias = 1 << 20, kMask = (1 << 21) - 1;
  return {int((key & kMask) - kBias), int(((key >> 21) & kMask) - kBias), int(((key >> 42) & kMask) - kBias)};
}

}  // namespace

OrientedPoints estimate_normals(const std::vector<Eigen::Vector3d>& points, double radius_m) {
  const VoxelHash grid(points, radius_m);
  OrientedPoints out;
  for (const auto& p : points) {
    const auto normal = pca_normal(p, radius_m, [&](auto&& f) { grid.visit(p, [&](int i) { f(points[i]); }); });
    if (!normal) continue;
    out.points.push_back(p);
    out.normals.push_back(*normal);
  }
  return out;
}

GrowingModel::GrowingModel(double voxel_m, double normal_radius_m)
    : voxel_(voxel_m), radius_(normal_radius_m), bin_cubes_(int(std::ceil(normal_radius_m / voxel_m - 1e-9))) {
  STRATA_CHECK(voxel_m > 0 && normal_radius_m > 0, "voxel {} m, normal radius {} m", voxel_m, normal_radius_m);
  bin_cubes_ = std::max(bin_cubes_, 1);
}

void GrowingModel::add(const std::vector<Eigen::Vector3d>& points) {
  // 1. The means: the cubes touched, and the bins they lie in.
  std::set<std::int64_t> touched_bins;
  for (const auto& p : points) {
    const Eigen::Vector3i c = (p / voxel_).array().floor().cast<int>();
    const std::int64_t key = cell_key(c);
    auto [it, fresh] = cubes_.try_emplace(key);
    it->second.sum += p;
    ++it->second.count;
    const std::int64_t bin = cell_key(floor_div(c, bin_cubes_));
    if (fresh) bins_[bin].push_back(&it->second);
    touched_bins.insert(bin);
  }
  // 2. The normals of every cube in a bin next to a touched one: a bin is at least the
  // radius wide, so these are all the cubes with a changed mean within the radius.
  std::set<std::int64_t> stale_bins;
  for (const std::int64_t bin : touched_bins) {
    const Eigen::Vector3i b = key_cell(bin);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) stale_bins.insert(cell_key(b + Eigen::Vector3i(dx, dy, dz)));
  }
  const auto mean = [](const Cube& c) -> Eigen::Vector3d { return c.sum / double(c.count); };
  for (const std::int64_t bin : stale_bins) {
    const auto in_bin = bins_.find(bin);
    if (in_bin == bins_.end()) continue;
    const Eigen::Vector3i b = key_cell(bin);
    for (Cube* cube : in_bin->second) {
      const Eigen::Vector3d p = mean(*cube);
      const auto normal = pca_normal(p, radius_, [&](auto&& f) {
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const auto near = bins_.find(cell_key(b + Eigen::Vector3i(dx, dy, dz)));
              if (near == bins_.end()) continue;
              for (const Cube* c : near->second) f(mean(*c));
            }
      });
      cube->has_normal = normal.has_value();
      if (normal) cube->normal = *normal;
      ++normals_estimated_;
    }
  }
  // 3. The oriented points, in key order.
  oriented_.points.clear();
  oriented_.normals.clear();
  for (const auto& [key, cube] : cubes_) {
    if (!cube.has_normal) continue;
    oriented_.points.push_back(mean(cube));
    oriented_.normals.push_back(cube.normal);
  }
}

IcpSummary register_point_to_plane(const std::vector<Eigen::Vector3d>& source, const OrientedPoints& target,
                                   const Eigen::Isometry3d& initial, const IcpOptions& options) {
  options.validate();
  STRATA_CHECK(target.points.size() == target.normals.size(), "target needs one normal per point");
  IcpSummary out;
  out.pose = initial;
  if (source.empty() || target.points.empty()) return out;
  const VoxelHash grid(target.points, options.min_correspondence_m);
  double gate = options.max_correspondence_m;
  std::vector<Eigen::Vector3d> moved(source.size());
  std::vector<Pair> pairs;
  Mat6 H = Mat6::Zero();
  std::vector<Vec6> jacobians;  // of the last iteration's pairs, rotation at a unit lever arm
  double rms = 0, radius = 1;
  for (out.iterations = 1; out.iterations <= options.max_iterations; ++out.iterations) {
    for (std::size_t i = 0; i < source.size(); ++i) moved[i] = out.pose * source[i];
    pairs = correspondences(moved, target, grid, gate, options.trim_share);
    if (pairs.size() < 6) break;
    // Linearised about the pairs' centroid c: r + (p - c) x n . w + n . d, so the
    // rotation's covariance does not leak into the translation's.
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const Pair& pr : pairs) c += moved[pr.source];
    c /= double(pairs.size());
    H.setZero();
    jacobians.clear();
    Vec6 g = Vec6::Zero();
    double sum_r2 = 0, sum_d2 = 0;
    for (const Pair& pr : pairs) {
      const Eigen::Vector3d& n = target.normals[pr.target];
      const Eigen::Vector3d q = moved[pr.source] - c;
      Vec6 J;
      J << q.cross(n), n;
      Vec6 unit_arm;  // the rotation's response per radian at this point's own lever arm
      unit_arm << q.cross(n) / std::max(q.norm(), 1e-3), n;
      jacobians.push_back(unit_arm);
      const double r = pr.residual, a = std::abs(r);
      const double w = a <= options.huber_m ? 1.0 : options.huber_m / a;  // Huber (IRLS)
      H += w * J * J.transpose();
      g += w * r * J;
      sum_r2 += r * r;
      sum_d2 += q.squaredNorm();
    }
    rms = std::sqrt(sum_r2 / double(pairs.size()));
    radius = std::max(1e-3, std::sqrt(sum_d2 / double(pairs.size())));
    const Vec6 x = H.ldlt().solve(-g);
    if (!x.allFinite()) break;
    const Eigen::Matrix3d dR = rotation_of(x.head<3>());
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = dR;
    step.translation() = c + x.tail<3>() - dR * c;
    out.pose = step * out.pose;
    gate = std::clamp(options.gate_rms_factor * rms, options.min_correspondence_m, gate);
    if (x.head<3>().norm() * radius + x.tail<3>().norm() < options.converged_step_m) {
      out.converged = true;
      break;
    }
  }
  out.iterations = std::min(out.iterations, options.max_iterations);
  out.inliers = int(pairs.size());
  out.inlier_share = double(pairs.size()) / double(source.size());
  out.rms_m = rms;
  if (pairs.size() < 6) return out;
  // Observability: eigenvectors of H with the rotation in metres at the cloud's
  // radius, and how many pairs each one moves, a rotation measured at each point's
  // own lever arm (so a small block near the middle still fixes the yaw).
  constexpr double kSupportResponse = 0.3;  // |J . v| per unit of v: a surface turned >= 17 degrees to it
  Mat6 S = Mat6::Identity();
  S.topLeftCorner<3, 3>() *= 1.0 / radius;
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(S * H * S);
  const double top = eig.eigenvalues().maxCoeff();
  out.eigen_ratio = top > 0 ? std::max(0.0, eig.eigenvalues().minCoeff()) / top : 0.0;
  out.support_share = 1.0;
  for (int k = 0; k < 6; ++k) {
    const Vec6 v = eig.eigenvectors().col(k);
    int support = 0;
    for (const Vec6& J : jacobians)
      if (std::abs(J.dot(v)) >= kSupportResponse) ++support;
    out.support_share = std::min(out.support_share, double(support) / double(jacobians.size()));
  }
  out.degenerate = out.support_share < options.min_support_share || !(out.eigen_ratio > 1e-12);
  if (!out.degenerate) {
    const double dof = std::max(1.0, double(pairs.size()) - 6.0);
    out.covariance = (rms * rms * double(pairs.size()) / dof) * H.inverse();
    out.sigma_rotation_rad =
        std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(out.covariance.topLeftCorner<3, 3>()).eigenvalues().maxCoeff());
    out.sigma_translation_m = std::sqrt(
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(out.covariance.bottomRightCorner<3, 3>()).eigenvalues().maxCoeff());
  }
  return out;
}

CoarseResult coarse_yaw_search(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                               const CoarseOptions& options) {
  STRATA_CHECK(options.yaw_step_rad > 0 && options.voxel_m > 0 && options.iterations > 0, "coarse options");
  std::vector<Eigen::Vector3d> src = voxel_subsample(source, options.voxel_m);
  const std::vector<Eigen::Vector3d> dst = voxel_subsample(target, options.voxel_m);
  CoarseResult best;
  if (src.empty() || dst.empty()) return best;
  const Eigen::Vector3d cs = centroid(src), cd = centroid(dst);  // of the thinned clouds: even density
  if (int(src.size()) > options.max_source_points) {
    std::vector<Eigen::Vector3d> thin;
    const double every = double(src.size()) / options.max_source_points;
    for (double k = 0; k < double(src.size()); k += every) thin.push_back(src[std::size_t(k)]);
    src.swap(thin);
  }
  const OrientedPoints surface = estimate_normals(dst, 2.5 * options.voxel_m);
  IcpOptions icp;
  icp.max_iterations = options.iterations;
  icp.max_correspondence_m = options.gate_m;
  icp.min_correspondence_m = std::min(options.gate_m, 2 * options.score_gate_m);
  icp.huber_m = options.score_gate_m;
  icp.trim_share = 0;  // far from the pose, the few points on relief have the largest residuals: keep them
  const VoxelHash grid(surface.points, options.voxel_m);
  best.score = -1;
  const int steps = int(std::ceil(2 * M_PI / options.yaw_step_rad - 1e-9));
  for (int k = 0; k < steps; ++k) {
    const double yaw = k * options.yaw_step_rad;
    Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
    start.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    start.translation() = cd - start.linear() * cs;
    const IcpSummary fit = register_point_to_plane(src, surface, start, icp);
    int close = 0;
    for (const auto& p : src) {
      const Eigen::Vector3d q = fit.pose * p;
      const int j = grid.nearest(q, options.voxel_m);  // the thinned target's spacing
      if (j >= 0 && std::abs(surface.normals[j].dot(q - surface.points[j])) < options.score_gate_m) ++close;
    }
    const double score = double(close) / double(src.size());
    if (score > best.score) best = {fit.pose, yaw, score};
  }
  return best;
}

PlaneFit dominant_plane(const std::vector<Eigen::Vector3d>& points, double tolerance_m, int hypotheses) {
  STRATA_CHECK(tolerance_m > 0 && hypotheses > 0, "plane fit options");
  PlaneFit best;
  if (points.size() < 3) return best;
  std::mt19937 rng(17);  // fixed: the same cloud gives the same plane
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  const auto count_within = [&](const Eigen::Vector3d& n, const Eigen::Vector3d& p0) {
    std::size_t k = 0;
    for (const auto& p : points) k += std::abs(n.dot(p - p0)) < tolerance_m;
    return k;
  };
  std::size_t best_count = 0;
  for (int h = 0; h < hypotheses; ++h) {
    const Eigen::Vector3d &a = points[pick(rng)], &b = points[pick(rng)], &c = points[pick(rng)];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;  // collinear or repeated
    const std::size_t k = count_within(n.normalized(), a);
    if (k > best_count) best_count = k, best.normal = n.normalized(), best.point = a;
  }
  // Least squares on the inliers: the normal is the direction of least spread.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::vector<const Eigen::Vector3d*> in;
  for (const auto& p : points)
    if (std::abs(best.normal.dot(p - best.point)) < tolerance_m) in.push_back(&p), mean += p;
  if (in.size() < 3) return best;
  mean /= double(in.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d* p : in) cov += (*p - mean) * (*p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  best.normal = eig.eigenvectors().col(0).normalized();
  best.point = mean;
  best.inlier_share = double(count_within(best.normal, mean)) / double(points.size());
  return best;
}

}  // namespace strata
