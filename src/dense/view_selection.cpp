// Source-view selection for multi-view stereo from the sparse reconstruction:
// images that share many tracks at a useful triangulation angle (the criterion of
// Goesele et al. 2007 and COLMAP's PatchMatch view selection, simplified).
#include "core/statistics.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
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


// The sparse points of each image and the images of each point (each once).
struct Covisibility {
  std::vector<std::vector<int>> seen_by;  // per image: indices into rec.points
  std::vector<std::vector<int>> tracks;   // per point: registered images
};

Covisibility covisibility(const Reconstruction& rec) {
  const int n = static_cast<int>(rec.images.size());
  Covisibility c;
  c.seen_by.resize(static_cast<std::size_t>(n));
  c.tracks.resize(rec.points.size());
  for (std::size_t k = 0; k < rec.points.size(); ++k) {
    auto& seen = c.tracks[k];
    for (const auto& e : rec.points[k].track) {
      if (e.image < 0 || e.image >= n || !rec.images[e.image].registered) continue;
      if (std::find(seen.begin(), seen.end(), e.image) == seen.end()) seen.push_back(e.image);
    }
    for (int i : seen) c.seen_by[i].push_back(static_cast<int>(k));
  }
  return c;
}

// Up to `count` views among `allowed` for image i, chosen greedily with diminishing
// returns per point (the coverage term of Goesele et al. 2007's global view
// selection): a view that sees parts of the image the chosen ones miss beats another
// view of the same part, so the whole image - trench floor, far side, walls - is
// covered.
std::vector<int> greedy_views(const Reconstruction& rec, const Covisibility& cv, const std::vector<Eigen::Vector3d>& centres,
                              int i, const std::vector<char>& allowed, int count, const ViewSelectionOptions& opt) {
  const int n = static_cast<int>(rec.images.size());
  struct Shared {
    int point;  // index into seen_by[i]
    double weight;
  };
  std::vector<std::vector<Shared>> shared(static_cast<std::size_t>(n));
  const auto& mine = cv.seen_by[i];
  for (std::size_t a = 0; a < mine.size(); ++a) {
    const auto& p = rec.points[mine[a]];
    const Eigen::Vector3d ri = (centres[i] - p.X).normalized();
    for (int j : cv.tracks[mine[a]]) {
      if (j == i || !allowed[j]) continue;
      const Eigen::Vector3d rj = (centres[j] - p.X).normalized();
      const double angle = std::acos(std::clamp(ri.dot(rj), -1.0, 1.0)) * 180.0 / std::numbers::pi;
      shared[j].push_back({static_cast<int>(a), angle_weight(angle, opt)});
    }
  }
  std::vector<int> cover(mine.size(), 0);
  std::vector<char> taken(static_cast<std::size_t>(n), 0);
  std::vector<int> out;
  for (int k = 0; k < count; ++k) {
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
    out.push_back(best_j);
    for (const auto& sp : shared[best_j]) ++cover[sp.point];
  }
  return out;
}

// A sparse point inside a photo's frustum (in front of the camera, inside the photo)
// and its depth there.
struct PointInView {
  int point;
  double depth;
};

// Per image, the sparse points inside its frustum.
std::vector<std::vector<PointInView>> points_in_view(const Reconstruction& rec) {
  std::vector<std::vector<PointInView>> out(rec.images.size());
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    const auto& im = rec.images[i];
    if (!im.registered) continue;
    const auto& intr = rec.groups.at(im.group).intrinsics;
    for (std::size_t k = 0; k < rec.points.size(); ++k) {
      const Eigen::Vector3d Xc = im.pose.to_camera(rec.points[k].X);
      if (Xc.z() <= 0) continue;
      const Eigen::Vector2d px = intr.to_pixel(Xc.head<2>() / Xc.z());
      if (px.x() >= 0 && px.y() >= 0 && px.x() < intr.width && px.y() < intr.height) {
        out[i].push_back({static_cast<int>(k), Xc.z()});
      }
    }
  }
  return out;
}

// Per sparse point, the candidate images whose view holds it: inside the frustum and
// inside the image's depth range. Not only the images that matched it: a sparse track
// holds 3-4 of the 10-20 photos that see a spot of a trench, so a cover counted on
// tracks alone needs nearly every photo.
std::vector<std::vector<int>> frustum_visibility(std::size_t points, const std::vector<std::vector<PointInView>>& in_view,
                                                 const std::vector<ViewNeighbours>& views,
                                                 const std::vector<char>& candidate) {
  std::vector<std::vector<int>> out(points);
  for (std::size_t i = 0; i < candidate.size(); ++i) {
    if (!candidate[i]) continue;
    for (const PointInView& v : in_view[i]) {
      if (v.depth < views[i].depth_min || v.depth > views[i].depth_max) continue;
      out[static_cast<std::size_t>(v.point)].push_back(static_cast<int>(i));
    }
  }
  return out;
}

// The fewest candidate images (greedy set multicover) such that every sparse point
// lies in the views of `k` of them, or of all the candidates that see it when fewer do.
std::vector<char> covering_references(std::size_t points, const std::vector<std::vector<PointInView>>& in_view,
                                      const std::vector<ViewNeighbours>& views, const std::vector<char>& candidate,
                                      int k) {
  const std::size_t n = candidate.size();
  const std::vector<std::vector<int>> visible = frustum_visibility(points, in_view, views, candidate);
  std::vector<std::vector<int>> holds(n);  // per image, the points in its view
  for (std::size_t p = 0; p < visible.size(); ++p)
    for (int i : visible[p]) holds[static_cast<std::size_t>(i)].push_back(static_cast<int>(p));
  std::vector<int> need(visible.size(), 0), cover(visible.size(), 0);
  for (std::size_t p = 0; p < visible.size(); ++p) need[p] = std::min(static_cast<int>(visible[p].size()), k);
  std::vector<char> chosen(n, 0);
  for (;;) {
    std::size_t best_gain = 0;
    std::size_t best = n;
    for (std::size_t i = 0; i < n; ++i) {
      if (!candidate[i] || chosen[i]) continue;
      std::size_t gain = 0;
      for (int p : holds[i]) gain += cover[p] < need[p] ? 1 : 0;
      if (gain > best_gain) {  // ties: the lower index, so the choice is reproducible
        best_gain = gain;
        best = i;
      }
    }
    if (best == n) break;
    chosen[best] = 1;
    for (int p : holds[best]) ++cover[p];
    log::debug("dense: reference view {}: {} points newly covered", best, best_gain);
  }
  return chosen;
}

}  // namespace

std::vector<ViewNeighbours> select_views(const Reconstruction& rec, const ViewSelectionOptions& opt,
                                         double depth_margin) {
  const int n = static_cast<int>(rec.images.size());
  std::vector<ViewNeighbours> out(static_cast<std::size_t>(n));
  std::vector<Eigen::Vector3d> centres(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) centres[i] = rec.images[i].pose.centre();
  const Covisibility cv = covisibility(rec);
  const std::vector<char> every(static_cast<std::size_t>(n), 1);
  const std::vector<std::vector<PointInView>> in_view = points_in_view(rec);

  for (int i = 0; i < n; ++i) {
    if (!rec.images[i].registered) continue;
    out[i].sources = greedy_views(rec, cv, centres, i, every, opt.max_neighbours, opt);

    // Depth range: robust percentiles of the depths of every sparse point inside the
    // photo's frustum, not only the points this photo matched: markers and ground at
    // the far edge of an oblique photo are often matched only by photos taken nearer
    // to them, and a range cut at this photo's own matches leaves them without depth.
    // Points hidden behind a wall only widen the range, which PatchMatch tolerates.
    std::vector<double> d;
    d.reserve(in_view[i].size());
    for (const PointInView& v : in_view[i]) d.push_back(v.depth);
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

  // Reference views, and for each the reference views that check its depth map: its
  // sources when every candidate is a reference (their depth maps exist), else the
  // references ranked the same way among themselves.
  std::vector<char> candidate(static_cast<std::size_t>(n), 0);
  for (int i = 0; i < n; ++i) candidate[i] = out[i].sources.empty() ? 0 : 1;
  const std::vector<char> reference =
      opt.reference_cover > 0 ? covering_references(rec.points.size(), in_view, out, candidate, opt.reference_cover)
                              : candidate;
  for (int i = 0; i < n; ++i) {
    if (!reference[i]) continue;
    out[i].reference = true;
    if (opt.reference_cover > 0) {
      out[i].checks = greedy_views(rec, cv, centres, i, reference, opt.max_neighbours, opt);
    } else {
      for (int s : out[i].sources) if (reference[s]) out[i].checks.push_back(s);
    }
  }
  return out;
}

}  // namespace strata::dense
