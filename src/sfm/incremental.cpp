#include "sfm/incremental.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "sfm/bundle_problem.hpp"
#include "sfm/quality.hpp"
#include "sfm/tracks.hpp"
#include "sfm/triangulation.hpp"

#include <fmt/ranges.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <set>

namespace strata {
namespace {

// The groups of photos that verified matches join (connected components of the match
// graph), largest first; image indices ascending within a group.
std::vector<std::vector<int>> match_groups(std::size_t n_images, const std::vector<PairMatches>& matches) {
  std::vector<int> parent(n_images);
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (const auto& m : matches) {
    if (m.matches.empty() || m.image_a < 0 || m.image_b < 0) continue;
    parent[root(m.image_a)] = root(m.image_b);
  }
  std::map<int, std::vector<int>> by_root;
  for (int i = 0; i < int(n_images); ++i) by_root[root(i)].push_back(i);
  std::vector<std::vector<int>> groups;
  for (auto& [r, members] : by_root) groups.push_back(std::move(members));
  std::stable_sort(groups.begin(), groups.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  return groups;
}

// OpenCV's rotation vector and translation (world to camera) as a Pose.
Pose pose_from_cv(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat Rcv;
  cv::Rodrigues(rvec, Rcv);
  Pose pose;
  cv::cv2eigen(Rcv, pose.R);
  cv::cv2eigen(tvec, pose.t);
  return pose;
}

// Pixels from where `cam` sees X to `pixel`; infinite when X is behind the camera.
double reprojection_px(const Camera& cam, const Eigen::Vector3d& X, const Eigen::Vector2d& pixel) {
  const auto proj = cam.project(X);
  return proj ? (*proj - pixel).norm() : std::numeric_limits<double>::infinity();
}

}  // namespace

void IncrementalOptions::validate() const {
  auto fail = [](const char* name, auto value, const char* rule) {
    throw InputError(fmt::format("incremental SfM option {} must be {}, got {}", name, rule, value));
  };
  if (init_min_inliers < 8) fail("init_min_inliers", init_min_inliers, ">= 8");
  if (!(init_min_angle_deg > 0 && init_min_angle_deg < 90)) fail("init_min_angle_deg", init_min_angle_deg, "in (0, 90)");
  if (!(init_max_homography_ratio > 0 && init_max_homography_ratio <= 1)) fail("init_max_homography_ratio", init_max_homography_ratio, "in (0, 1]");
  if (!(init_planar_min_angle_deg >= init_min_angle_deg && init_planar_min_angle_deg < 90)) fail("init_planar_min_angle_deg", init_planar_min_angle_deg, "in [init_min_angle_deg, 90)");
  if (init_max_candidates < 1) fail("init_max_candidates", init_max_candidates, ">= 1");
  if (!(ransac_threshold_px > 0)) fail("ransac_threshold_px", ransac_threshold_px, "> 0");
  if (!(ransac_confidence > 0 && ransac_confidence < 1)) fail("ransac_confidence", ransac_confidence, "in (0, 1)");
  if (ransac_max_iterations < 10) fail("ransac_max_iterations", ransac_max_iterations, ">= 10");
  if (resection_min_inliers < 4) fail("resection_min_inliers", resection_min_inliers, ">= 4");
  if (!(resection_min_inlier_ratio >= 0 && resection_min_inlier_ratio <= 1)) fail("resection_min_inlier_ratio", resection_min_inlier_ratio, "in [0, 1]");
  if (retry_min_inliers < 4 || retry_min_inliers > resection_min_inliers) fail("retry_min_inliers", retry_min_inliers, "in [4, resection_min_inliers]");
  if (!(retry_min_inlier_ratio >= 0 && retry_min_inlier_ratio <= 1)) fail("retry_min_inlier_ratio", retry_min_inlier_ratio, "in [0, 1]");
  if (retry_min_pair_matches < 8) fail("retry_min_pair_matches", retry_min_pair_matches, ">= 8");
  if (!(retry_min_pair_agreement > 0 && retry_min_pair_agreement <= 1)) fail("retry_min_pair_agreement", retry_min_pair_agreement, "in (0, 1]");
  if (!(min_triangulation_angle_deg >= 0 && min_triangulation_angle_deg < 90)) fail("min_triangulation_angle_deg", min_triangulation_angle_deg, "in [0, 90)");
  if (!(max_reprojection_px > 0)) fail("max_reprojection_px", max_reprojection_px, "> 0");
  if (!(final_max_reprojection_px > 0)) fail("final_max_reprojection_px", final_max_reprojection_px, "> 0");
  if (local_ba_images < 1) fail("local_ba_images", local_ba_images, ">= 1");
  if (local_ba_max_observations < 0) fail("local_ba_max_observations", local_ba_max_observations, ">= 0");
  if (global_ba_max_observations < 0) fail("global_ba_max_observations", global_ba_max_observations, ">= 0");
  if (!(global_ba_growth > 1)) fail("global_ba_growth", global_ba_growth, "> 1");
  if (calibration_min_images < 2) fail("calibration_min_images", calibration_min_images, ">= 2");
  if (higher_order_min_images < calibration_min_images) {
    fail("higher_order_min_images", higher_order_min_images, ">= calibration_min_images");
  }
  if (principal_point_min_images < 2) fail("principal_point_min_images", principal_point_min_images, ">= 2");
  if (intermediate_ba_max_iterations < 1) fail("intermediate_ba_max_iterations", intermediate_ba_max_iterations, ">= 1");
  if (!(intermediate_ba_function_tolerance > 0)) fail("intermediate_ba_function_tolerance", intermediate_ba_function_tolerance, "> 0");
  if (!(final_ba_function_tolerance > 0)) fail("final_ba_function_tolerance", final_ba_function_tolerance, "> 0");
  if (final_refinement_passes < 1) fail("final_refinement_passes", final_refinement_passes, ">= 1");
  bundle.validate();
}

namespace {

using namespace sfm_detail;

struct Track {
  std::vector<TrackElement> elements;
  std::vector<char> inlier;  // per element: usable (not rejected as an outlier)
  bool has_point = false;
  Eigen::Vector3d X = Eigen::Vector3d::Zero();
};

struct TwoViewGeometry {
  bool ok = false;
  int inliers = 0;
  double homography_ratio = 1;
  double median_angle_deg = 0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

class IncrementalMapper {
 public:
  IncrementalMapper(const IncrementalOptions& options, const std::vector<CameraGroup>& groups,
                    const std::vector<ImageInput>& images,
                    const std::vector<ImageKeypoints>& keypoints,
                    const std::vector<PairMatches>& matches)
      : opt_(options), groups_(groups), images_(images), keypoints_(keypoints), matches_(matches) {}

  Reconstruction run(IncrementalSummary& summary);

 private:
  // --- setup
  void prepare_intrinsics();
  void build_track_index(IncrementalSummary& summary);
  // --- geometry helpers
  const Intrinsics& intrinsics_of(int image) const { return intr_[images_[image].group]; }
  Eigen::Vector2d pixel(const TrackElement& e) const { return keypoints_[e.image].points[e.keypoint]; }
  Eigen::Vector2d normalised(const TrackElement& e) const {
    return intrinsics_of(e.image).to_normalised(pixel(e));
  }
  double focal_of(int image) const { return intrinsics_of(image).fx; }
  Camera camera(int image) const { return Camera{intrinsics_of(image), poses_[image]}; }
  double error_px(const Track& t, std::size_t k) const;
  // A world point and where a photo sees it.
  struct Correspondence {
    Eigen::Vector3d X;
    Eigen::Vector2d pixel;
  };
  // How many of them a pose of `image` reprojects within max_reprojection_px.
  std::size_t fitting_correspondences(int image, const Pose& pose,
                                      const std::vector<Correspondence>& c) const;
  // --- stages
  TwoViewGeometry two_view(const PairMatches& pair) const;
  std::pair<int, int> initialise();
  // Acceptance rule of a resection: the normal one, or the retry's (fewer inliers,
  // checked against the verified pair matches).
  struct ResectionRule {
    int min_inliers;
    double min_inlier_ratio;
    bool check_pairs;
  };
  bool try_register(int image, const ResectionRule& rule);
  // Unregistered images not yet tried at the current model size (`tried_at`), with at
  // least `min_visible` triangulated tracks, most visible first.
  std::vector<int> next_best(const std::vector<int>& tried_at, int min_visible) const;
  int register_next();
  int register_left_out();
  // Verified matches of `image` with registered photos, and how many of them lie
  // within `max_px` of the epipolar lines implied by `pose` and the registered poses.
  std::pair<std::size_t, std::size_t> pair_agreement(int image, const Pose& pose,
                                                     double max_px) const;
  // Elements of `t` that are inliers in registered photos.
  std::vector<std::size_t> usable_elements(const Track& t) const;
  // The multi-view DLT point of `t` from the elements `use` (non-finite when degenerate).
  Eigen::Vector3d dlt_point(const Track& t, const std::vector<std::size_t>& use) const;
  bool triangulate_track(Track& t, double max_error_px);
  std::size_t triangulate_image(int image);
  std::size_t retriangulate_all();
  std::size_t complete_tracks(double max_error_px);
  std::size_t filter_points(const std::vector<int>& tracks, double max_error_px);
  std::vector<int> all_point_tracks() const;
  void adjust(const std::vector<int>& variable_images, bool global, bool bounded = false);
  // The points of a local adjustment within local_ba_max_observations.
  std::vector<int> bound_local_points(const std::vector<int>& ids,
                                      const std::vector<int>& variable_images,
                                      const std::vector<char>& variable) const;
  // The points of an intermediate global adjustment within global_ba_max_observations.
  std::vector<int> bound_global_points(const std::vector<int>& ids) const;
  // Points left out of an adjustment, triangulated again from the adjusted poses.
  void retriangulate_left_out(const std::vector<int>& all_ids, const std::vector<int>& adjusted);
  bool final_stage_ = false;  // final adjustments run to the full tolerances
  void local_adjust(int image);
  // bounded: an intermediate adjustment (global_ba_max_observations applies).
  void global_adjust(double max_error_px, bool bounded = false);
  Reconstruction result() const;
  void log_unregistered(int image) const;  // why an image stayed out (debug log)

  const IncrementalOptions& opt_;
  const std::vector<CameraGroup>& groups_;
  const std::vector<ImageInput>& images_;
  const std::vector<ImageKeypoints>& keypoints_;
  const std::vector<PairMatches>& matches_;

  std::vector<Intrinsics> intr_;
  std::vector<Track> tracks_;
  std::vector<std::vector<int>> track_of_;     // [image][keypoint] -> track or -1
  std::vector<std::vector<int>> image_tracks_; // [image] -> tracks seen in it
  std::vector<char> registered_;
  std::vector<Pose> poses_;
  std::vector<int> failed_at_;  // registered count at the last failed attempt, -1 if none
  std::vector<int> retried_at_; // the same for the relaxed retry
  std::vector<std::vector<int>> pairs_of_; // [image] -> indices into matches_
  std::size_t retry_registered_ = 0;
  int n_registered_ = 0;
  std::pair<int, int> init_pair_{-1, -1};
  int local_count_ = 0, global_count_ = 0, bounded_count_ = 0;
  std::size_t filtered_ = 0;
  double ba_seconds_ = 0;
};

void IncrementalMapper::prepare_intrinsics() {
  for (std::size_t g = 0; g < groups_.size(); ++g) {
    Intrinsics k = groups_[g].intrinsics;
    if (k.width <= 0 || k.height <= 0) {
      throw InputError(fmt::format("camera group {}: image size {}x{} is not valid", g, k.width,
                                   k.height));
    }
    if (!(k.fx > 0) || !(k.fy > 0)) {
      // No EXIF focal: a common field of view (about 45 degrees across the long side);
      // self-calibration takes it from there.
      k.fx = k.fy = 1.2 * std::max(k.width, k.height);
      k.cx = 0.5 * (k.width - 1);  // (0,0) is the centre of the top-left pixel
      k.cy = 0.5 * (k.height - 1);
    }
    intr_.push_back(k);
  }
}

void IncrementalMapper::build_track_index(IncrementalSummary& summary) {
  TrackStatistics stats;
  auto raw = build_tracks(keypoints_, matches_, &stats);
  summary.tracks = stats.tracks;
  summary.inconsistent_tracks = stats.inconsistent_tracks;
  summary.repaired_tracks = stats.repaired_tracks;
  track_of_.resize(images_.size());
  image_tracks_.resize(images_.size());
  for (std::size_t i = 0; i < images_.size(); ++i) {
    track_of_[i].assign(keypoints_[i].points.size(), -1);
  }
  tracks_.reserve(raw.size());
  for (auto& elements : raw) {
    const int id = int(tracks_.size());
    for (const auto& e : elements) {
      track_of_[e.image][e.keypoint] = id;
      image_tracks_[e.image].push_back(id);
    }
    Track t;
    t.inlier.assign(elements.size(), 1);
    t.elements = std::move(elements);
    tracks_.push_back(std::move(t));
  }
}

double IncrementalMapper::error_px(const Track& t, std::size_t k) const {
  const auto& e = t.elements[k];
  return reprojection_px(camera(e.image), t.X, pixel(e));
}

std::size_t IncrementalMapper::fitting_correspondences(int image, const Pose& pose,
                                                      const std::vector<Correspondence>& c) const {
  const Camera cam{intrinsics_of(image), pose};
  std::size_t n = 0;
  for (const auto& [X, px] : c) {
    if (reprojection_px(cam, X, px) <= opt_.max_reprojection_px) ++n;
  }
  return n;
}

TwoViewGeometry IncrementalMapper::two_view(const PairMatches& pair) const {
  TwoViewGeometry g;
  std::vector<cv::Point2d> pa, pb;
  for (const auto& [ka, kb] : pair.matches) {
    const int ta = track_of_[pair.image_a][ka];
    if (ta < 0 || ta != track_of_[pair.image_b][kb]) continue;
    const Eigen::Vector2d a = normalised({pair.image_a, ka});
    const Eigen::Vector2d b = normalised({pair.image_b, kb});
    pa.emplace_back(a.x(), a.y());
    pb.emplace_back(b.x(), b.y());
  }
  if (int(pa.size()) < opt_.init_min_inliers) return g;
  const double threshold =
      opt_.ransac_threshold_px / (0.5 * (focal_of(pair.image_a) + focal_of(pair.image_b)));
  cv::Mat mask;
  const cv::Mat E = cv::findEssentialMat(pa, pb, 1.0, cv::Point2d(0, 0), cv::RANSAC,
                                         opt_.ransac_confidence, threshold, mask);
  if (E.rows != 3 || E.cols != 3) return g;  // several solutions stacked or none
  cv::Mat R, t;
  g.inliers = cv::recoverPose(E, pa, pb, R, t, 1.0, cv::Point2d(0, 0), mask);
  if (g.inliers < opt_.init_min_inliers) return g;
  cv::Mat hmask;
  cv::findHomography(pa, pb, cv::RANSAC, threshold, hmask, opt_.ransac_max_iterations,
                     opt_.ransac_confidence);
  g.homography_ratio = hmask.empty() ? 0.0 : double(cv::countNonZero(hmask)) / g.inliers;
  cv::cv2eigen(R, g.R);
  cv::cv2eigen(t, g.t);
  // Median triangulation angle of the inliers with P1 = [I|0], P2 = [R|t].
  const std::vector<Pose> poses{Pose{}, Pose{g.R, g.t}};
  const std::vector<Eigen::Vector3d> centres{Eigen::Vector3d::Zero(), poses[1].centre()};
  std::vector<double> angles;
  for (int i = 0; i < int(pa.size()); ++i) {
    if (!mask.at<uchar>(i)) continue;
    const Eigen::Vector3d X = triangulate_dlt(
        poses, {Eigen::Vector2d(pa[i].x, pa[i].y), Eigen::Vector2d(pb[i].x, pb[i].y)});
    if (!X.allFinite() || X.z() <= 0 || poses[1].to_camera(X).z() <= 0) continue;
    angles.push_back(max_triangulation_angle_deg(X, centres));
  }
  if (angles.empty()) return g;
  g.median_angle_deg = median_in_place(angles);
  g.ok = true;
  return g;
}

std::pair<int, int> IncrementalMapper::initialise() {
  // Pairs by decreasing number of track-consistent matches.
  // The initial pair comes from the largest group of matched photos: a pair from a
  // smaller group (photos of another place, a trench end without a bridge) would
  // leave the larger group unaligned.
  const auto groups = match_groups(images_.size(), matches_);
  std::set<int> largest(groups.front().begin(), groups.front().end());
  std::vector<std::pair<std::size_t, int>> order;
  for (int i = 0; i < int(matches_.size()); ++i) {
    if (!largest.count(matches_[i].image_a)) continue;
    order.emplace_back(matches_[i].matches.size(), i);
  }
  std::sort(order.rbegin(), order.rend());
  if (int(order.size()) > opt_.init_max_candidates) order.resize(opt_.init_max_candidates);

  // Many inliers, with a bonus for baseline up to twice the minimum angle.
  auto score = [](const TwoViewGeometry& g, double min_angle) {
    return g.inliers * std::min(g.median_angle_deg / (2 * min_angle), 1.0);
  };
  // A homography explains a pair seen from one spot (pure rotation: no depth) but also
  // any pair of a flat surface, as a freshly trowelled layer nearly is. The median
  // triangulation angle tells them apart (Schoenberger & Frahm 2016, sec. 4.2: a
  // planar scene with enough parallax is a valid initialisation), so the ratio only
  // rules out pairs whose angle is below `init_planar_min_angle_deg`.
  auto conditioned = [&](const TwoViewGeometry& g, double min_angle, double max_h) {
    if (g.median_angle_deg < min_angle) return false;
    return g.homography_ratio <= max_h || g.median_angle_deg >= opt_.init_planar_min_angle_deg;
  };
  std::vector<std::pair<int, TwoViewGeometry>> candidates;
  double best_strict = 0;
  for (const auto& [n, i] : order) {
    // Pairs come by decreasing match count and a score never exceeds the count:
    // once it is below the best strict score, no later pair can win.
    if (double(n) <= best_strict) break;
    check_cancelled();
    auto g = two_view(matches_[i]);
    if (!g.ok) continue;
    if (conditioned(g, opt_.init_min_angle_deg, opt_.init_max_homography_ratio)) {
      best_strict = std::max(best_strict, score(g, opt_.init_min_angle_deg));
    }
    candidates.emplace_back(i, g);
  }
  // Strict criteria first; relaxed ones (with a warning) before giving up.
  int best = -1;
  double best_score = 0;
  for (int pass = 0; pass < 2 && best < 0; ++pass) {
    const double min_angle = pass == 0 ? opt_.init_min_angle_deg : 0.5 * opt_.init_min_angle_deg;
    const double max_h = pass == 0 ? opt_.init_max_homography_ratio : 0.95;
    for (int c = 0; c < int(candidates.size()); ++c) {
      const auto& g = candidates[c].second;
      if (!conditioned(g, min_angle, max_h)) continue;
      if (score(g, min_angle) > best_score) {
        best_score = score(g, min_angle);
        best = c;
      }
    }
    if (best >= 0 && pass == 1) {
      log::warn("sfm: no initial pair meets the strict criteria; using a weaker one");
    }
  }
  if (best < 0) {
    throw ProcessingError(fmt::format(
        "sfm: no well-conditioned initial image pair among {} candidates (need >= {} "
        "inliers, median triangulation angle >= {} deg, homography ratio <= {}): the photos "
        "may overlap too little or be taken from one spot",
        order.size(), opt_.init_min_inliers, opt_.init_min_angle_deg,
        opt_.init_max_homography_ratio));
  }
  const auto& pair = matches_[candidates[best].first];
  const auto& g = candidates[best].second;
  const int a = pair.image_a, b = pair.image_b;
  poses_[a] = Pose{};
  poses_[b] = Pose{g.R, g.t.normalized()};
  registered_[a] = registered_[b] = 1;
  n_registered_ = 2;
  log::debug("sfm: initial pair {} / {}: {} inliers, median angle {:.1f} deg, H ratio {:.2f}",
             images_[a].name, images_[b].name, g.inliers, g.median_angle_deg, g.homography_ratio);
  return {a, b};
}

std::vector<std::size_t> IncrementalMapper::usable_elements(const Track& t) const {
  std::vector<std::size_t> use;
  for (std::size_t k = 0; k < t.elements.size(); ++k) {
    if (t.inlier[k] && registered_[t.elements[k].image]) use.push_back(k);
  }
  return use;
}

Eigen::Vector3d IncrementalMapper::dlt_point(const Track& t, const std::vector<std::size_t>& use) const {
  std::vector<Pose> poses;
  std::vector<Eigen::Vector2d> xn;
  for (auto k : use) {
    poses.push_back(poses_[t.elements[k].image]);
    xn.push_back(normalised(t.elements[k]));
  }
  return triangulate_dlt(poses, xn);
}

bool IncrementalMapper::triangulate_track(Track& t, double max_error_px) {
  std::vector<std::size_t> use = usable_elements(t);
  // Two rounds: the linear solution from every view, then without views it fits badly.
  for (int round = 0; round < 2; ++round) {
    if (use.size() < 2) return false;
    const Eigen::Vector3d X = dlt_point(t, use);
    if (!X.allFinite()) return false;
    t.X = X;
    std::vector<std::size_t> good;
    std::vector<Eigen::Vector3d> centres;
    for (auto k : use) {
      if (error_px(t, k) <= max_error_px) {
        good.push_back(k);
        centres.push_back(poses_[t.elements[k].image].centre());
      }
    }
    if (good.size() == use.size()) {
      if (max_triangulation_angle_deg(X, centres) < opt_.min_triangulation_angle_deg) return false;
      t.has_point = true;
      return true;
    }
    use = std::move(good);
  }
  return false;
}

std::size_t IncrementalMapper::triangulate_image(int image) {
  std::size_t n = 0;
  for (int id : image_tracks_[image]) {
    auto& t = tracks_[id];
    if (t.has_point) continue;
    if (triangulate_track(t, opt_.max_reprojection_px)) ++n;
  }
  return n;
}

std::size_t IncrementalMapper::retriangulate_all() {
  std::size_t n = 0;
  for (auto& t : tracks_) {
    if (t.has_point) continue;
    // Give rejected observations another chance with the improved cameras.
    std::fill(t.inlier.begin(), t.inlier.end(), 1);
    if (triangulate_track(t, opt_.max_reprojection_px)) ++n;
  }
  return n;
}

std::size_t IncrementalMapper::complete_tracks(double max_error_px) {
  // Observations rejected earlier (or in images registered after the point was made)
  // rejoin their point when they now fit.
  std::size_t n = 0;
  for (auto& t : tracks_) {
    if (!t.has_point) continue;
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      if (!t.inlier[k] && registered_[t.elements[k].image] && error_px(t, k) <= max_error_px) {
        t.inlier[k] = 1;
        ++n;
      }
    }
  }
  return n;
}

std::vector<int> IncrementalMapper::all_point_tracks() const {
  std::vector<int> ids;
  for (int i = 0; i < int(tracks_.size()); ++i) {
    if (tracks_[i].has_point) ids.push_back(i);
  }
  return ids;
}

std::size_t IncrementalMapper::filter_points(const std::vector<int>& ids, double max_error_px) {
  std::size_t removed = 0;
  for (int id : ids) {
    auto& t = tracks_[id];
    if (!t.has_point) continue;
    std::vector<Eigen::Vector3d> centres;
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      if (!t.inlier[k] || !registered_[t.elements[k].image]) continue;
      if (error_px(t, k) > max_error_px) {
        t.inlier[k] = 0;
        ++removed;
      } else {
        centres.push_back(poses_[t.elements[k].image].centre());
      }
    }
    // A point needs two good rays at a sufficient angle (Schoenberger & Frahm 2016,
    // sec. 4.5: filter by reprojection error and triangulation angle).
    if (centres.size() < 2 ||
        max_triangulation_angle_deg(t.X, centres) < opt_.min_triangulation_angle_deg) {
      t.has_point = false;
    }
  }
  filtered_ += removed;
  return removed;
}

bool IncrementalMapper::try_register(int image, const ResectionRule& rule) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image_points;
  std::vector<Correspondence> pixels;  // the same in pixels, to judge a pose
  for (int id : image_tracks_[image]) {
    const auto& t = tracks_[id];
    if (!t.has_point) continue;
    for (const auto& e : t.elements) {
      if (e.image != image) continue;
      const Eigen::Vector2d xn = normalised(e);
      object.emplace_back(t.X.x(), t.X.y(), t.X.z());
      image_points.emplace_back(xn.x(), xn.y());
      pixels.push_back({t.X, pixel(e)});
    }
  }
  if (int(object.size()) < rule.min_inliers) {
    log::debug("sfm: resection of {}: {} 2D-3D correspondences, fewer than {}", images_[image].name,
               object.size(), rule.min_inliers);
    return false;
  }
  // Normalised coordinates with K = I: the threshold is in focal units.
  const double threshold = opt_.ransac_threshold_px / focal_of(image);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  std::size_t n_inliers = 0;
  Pose pose;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  try {
    const bool ok = cv::solvePnPRansac(object, image_points, K, cv::noArray(), rvec, tvec, false,
                                       opt_.ransac_max_iterations, float(threshold),
                                       opt_.ransac_confidence, inliers, cv::SOLVEPNP_AP3P);
    if (!ok || int(inliers.size()) < rule.min_inliers ||
        double(inliers.size()) < rule.min_inlier_ratio * double(object.size())) {
      log::debug("sfm: resection of {} rejected: {} of {} correspondences inliers (RANSAC {})",
                 images_[image].name, inliers.size(), object.size(), ok ? "ok" : "failed");
      return false;
    }
    // Levenberg-Marquardt on the inliers (the minimal-sample pose is noisy).
    std::vector<cv::Point3d> in_obj;
    std::vector<cv::Point2d> in_img;
    for (int i : inliers) {
      in_obj.push_back(object[i]);
      in_img.push_back(image_points[i]);
    }
    cv::Mat rvec_lm = rvec.clone(), tvec_lm = tvec.clone();
    cv::solvePnPRefineLM(in_obj, in_img, K, cv::noArray(), rvec_lm, tvec_lm);
    // Both poses are judged where the adjustment and the track filter judge them: in
    // pixels, through the full lens model, in front of the camera. Normalised
    // coordinates do not see a point behind the camera and stretch towards the edge of
    // a wide lens: a fisheye photo once had 210 of 214 RANSAC inliers there, of which
    // 6 fitted in pixels (0 after the refinement), and was placed 2.7 m off.
    const Pose ransac_pose = pose_from_cv(rvec, tvec);
    const Pose refined_pose = pose_from_cv(rvec_lm, tvec_lm);
    const std::size_t fit_ransac = fitting_correspondences(image, ransac_pose, pixels);
    const std::size_t fit_refined = fitting_correspondences(image, refined_pose, pixels);
    pose = fit_refined >= fit_ransac ? refined_pose : ransac_pose;
    n_inliers = std::max(fit_ransac, fit_refined);
    if (int(n_inliers) < rule.min_inliers ||
        double(n_inliers) < rule.min_inlier_ratio * double(object.size())) {
      log::debug("sfm: resection of {} rejected: {} of {} correspondences within {:.1f} px "
                 "(RANSAC {}, refined {})", images_[image].name, n_inliers, object.size(),
                 opt_.max_reprojection_px, fit_ransac, fit_refined);
      return false;
    }
  } catch (const cv::Exception& e) {
    log::debug("sfm: resection of {} failed in OpenCV: {}", images_[image].name, e.what());
    return false;
  }
  if (rule.check_pairs) {
    const auto [matches, agree] = pair_agreement(image, pose, opt_.ransac_threshold_px);
    const bool ok = int(matches) >= opt_.retry_min_pair_matches &&
                    double(agree) >= opt_.retry_min_pair_agreement * double(matches);
    log::debug("sfm: retry of {}: {} of {} 2D-3D inliers; {} of {} verified pair matches agree "
               "with the pose: {}", images_[image].name, n_inliers, object.size(), agree, matches,
               ok ? "accepted" : "rejected");
    if (!ok) return false;
    log::info("sfm: {} registered on retry: {} of {} 2D-3D inliers, {} of {} verified matches "
              "with registered photos agree with its pose", images_[image].name, n_inliers,
              object.size(), agree, matches);
  }
  log::debug("sfm: registered {} as photo {}: {} of {} 2D-3D inliers", images_[image].name,
             n_registered_ + 1, n_inliers, object.size());
  poses_[image] = pose;
  registered_[image] = 1;
  ++n_registered_;
  // Observations of existing points in the new image join only when they fit.
  for (int id : image_tracks_[image]) {
    auto& tr = tracks_[id];
    if (!tr.has_point) continue;
    for (std::size_t k = 0; k < tr.elements.size(); ++k) {
      if (tr.elements[k].image == image && error_px(tr, k) > opt_.max_reprojection_px) {
        tr.inlier[k] = 0;
      }
    }
  }
  return true;
}

std::vector<int> IncrementalMapper::next_best(const std::vector<int>& tried_at, int min_visible) const {
  // Next best images: most visible triangulated tracks (Snavely et al. 2006), skipping
  // those already tried at the current model size.
  std::vector<std::pair<int, int>> ranked;
  for (int i = 0; i < int(images_.size()); ++i) {
    if (registered_[i] || tried_at[i] == n_registered_) continue;
    int visible = 0;
    for (int id : image_tracks_[i]) visible += tracks_[id].has_point ? 1 : 0;
    if (visible >= min_visible) ranked.emplace_back(visible, i);
  }
  std::sort(ranked.rbegin(), ranked.rend());
  std::vector<int> out;
  for (const auto& r : ranked) out.push_back(r.second);
  return out;
}

int IncrementalMapper::register_next() {
  for (int image : next_best(failed_at_, opt_.resection_min_inliers)) {
    check_cancelled();
    if (try_register(image, {opt_.resection_min_inliers, opt_.resection_min_inlier_ratio, false})) {
      return image;
    }
    failed_at_[image] = n_registered_;
  }
  return -1;
}

int IncrementalMapper::register_left_out() {
  if (!opt_.retry_unregistered) return -1;
  for (int image : next_best(retried_at_, opt_.retry_min_inliers)) {
    check_cancelled();
    retried_at_[image] = n_registered_;
    if (try_register(image, {opt_.retry_min_inliers, opt_.retry_min_inlier_ratio, true})) {
      ++retry_registered_;
      return image;
    }
  }
  return -1;
}

std::pair<std::size_t, std::size_t> IncrementalMapper::pair_agreement(int image, const Pose& pose,
                                                                      double max_px) const {
  std::size_t total = 0, agree = 0;
  for (int m : pairs_of_[image]) {
    const auto& pair = matches_[m];
    const int other = pair.image_a == image ? pair.image_b : pair.image_a;
    if (!registered_[other]) continue;
    // x_image ~ R X + t, x_other ~ R_o X + t_o: from `image` to `other`,
    // R_rel = R_o R^T, t_rel = t_o - R_rel t, E = [t_rel]x R_rel, x_o^T E x = 0.
    const Pose& po = poses_[other];
    const Eigen::Matrix3d R_rel = po.R * pose.R.transpose();
    const Eigen::Vector3d t_rel = po.t - R_rel * pose.t;
    if (t_rel.norm() < 1e-12) continue;  // no baseline: no epipolar geometry
    Eigen::Matrix3d tx;
    tx << 0, -t_rel.z(), t_rel.y(), t_rel.z(), 0, -t_rel.x(), -t_rel.y(), t_rel.x(), 0;
    const Eigen::Matrix3d E = tx * R_rel;
    // Sampson distance in normalised units; the pixel limit by the mean focal length.
    const double limit = max_px / (0.5 * (focal_of(image) + focal_of(other)));
    for (const auto& [ka, kb] : pair.matches) {
      const int k_image = pair.image_a == image ? ka : kb;
      const int k_other = pair.image_a == image ? kb : ka;
      const Eigen::Vector3d x = normalised({image, k_image}).homogeneous();
      const Eigen::Vector3d xo = normalised({other, k_other}).homogeneous();
      const Eigen::Vector3d Ex = E * x, Etxo = E.transpose() * xo;
      const double r = xo.dot(Ex);
      const double d2 = r * r / (Ex.head<2>().squaredNorm() + Etxo.head<2>().squaredNorm());
      ++total;
      if (d2 <= limit * limit) ++agree;
    }
  }
  return {total, agree};
}

void IncrementalMapper::adjust(const std::vector<int>& variable_images, bool global, bool bounded) {
  BaProblem problem;
  for (std::size_t g = 0; g < intr_.size(); ++g) {
    add_group(problem, intr_[g], groups_[g].calibration_fixed);
  }
  std::vector<int> camera_of(images_.size(), -1);
  std::vector<int> image_of_camera;
  std::vector<char> variable(images_.size(), 0);
  for (int i : variable_images) variable[i] = 1;
  auto add_camera = [&](int image) {
    if (camera_of[image] >= 0) return camera_of[image];
    BaCamera cam;
    cam.pose = to_block(poses_[image]);
    cam.group = images_[image].group;
    cam.variable = variable[image];
    camera_of[image] = int(problem.cameras.size());
    image_of_camera.push_back(image);
    problem.cameras.push_back(cam);
    return camera_of[image];
  };
  for (int i : variable_images) add_camera(i);

  // Points seen by a variable image, with all their registered observations.
  std::vector<int> point_tracks;
  std::set<int> chosen;
  for (int i : variable_images) {
    for (int id : image_tracks_[i]) {
      if (tracks_[id].has_point && chosen.insert(id).second) point_tracks.push_back(id);
    }
  }
  if (!global && opt_.local_ba_max_observations > 0) {
    point_tracks = bound_local_points(point_tracks, variable_images, variable);
  }
  std::vector<int> all_tracks;  // of a bounded global adjustment: every point before the bound
  if (global && bounded && opt_.global_ba_max_observations > 0) {
    all_tracks = point_tracks;
    std::sort(all_tracks.begin(), all_tracks.end());
    point_tracks = bound_global_points(point_tracks);
    if (point_tracks.size() == all_tracks.size()) {
      all_tracks.clear();
    } else {
      ++bounded_count_;
    }
  }
  for (int id : point_tracks) {
    const auto& t = tracks_[id];
    const int p = int(problem.points.size());
    problem.points.push_back(t.X);
    problem.point_variable.push_back(1);
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      const auto& e = t.elements[k];
      if (!t.inlier[k] || !registered_[e.image]) continue;
      problem.observations.push_back({add_camera(e.image), p, pixel(e), false});
    }
  }
  const int n_constant = int(problem.cameras.size() - variable_images.size());
  if (global || n_constant < 2) {
    const int a = add_camera(init_pair_.first), b = add_camera(init_pair_.second);
    set_gauge(problem, a, b);
  }
  // Self-calibration in global adjustments once enough views constrain it.
  BundleOptions bo = opt_.bundle;
  if (!final_stage_) {
    bo.max_iterations = std::min(bo.max_iterations, opt_.intermediate_ba_max_iterations);
    bo.function_tolerance = std::max(bo.function_tolerance, opt_.intermediate_ba_function_tolerance);
  } else {
    bo.function_tolerance = std::max(bo.function_tolerance, opt_.final_ba_function_tolerance);
  }
  problem.refine_intrinsics = global && n_registered_ >= opt_.calibration_min_images;
  if (n_registered_ < opt_.principal_point_min_images) bo.refine.principal_point = false;
  if (n_registered_ < opt_.higher_order_min_images) {
    bo.refine.k3 = bo.refine.k4 = bo.refine.tangential = false;
  }

  const auto s = solve_bundle(bo, problem);
  ba_seconds_ += s.seconds;
  (global ? global_count_ : local_count_)++;

  // A fixed calibration is not read back (bit-identical, see bundle_adjust()).
  for (std::size_t g = 0; g < intr_.size(); ++g) {
    if (!groups_[g].calibration_fixed) from_block(problem.intrinsics[g], intr_[g]);
  }
  for (std::size_t c = 0; c < problem.cameras.size(); ++c) {
    if (!problem.cameras[c].variable) continue;
    const int image = image_of_camera[c];
    poses_[image] = pose_from_block(problem.cameras[c].pose);
  }
  for (std::size_t p = 0; p < point_tracks.size(); ++p) tracks_[point_tracks[p]].X = problem.points[p];
  log::debug("sfm: {} BA over {} images, {} observations{}: rmse {:.3f} px, {} iterations, {:.2f} s",
             global ? "global" : "local", variable_images.size(), s.observations,
             all_tracks.empty() ? "" : fmt::format(" ({} of {} points)", point_tracks.size(), all_tracks.size()),
             s.rmse_px, s.iterations, s.seconds);
  if (!all_tracks.empty()) retriangulate_left_out(all_tracks, point_tracks);
  filter_points(point_tracks, opt_.max_reprojection_px);
}

std::vector<int> IncrementalMapper::bound_local_points(const std::vector<int>& ids,
                                                      const std::vector<int>& variable_images,
                                                      const std::vector<char>& variable) const {
  struct Candidate {
    int id;
    bool seen_by_new;  // by variable_images[0], the image just registered
    int variable_rays; // inlier observations in variable images
    int rays;          // inlier observations in registered images
  };
  std::vector<Candidate> candidates;
  std::size_t total = 0;
  for (int id : ids) {
    const auto& t = tracks_[id];
    Candidate c{id, false, 0, 0};
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      const int image = t.elements[k].image;
      if (!t.inlier[k] || !registered_[image]) continue;
      ++c.rays;
      if (variable[image]) ++c.variable_rays;
      if (image == variable_images.front()) c.seen_by_new = true;
    }
    total += std::size_t(c.rays);
    candidates.push_back(c);
  }
  const auto budget = std::size_t(opt_.local_ba_max_observations);
  if (total <= budget) return ids;
  std::stable_sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.seen_by_new != b.seen_by_new) return a.seen_by_new;
    return a.variable_rays > b.variable_rays;
  });
  std::vector<int> kept;
  std::size_t used = 0;
  for (const auto& c : candidates) {
    if (used + std::size_t(c.rays) > budget) continue;
    used += std::size_t(c.rays);
    kept.push_back(c.id);
  }
  return kept;
}

std::vector<int> IncrementalMapper::bound_global_points(const std::vector<int>& ids) const {
  struct Candidate {
    int id;
    int rays;  // inlier observations in registered images
  };
  std::vector<Candidate> candidates;
  candidates.reserve(ids.size());
  std::size_t total = 0;
  for (int id : ids) {
    const Candidate c{id, int(usable_elements(tracks_[id]).size())};
    total += std::size_t(c.rays);
    candidates.push_back(c);
  }
  const auto budget = std::size_t(opt_.global_ba_max_observations);
  if (total <= budget || n_registered_ < 1) return ids;
  // Longest tracks first: each ties the most photos together for its cost. A point is
  // taken while one of its photos is below its share, so that no photo is left with
  // too few points to hold its pose.
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.rays > b.rays; });
  const std::size_t share = budget / std::size_t(n_registered_);
  std::vector<std::size_t> taken(images_.size(), 0);
  std::vector<int> kept;
  std::size_t used = 0;
  for (const auto& c : candidates) {
    if (used + std::size_t(c.rays) > budget) continue;
    const auto& t = tracks_[c.id];
    const std::vector<std::size_t> use = usable_elements(t);
    const bool needed =
        std::any_of(use.begin(), use.end(), [&](std::size_t k) { return taken[t.elements[k].image] < share; });
    if (!needed) continue;
    for (std::size_t k : use) ++taken[t.elements[k].image];
    used += std::size_t(c.rays);
    kept.push_back(c.id);
  }
  std::sort(kept.begin(), kept.end());  // the order the problem is built in, as unbounded
  return kept;
}

void IncrementalMapper::retriangulate_left_out(const std::vector<int>& all_ids, const std::vector<int>& adjusted) {
  // Both sorted by track id.
  std::vector<int> left_out;
  std::set_difference(all_ids.begin(), all_ids.end(), adjusted.begin(), adjusted.end(),
                      std::back_inserter(left_out));
  for (int id : left_out) {
    auto& t = tracks_[id];
    const std::vector<std::size_t> use = usable_elements(t);
    if (use.size() < 2) continue;
    const Eigen::Vector3d X = dlt_point(t, use);
    if (X.allFinite()) t.X = X;  // the filter after the adjustment judges it
  }
}

void IncrementalMapper::local_adjust(int image) {
  // The new image and the registered images sharing the most points with it.
  std::map<int, int> shared;
  for (int id : image_tracks_[image]) {
    const auto& t = tracks_[id];
    if (!t.has_point) continue;
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      const int other = t.elements[k].image;
      if (other != image && registered_[other] && t.inlier[k]) ++shared[other];
    }
  }
  std::vector<std::pair<int, int>> ranked;
  for (const auto& [other, n] : shared) ranked.emplace_back(n, other);
  std::sort(ranked.rbegin(), ranked.rend());
  std::vector<int> variable{image};
  for (const auto& [n, other] : ranked) {
    if (int(variable.size()) >= opt_.local_ba_images) break;
    variable.push_back(other);
  }
  adjust(variable, false);
}

void IncrementalMapper::global_adjust(double max_error_px, bool bounded) {
  std::vector<int> all;
  for (int i = 0; i < int(images_.size()); ++i) {
    if (registered_[i]) all.push_back(i);
  }
  adjust(all, true, bounded);
  complete_tracks(max_error_px);
  filter_points(all_point_tracks(), max_error_px);
  retriangulate_all();
}

Reconstruction IncrementalMapper::run(IncrementalSummary& summary) {
  Stopwatch clock;
  prepare_intrinsics();
  build_track_index(summary);
  registered_.assign(images_.size(), 0);
  poses_.assign(images_.size(), Pose{});
  failed_at_.assign(images_.size(), -1);
  retried_at_.assign(images_.size(), -1);
  pairs_of_.assign(images_.size(), {});
  for (std::size_t m = 0; m < matches_.size(); ++m) {
    pairs_of_[matches_[m].image_a].push_back(int(m));
    pairs_of_[matches_[m].image_b].push_back(int(m));
  }
  Progress progress("aligning photos", images_.size());

  init_pair_ = initialise();
  summary.initial_pair_seconds = clock.seconds();
  triangulate_image(init_pair_.second);
  global_adjust(opt_.max_reprojection_px);
  progress.step(2);

  int last_global = n_registered_;
  while (n_registered_ < int(images_.size())) {
    check_cancelled();
    int image = register_next();
    bool retried = false;
    if (image < 0) {
      // Stuck: a global refinement may add points that let another image in, so every
      // image that failed gets another try.
      if (last_global != n_registered_) {
        global_adjust(opt_.max_reprojection_px, true);
        last_global = n_registered_;
        std::fill(failed_at_.begin(), failed_at_.end(), -1);
        continue;
      }
      // Still stuck after a global adjustment: the relaxed, cross-checked retry.
      image = register_left_out();
      if (image < 0) break;
      retried = true;
    }
    progress.step();
    triangulate_image(image);
    // A pose from few points: the global adjustment pins it with its new two-view points.
    if (retried || n_registered_ < opt_.early_global_images ||
        n_registered_ >= opt_.global_ba_growth * last_global) {
      global_adjust(opt_.max_reprojection_px, true);  // covers what the local one would do
      last_global = n_registered_;
    } else {
      local_adjust(image);
    }
  }
  // Final refinement with a gate that tightens to the calibrated model's level. These
  // rounds only decide which observations and points stay: they stop at the
  // intermediate tolerances, and only the last adjustment runs to `bundle`'s.
  for (int pass = 0; pass < opt_.final_refinement_passes; ++pass) {
    check_cancelled();
    const bool last = pass + 1 == opt_.final_refinement_passes;
    const double gate = last ? opt_.final_max_reprojection_px : opt_.max_reprojection_px;
    global_adjust(gate);
  }
  // Last adjustment after the final filtering, so the points removed do not bias it.
  final_stage_ = true;
  {
    std::vector<int> all;
    for (int i = 0; i < int(images_.size()); ++i) {
      if (registered_[i]) all.push_back(i);
    }
    adjust(all, true);
    filter_points(all_point_tracks(), opt_.final_max_reprojection_px);
  }
  progress.finish();

  Reconstruction rec = result();
  summary.images = images_.size();
  summary.registered = std::size_t(n_registered_);
  summary.initial_pair = init_pair_;
  summary.points = rec.points.size();
  summary.observations = 0;
  for (const auto& p : rec.points) summary.observations += p.track.size();
  summary.reprojection_rmse_px = reprojection_rmse_px(rec, keypoints_);
  summary.local_adjustments = local_count_;
  summary.global_adjustments = global_count_;
  summary.bounded_adjustments = bounded_count_;
  summary.filtered_observations = filtered_;
  summary.registered_on_retry = retry_registered_;
  for (std::size_t i = 0; i < images_.size(); ++i) {
    if (!registered_[i]) {
      summary.unregistered.push_back(images_[i].name);
      log_unregistered(int(i));
    }
  }
  summary.adjustment_seconds = ba_seconds_;
  summary.seconds = clock.seconds();
  return rec;
}

void IncrementalMapper::log_unregistered(int image) const {
  std::size_t pairs = 0, matched = 0;
  std::string per_pair;
  for (int m : pairs_of_[image]) {
    const auto& p = matches_[m];
    const int other = p.image_a == image ? p.image_b : p.image_a;
    if (!registered_[other] || p.matches.empty()) continue;
    ++pairs;
    matched += p.matches.size();
    per_pair += fmt::format(" {}:{}", images_[other].name, p.matches.size());
  }
  std::size_t with_point = 0, rays = 0;
  for (int id : image_tracks_[image]) {
    const auto& t = tracks_[id];
    if (!t.has_point) continue;
    ++with_point;
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      if (t.inlier[k] && registered_[t.elements[k].image]) ++rays;
    }
  }
  log::debug("sfm: {} not registered: {} verified matches in {} pairs with registered photos "
             "({}); {} of its {} tracks have a point ({} registered rays)",
             images_[image].name, matched, pairs, per_pair.empty() ? "none" : per_pair.substr(1),
             with_point, image_tracks_[image].size(), rays);
}

Reconstruction IncrementalMapper::result() const {
  Reconstruction rec;
  rec.groups = groups_;
  for (std::size_t g = 0; g < groups_.size(); ++g) rec.groups[g].intrinsics = intr_[g];
  for (std::size_t i = 0; i < images_.size(); ++i) {
    RegisteredImage im;
    im.name = images_[i].name;
    im.group = images_[i].group;
    im.registered = registered_[i];
    if (registered_[i]) im.pose = poses_[i];
    rec.images.push_back(im);
  }
  for (const auto& t : tracks_) {
    if (!t.has_point) continue;
    SparsePoint p;
    p.X = t.X;
    double sum = 0;
    for (std::size_t k = 0; k < t.elements.size(); ++k) {
      if (!t.inlier[k] || !registered_[t.elements[k].image]) continue;
      p.track.push_back(t.elements[k]);
      sum += error_px(t, k);
    }
    if (p.track.size() < 2) continue;
    p.error_px = sum / double(p.track.size());
    const auto& first = p.track.front();
    const auto& colours = keypoints_[first.image].colours;
    if (colours.size() >= 3 * (std::size_t(first.keypoint) + 1)) {
      for (int c = 0; c < 3; ++c) p.colour[c] = colours[3 * first.keypoint + c];
    }
    rec.points.push_back(std::move(p));
  }
  return rec;
}

// The photos fall into groups that no verified match joins (the connected components
// of the match graph): e.g. two ends of a trench photographed without a bridge between
// them, or photos of another place. Only the group that holds the reconstruction can
// be aligned; the others are named so that the user can add bridging photos.
void report_disconnected_groups(const std::vector<ImageInput>& images, const std::vector<PairMatches>& matches,
                                const Reconstruction& rec) {
  const auto sorted = match_groups(images.size(), matches);
  if (sorted.size() < 2) return;
  std::vector<std::string> parts;
  for (const auto& members : sorted) {
    std::size_t registered = 0;
    std::vector<std::string> names;
    for (int i : members) {
      if (rec.images[std::size_t(i)].registered) ++registered;
      names.push_back(images[std::size_t(i)].name);
    }
    parts.push_back(fmt::format("{} photo(s), {} aligned ({})", members.size(), registered, fmt::join(names, ", ")));
  }
  log::warn("sfm: the photos form {} groups that no match joins; only the group holding the alignment is "
            "used; add photos that overlap both to join them: {}",
            sorted.size(), fmt::join(parts, "; "));
}

}  // namespace

Reconstruction reconstruct_incremental(const IncrementalOptions& options,
                                       const std::vector<CameraGroup>& groups,
                                       const std::vector<ImageInput>& images,
                                       const std::vector<ImageKeypoints>& keypoints,
                                       const std::vector<PairMatches>& matches,
                                       IncrementalSummary* summary) {
  options.validate();
  STRATA_CHECK(keypoints.size() == images.size(), "{} keypoint sets for {} images",
               keypoints.size(), images.size());
  for (const auto& im : images) {
    if (im.group < 0 || std::size_t(im.group) >= groups.size()) {
      throw InputError(fmt::format("image {}: camera group {} does not exist ({} groups)",
                                   im.name, im.group, groups.size()));
    }
  }
  if (images.size() < 2) {
    throw ProcessingError(fmt::format("sfm: {} image(s); at least 2 are needed", images.size()));
  }
  IncrementalSummary local;
  const std::clock_t cpu_start = std::clock();
  IncrementalMapper mapper(options, groups, images, keypoints, matches);
  Reconstruction rec = mapper.run(local);
  log::info("sfm: {} of {} images, {} points, {} observations, rmse {:.3f} px; {} local and {} "
            "global adjustments ({:.1f} s); {:.1f} s ({:.1f} s CPU)",
            local.registered, local.images, local.points, local.observations,
            local.reprojection_rmse_px, local.local_adjustments, local.global_adjustments,
            local.adjustment_seconds, local.seconds,
            double(std::clock() - cpu_start) / CLOCKS_PER_SEC);
  if (local.registered < images.size()) {
    log::warn("sfm: {} of {} images registered; not registered: {}", local.registered, images.size(),
              fmt::join(local.unregistered, ", "));
    report_disconnected_groups(images, matches, rec);
  }
  if (summary) *summary = local;
  return rec;
}

}  // namespace strata
