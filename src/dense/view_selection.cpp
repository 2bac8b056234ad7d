// Source-view selection for multi-view stereo from the sparse reconstruction:
// images that share many tracks at a useful triangulation angle (the criterion of
// Goesele et al. 2007 and COLMAP's PatchMatch view selection, simplified).
#include "core/statistics.hpp"
#include "core/error.hpp"
#include "dense/internal.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace strata::dense {
namespace {

// Weight of one shared point by its triangulation angle: full inside the
// preferred range, falling off quadratically below it (depth too uncertain) and
// smoothly above it (appearance changes too much for NCC).
double angle_weight(double angle_deg, const ViewSelectionOptions& opt) {
  if (angle_deg < opt.min_angle_deg) {
    const double r = angle_deg / opt.min_angle_deg;
    return r * r;
  }
  if (angle_deg > opt.max_angle_deg) {
    const double d = (angle_deg - opt.max_angle_deg) / 10.0;
    return std::exp(-d * d);
  }
  return 1.0;
}

}  // namespace

std::vector<ViewNeighbours> select_views(const Reconstruction& rec, const ViewSelectionOptions& opt,
                                         double depth_margin) {
  const int n = static_cast<int>(rec.images.size());
  std::vector<ViewNeighbours> out(static_cast<std::size_t>(n));
  std::vector<Eigen::Vector3d> centres(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) centres[i] = rec.images[i].pose.centre();

  // Per image, the sparse points it sees (each point once per image).
  std::vector<std::vector<int>> seen_by(static_cast<std::size_t>(n));
  std::vector<std::vector<int>> tracks(rec.points.size());
  for (std::size_t k = 0; k < rec.points.size(); ++k) {
    auto& seen = tracks[k];
    for (const auto& e : rec.points[k].track) {
      if (e.image < 0 || e.image >= n || !rec.images[e.image].registered) continue;
      if (std::find(seen.begin(), seen.end(), e.image) == seen.end()) seen.push_back(e.image);
    }
    for (int i : seen) seen_by[i].push_back(static_cast<int>(k));
  }

  for (int i = 0; i < n; ++i) {
    if (!rec.images[i].registered) continue;
    // Every (source, shared point, angle weight) of this reference image.
    struct Shared {
      int point;  // index into seen_by[i]
      double weight;
    };
    std::vector<std::vector<Shared>> shared(static_cast<std::size_t>(n));
    const auto& mine = seen_by[i];
    for (std::size_t a = 0; a < mine.size(); ++a) {
      const auto& p = rec.points[mine[a]];
      const Eigen::Vector3d ri = (centres[i] - p.X).normalized();
      for (int j : tracks[mine[a]]) {
        if (j == i) continue;
        const Eigen::Vector3d rj = (centres[j] - p.X).normalized();
        const double angle = std::acos(std::clamp(ri.dot(rj), -1.0, 1.0)) * 180.0 / std::numbers::pi;
        shared[j].push_back({static_cast<int>(a), angle_weight(angle, opt)});
      }
    }
    // Greedy choice with diminishing returns per point (the coverage term of
    // Goesele et al. 2007's global view selection): a source that sees parts of the
    // reference the chosen ones miss beats another view of the same part, so the
    // whole reference image - trench floor, far side, walls - gets sources.
    std::vector<int> cover(mine.size(), 0);
    std::vector<char> taken(static_cast<std::size_t>(n), 0);
    for (int k = 0; k < opt.max_neighbours; ++k) {
      double best = 0;
      int best_j = -1;
      for (int j = 0; j < n; ++j) {
        if (taken[j] || static_cast<int>(shared[j].size()) < opt.min_shared_points) continue;
        double score = 0;
        for (const auto& sp : shared[j]) score += sp.weight / (1.0 + cover[sp.point]);
        if (score > best) {
          best = score;
          best_j = j;
        }
      }
      if (best_j < 0) break;
      taken[best_j] = 1;
      out[i].sources.push_back(best_j);
      for (const auto& sp : shared[best_j]) ++cover[sp.point];
    }

    // Depth range: robust percentiles of the depths of every sparse point inside the
    // photo's frustum, not only the points this photo matched: markers and ground at
    // the far edge of an oblique photo are often matched only by photos taken nearer
    // to them, and a range cut at this photo's own matches leaves them without depth.
    // Points hidden behind a wall only widen the range, which PatchMatch tolerates.
    std::vector<double> d;
    {
      const auto& intr = rec.groups.at(rec.images[i].group).intrinsics;
      for (const auto& p : rec.points) {
        const Eigen::Vector3d Xc = rec.images[i].pose.to_camera(p.X);
        if (Xc.z() <= 0) continue;
        const Eigen::Vector2d px = intr.to_pixel(Xc.head<2>() / Xc.z());
        if (px.x() >= 0 && px.y() >= 0 && px.x() < intr.width && px.y() < intr.height) {
          d.push_back(Xc.z());
        }
      }
    }
    if (d.size() < 3) {
      out[i].sources.clear();  // no depth prior: cannot run stereo reliably
      continue;
    }
    const double lo = percentile(d, 0.01), hi = percentile(d, 0.99), mid = percentile(d, 0.5);
    const double widen = depth_margin * std::max(hi - lo, 0.2 * mid);
    out[i].depth_min = std::max(lo - widen, 0.05 * mid);
    out[i].depth_max = hi + widen;
    out[i].depth_median = mid;
  }
  return out;
}

}  // namespace strata::dense
