// Structure from motion on synthetic layers with known truth.
#include "core/error.hpp"
#include "geometry/similarity.hpp"
#include "sfm/bundle_adjustment.hpp"
#include "sfm/incremental.hpp"
#include "sfm/quality.hpp"
#include "sfm/tracks.hpp"
#include "sfm/triangulation.hpp"
#include "unit/sfm/synthetic_scene.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

namespace strata {
namespace {

using test::make_scene;
using test::SceneOptions;
using test::SyntheticScene;

// --- tolerances ------------------------------------------------------------------
// 0.3 px keypoint noise at f = 1380 px and 1.6-2.4 m depth is about 0.4 mm on the
// ground per ray; with hundreds of points per photo a camera centre is determined to
// a fraction of a millimetre, so 2 mm leaves room for the calibration trade-offs.
constexpr double kCentreTolM = 0.002;
// Focal length from self-calibration with oblique, rolled views: 0.5 %.
constexpr double kFocalRelTol = 0.005;
// Principal point: correlated with camera tilt; a few pixels still proves recovery
// from a 17 px offset.
constexpr double kPrincipalPointTolPx = 3.0;
// The 2D reprojection error of noise sigma per axis has RMS sigma*sqrt(2); the
// adjustment absorbs a little of it, outliers are filtered: allow 20 % above.
constexpr double kRmseFactor = 1.2;
// Points that come back: a few percent of the ground is seen by one photo only and
// tracks glued by wrong matches that cannot be split are dropped.
constexpr double kPointsRecoveredFraction = 0.75;
// Noise-free scene: everything exact up to solver tolerances (1e-10 relative).
constexpr double kExactRelTol = 1e-6;

struct Alignment {
  double max_centre_error = 0;  // metres, after the similarity
  double rms_centre_error = 0;
  Similarity3 s;
};

// Similarity from the recovered to the true camera centres (Umeyama), residuals.
Alignment align_to_truth(const Reconstruction& rec, const SyntheticScene& scene) {
  std::vector<Eigen::Vector3d> src, dst;
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    if (!rec.images[i].registered) continue;
    src.push_back(rec.images[i].pose.centre());
    dst.push_back(scene.poses[i].centre());
  }
  Alignment a;
  a.s = fit_similarity(src, dst);
  double sum2 = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const double e = (a.s.apply(src[i]) - dst[i]).norm();
    a.max_centre_error = std::max(a.max_centre_error, e);
    sum2 += e * e;
  }
  a.rms_centre_error = std::sqrt(sum2 / double(src.size()));
  return a;
}

std::size_t count_registered(const Reconstruction& rec) {
  std::size_t n = 0;
  for (const auto& im : rec.images) n += im.registered ? 1 : 0;
  return n;
}

Reconstruction run(const SyntheticScene& scene, IncrementalSummary* summary,
                   IncrementalOptions options = {}) {
  return reconstruct_incremental(options, scene.groups, scene.images, scene.keypoints,
                                 scene.matches, summary);
}

// --- tracks -------------------------------------------------------------------------

TEST(Tracks, UnionFindJoinsChainsAndDropsInconsistentTracks) {
  std::vector<ImageKeypoints> kps(3);
  for (auto& k : kps) k.points.assign(4, Eigen::Vector2d::Zero());
  // 0:0 - 1:0 - 2:0 is a clean track of 3; 0:1 - 1:1 - 2:1 - 0:2 holds two keypoints
  // of image 0 and must be dropped; 0:3 - 1:3 is a clean pair.
  std::vector<PairMatches> matches(3);
  matches[0] = {0, 1, {{0, 0}, {1, 1}, {3, 3}}, TwoViewModel::essential};
  matches[1] = {1, 2, {{0, 0}, {1, 1}}, TwoViewModel::essential};
  matches[2] = {0, 2, {{2, 1}}, TwoViewModel::essential};
  TrackStatistics stats;
  const auto tracks = build_tracks(kps, matches, &stats);
  EXPECT_EQ(stats.tracks, 2u);
  EXPECT_EQ(stats.inconsistent_tracks, 1u);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0].size(), 3u);
  EXPECT_EQ(tracks[1].size(), 2u);
  EXPECT_EQ(tracks[1][0].keypoint, 3);
}

TEST(Tracks, ConflictingComponentIsSplitAtTheWrongMatch) {
  // Two true tracks over 4 images (keypoint 0 and keypoint 1 everywhere), matched in
  // every pair, glued by one wrong match 0:0 - 1:1.
  std::vector<ImageKeypoints> kps(4);
  for (auto& k : kps) k.points.assign(2, Eigen::Vector2d::Zero());
  std::vector<PairMatches> matches;
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) matches.push_back({a, b, {{0, 0}, {1, 1}}, TwoViewModel::essential});
  }
  matches[0].matches.emplace_back(0, 1);
  TrackStatistics stats;
  const auto tracks = build_tracks(kps, matches, &stats);
  EXPECT_EQ(stats.inconsistent_tracks, 1u);
  EXPECT_EQ(stats.repaired_tracks, 2u);
  ASSERT_EQ(tracks.size(), 2u);
  for (const auto& t : tracks) {
    ASSERT_EQ(t.size(), 4u);
    for (const auto& e : t) EXPECT_EQ(e.keypoint, t[0].keypoint);
  }
}

// --- triangulation ------------------------------------------------------------------

TEST(Triangulation, ExactFromThreeViewsAndRefusesNarrowRays) {
  const SyntheticScene scene = make_scene({.cameras = 6, .points = 10, .noise_px = 0});
  const Eigen::Vector3d X(0.2, -0.1, 0.05);
  std::vector<Camera> cams;
  std::vector<Eigen::Vector2d> px;
  for (int i = 0; i < 3; ++i) {
    cams.push_back({scene.truth, scene.poses[i]});
    px.push_back(*cams.back().project(X));
  }
  const auto r = triangulate_views(cams, px, {});
  ASSERT_TRUE(r.ok);
  EXPECT_LT((r.X - X).norm(), 1e-9);
  // Two cameras 1 mm apart: rays almost parallel, refused by the angle check.
  std::vector<Camera> close{cams[0], cams[0]};
  close[1].pose = Pose::from_centre(cams[0].pose.R, cams[0].pose.centre() + Eigen::Vector3d(0.001, 0, 0));
  const auto narrow = triangulate_views(close, {*close[0].project(X), *close[1].project(X)}, {});
  EXPECT_FALSE(narrow.ok);
  EXPECT_LT(narrow.max_angle_deg, 0.1);
}

// --- options ------------------------------------------------------------------------

TEST(IncrementalOptions, RefusesInvalidFieldsByName) {
  IncrementalOptions o;
  o.min_triangulation_angle_deg = -1;
  try {
    o.validate();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("min_triangulation_angle_deg"), std::string::npos);
  }
  IncrementalOptions b;
  b.bundle.loss_scale_px = 0;
  EXPECT_THROW(b.validate(), InputError);
  // The retry may only relax the resection, never ask for more than it.
  IncrementalOptions r;
  r.retry_min_inliers = r.resection_min_inliers + 1;
  try {
    r.validate();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("retry_min_inliers"), std::string::npos);
  }
}

// --- incremental reconstruction -----------------------------------------------------

TEST(Incremental, NoisySceneRegistersAllAndRecoversCamerasAndIntrinsics) {
  const SyntheticScene scene = make_scene({});
  IncrementalSummary summary;
  const Reconstruction rec = run(scene, &summary);

  EXPECT_EQ(count_registered(rec), scene.images.size());
  EXPECT_EQ(summary.registered, scene.images.size());
  EXPECT_TRUE(summary.unregistered.empty());
  EXPECT_FALSE(rec.georeferenced);

  const Alignment a = align_to_truth(rec, scene);
  const auto& k = rec.groups[0].intrinsics;
  const double focal_err = std::abs(k.fx / scene.truth.fx - 1.0);
  const double noise_rms = 0.3 * std::sqrt(2.0);
  std::printf(
      "[ figures  ] %zu/%zu registered, %zu tracks (%zu conflicting, %zu repaired), %zu points, %zu obs, rmse %.3f px, centres max %.2f mm "
      "rms %.2f mm, focal err %.3f %%, pp (%.2f, %.2f) vs (%.2f, %.2f), k1 %.4f (%.4f), "
      "k2 %.4f (%.4f), %d local / %d global BA, %.2f s\n",
      summary.registered, summary.images, summary.tracks, summary.inconsistent_tracks,
      summary.repaired_tracks, summary.points, summary.observations,
      summary.reprojection_rmse_px, a.max_centre_error * 1e3, a.rms_centre_error * 1e3,
      focal_err * 100, k.cx, k.cy, scene.truth.cx, scene.truth.cy, k.k1, scene.truth.k1, k.k2,
      scene.truth.k2, summary.local_adjustments, summary.global_adjustments, summary.seconds);

  EXPECT_LT(a.max_centre_error, kCentreTolM);
  EXPECT_LT(focal_err, kFocalRelTol);
  EXPECT_NEAR(k.fy / k.fx, 1.0, 1e-12) << "one focal: fy follows fx";
  EXPECT_NEAR(k.cx, scene.truth.cx, kPrincipalPointTolPx);
  EXPECT_NEAR(k.cy, scene.truth.cy, kPrincipalPointTolPx);
  EXPECT_LT(summary.reprojection_rmse_px, kRmseFactor * noise_rms);
  EXPECT_GT(summary.reprojection_rmse_px, 0.5 * noise_rms) << "suspiciously low: overfitting?";
  EXPECT_NEAR(summary.reprojection_rmse_px, reprojection_rmse_px(rec, scene.keypoints), 1e-12);
  // Most true points come back (some are dropped with the wrong matches' tracks).
  EXPECT_GT(summary.points, std::size_t(kPointsRecoveredFraction * scene.points.size()));
}

// Intermediate global adjustments on a subset of the points (global_ba_max_observations)
// must leave the final model as good as adjusting every point each time: a budget far
// below the scene's observations forces the subset in every one of them.
TEST(Incremental, BoundedIntermediateAdjustmentsKeepTheFinalModel) {
  const SyntheticScene scene = make_scene({});
  IncrementalOptions unbounded;
  unbounded.global_ba_max_observations = 0;
  IncrementalSummary su;
  const Reconstruction ru = run(scene, &su, unbounded);
  IncrementalOptions bounded;
  bounded.global_ba_max_observations = 400;
  IncrementalSummary sb;
  const Reconstruction rb = run(scene, &sb, bounded);
  EXPECT_EQ(su.bounded_adjustments, 0);
  EXPECT_GT(sb.bounded_adjustments, 0) << "the budget never bound: the test proves nothing";
  ASSERT_EQ(count_registered(rb), scene.images.size());
  const Alignment au = align_to_truth(ru, scene), ab = align_to_truth(rb, scene);
  std::printf("[ figures  ] bounded to 400 observations (%d of %d global BAs): centres max %.3f mm "
              "(unbounded %.3f mm), rmse %.4f px (%.4f px)\n",
              sb.bounded_adjustments, sb.global_adjustments, ab.max_centre_error * 1e3, au.max_centre_error * 1e3,
              sb.reprojection_rmse_px, su.reprojection_rmse_px);
  EXPECT_LT(ab.max_centre_error, kCentreTolM);
  // The final adjustments take every point in both runs: the same optimum within
  // the noise's own scatter.
  EXPECT_NEAR(sb.reprojection_rmse_px, su.reprojection_rmse_px, 0.02 * su.reprojection_rmse_px);
  EXPECT_NEAR(double(sb.points), double(su.points), 0.02 * double(su.points));
  IncrementalOptions negative;
  negative.global_ba_max_observations = -1;
  EXPECT_THROW(negative.validate(), InputError);
}

TEST(Incremental, NoiseFreeSceneIsRecoveredExactly) {
  const SyntheticScene scene =
      make_scene({.noise_px = 0.0, .outlier_fraction = 0.0, .marker_noise_px = 0.0, .seed = 21});
  IncrementalOptions options;
  options.bundle.function_tolerance = 1e-14;
  options.bundle.parameter_tolerance = 1e-14;
  options.bundle.gradient_tolerance = 1e-16;
  options.bundle.max_iterations = 200;
  IncrementalSummary summary;
  const Reconstruction rec = run(scene, &summary, options);
  ASSERT_EQ(count_registered(rec), scene.images.size());
  const Alignment a = align_to_truth(rec, scene);
  const double scene_size = 4.0;  // metres
  const auto& k = rec.groups[0].intrinsics;
  std::printf("[ figures  ] noise-free: centres max rel %.2e, focal rel %.2e, pp err %.2e px, rmse %.2e px\n",
              a.max_centre_error / scene_size, std::abs(k.fx / scene.truth.fx - 1),
              std::hypot(k.cx - scene.truth.cx, k.cy - scene.truth.cy), summary.reprojection_rmse_px);
  EXPECT_LT(a.max_centre_error / scene_size, kExactRelTol);
  EXPECT_LT(std::abs(k.fx / scene.truth.fx - 1), kExactRelTol);
  EXPECT_NEAR(k.cx, scene.truth.cx, kExactRelTol * scene.truth.fx);
  EXPECT_NEAR(k.cy, scene.truth.cy, kExactRelTol * scene.truth.fx);
  EXPECT_NEAR(k.k1, scene.truth.k1, kExactRelTol * 10);
  EXPECT_LT(summary.reprojection_rmse_px, kExactRelTol);
}

TEST(Incremental, CameraGroupsAreCalibratedSeparately) {
  // The same photos split into two groups (as if two identical bodies were used):
  // each group gets its own intrinsics, and both must find the truth.
  SyntheticScene scene = make_scene({.seed = 9});
  scene.groups.push_back(scene.groups[0]);
  scene.groups[1].intrinsics.fx = scene.groups[1].intrinsics.fy = 0;  // no EXIF: default prior
  for (std::size_t i = 0; i < scene.images.size(); ++i) scene.images[i].group = int(i % 2);
  IncrementalSummary summary;
  const Reconstruction rec = run(scene, &summary);
  ASSERT_EQ(count_registered(rec), scene.images.size());
  ASSERT_EQ(rec.groups.size(), 2u);
  for (const auto& g : rec.groups) {
    EXPECT_LT(std::abs(g.intrinsics.fx / scene.truth.fx - 1.0), kFocalRelTol);
    EXPECT_NEAR(g.intrinsics.cx, scene.truth.cx, kPrincipalPointTolPx);
  }
  EXPECT_NE(rec.groups[0].intrinsics.fx, rec.groups[1].intrinsics.fx) << "estimated separately";
  EXPECT_LT(align_to_truth(rec, scene).max_centre_error, kCentreTolM);
}

// --- lens models ---------------------------------------------------------------------

// The lens comes back from self-calibration within this, where the photos measure it:
// the largest difference between the recovered and the true lens over every
// observed keypoint position (the k's trade off against each other, so the pixel
// displacement they cause is compared, not the coefficients one by one; the
// fisheye's corners beyond the ground seen in this scene are not measured at all).
constexpr double kLensDisplacementTolPx = 0.5;  // pixels

// Largest difference in pixels between two calibrations at the observed keypoints.
double max_displacement_px(const Intrinsics& a, const Intrinsics& b,
                           const std::vector<ImageKeypoints>& keypoints) {
  double worst = 0;
  for (const auto& image : keypoints) {
    for (const auto& p : image.points) {
      worst = std::max(worst, (b.to_pixel(a.to_normalised(p)) - p).norm());
    }
  }
  return worst;
}

void expect_lens_recovered(CameraModel lens) {
  const SyntheticScene scene = make_scene({.seed = 13, .lens = lens});
  IncrementalSummary summary;
  const Reconstruction rec = run(scene, &summary);
  ASSERT_EQ(count_registered(rec), scene.images.size()) << to_string(lens);
  const Alignment a = align_to_truth(rec, scene);
  const auto& k = rec.groups[0].intrinsics;
  const double noise_rms = 0.3 * std::sqrt(2.0);
  const double lens_err = max_displacement_px(k, scene.truth, scene.keypoints);
  std::printf("[ figures  ] %s: rmse %.3f px, centres max %.2f mm, focal err %.3f %%, "
              "k %.4f %.4f %.4f %.5f p %.5f %.5f (truth %.4f %.4f %.4f %.5f p %.5f %.5f), "
              "lens max %.3f px\n",
              to_string(lens), summary.reprojection_rmse_px, a.max_centre_error * 1e3,
              100 * std::abs(k.fx / scene.truth.fx - 1), k.k1, k.k2, k.k3, k.k4, k.p1, k.p2,
              scene.truth.k1, scene.truth.k2, scene.truth.k3, scene.truth.k4, scene.truth.p1,
              scene.truth.p2, lens_err);
  EXPECT_EQ(k.model, lens);
  EXPECT_LT(summary.reprojection_rmse_px, kRmseFactor * noise_rms) << to_string(lens);
  EXPECT_LT(a.max_centre_error, kCentreTolM) << to_string(lens);
  EXPECT_LT(std::abs(k.fx / scene.truth.fx - 1.0), kFocalRelTol) << to_string(lens);
  EXPECT_LT(lens_err, kLensDisplacementTolPx) << to_string(lens);
}

TEST(Incremental, BrownLensIsSelfCalibrated) { expect_lens_recovered(CameraModel::brown); }

TEST(Incremental, FisheyeLensIsSelfCalibrated) { expect_lens_recovered(CameraModel::fisheye); }

// A known calibration held fixed comes out bit-identical, through the incremental
// mapper and a georeferencing adjustment with control markers.
bool same_bits(const Intrinsics& a, const Intrinsics& b) {
  return a.width == b.width && a.height == b.height && a.model == b.model && a.fx == b.fx &&
         a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.k1 == b.k1 && a.k2 == b.k2 &&
         a.k3 == b.k3 && a.k4 == b.k4 && a.p1 == b.p1 && a.p2 == b.p2;
}

TEST(Incremental, FixedCalibrationStaysExactlyFixed) {
  SyntheticScene scene = make_scene({.cameras = 12, .points = 1200, .seed = 17,
                                     .lens = CameraModel::brown});
  // The truth, slightly off (fy / fx not 1, so a read-back through the block's aspect
  // ratio would show): a fixed calibration must not move even when it is wrong.
  Intrinsics known = scene.truth;
  known.fx *= 1.003;
  known.fy = known.fx * (1.0 + 1.0 / 3.0 * 1e-3);
  scene.groups[0].intrinsics = known;
  scene.groups[0].calibration_known = true;
  scene.groups[0].calibration_fixed = true;
  scene.groups[0].calibration_source = "calibration";
  IncrementalSummary summary;
  Reconstruction rec = run(scene, &summary);
  ASSERT_EQ(count_registered(rec), scene.images.size());
  EXPECT_TRUE(same_bits(rec.groups[0].intrinsics, known));
  EXPECT_TRUE(rec.groups[0].calibration_fixed);

  // A further adjustment of the reconstruction (every pose and point free; the
  // georeference is tested in georef_test.cpp).
  BundleOptions options;
  const BundleSummary s = bundle_adjust(options, rec, scene.keypoints);
  EXPECT_GT(s.iterations, 0);
  EXPECT_TRUE(same_bits(rec.groups[0].intrinsics, known));

  // The same without the flag: self-calibration moves the focal back towards the truth.
  Reconstruction free = rec;
  free.groups[0].calibration_fixed = false;
  bundle_adjust(options, free, scene.keypoints);
  EXPECT_NE(free.groups[0].intrinsics.fx, known.fx);
  EXPECT_LT(std::abs(free.groups[0].intrinsics.fx / scene.truth.fx - 1),
            std::abs(known.fx / scene.truth.fx - 1));
}

TEST(Incremental, RefusesWhenNoPairOverlaps) {
  SyntheticScene scene = make_scene({.cameras = 4, .points = 300});
  scene.matches.clear();
  EXPECT_THROW(run(scene, nullptr), ProcessingError);
}

// A photo that overlaps mostly two registered photos (site-small L2_0017: a nadir
// photo at a trench corner whose other neighbours are 45-60 degree obliques): its
// verified matches are two-view tracks without a 3D point, and only a few of its
// matches join multi-view tracks. The last photo of the scene is rewired that way:
// `shared` of its matches with its best neighbour keep their (multi-view) tracks,
// every other match of it is replaced by `private_r1` / `private_r2` matches of new
// ground points seen only by it and one of its two best neighbours. The shared points
// are matched to both neighbours, so their matches close triangles and survive the
// repair of tracks glued by the scene's wrong matches.
struct LoneView {
  SyntheticScene scene;
  int image = -1;
};

LoneView make_lone_view(std::size_t shared, int private_r1, int private_r2, unsigned seed) {
  LoneView lv{make_scene({.seed = seed}), -1};
  SyntheticScene& s = lv.scene;
  const int u = int(s.images.size()) - 1;
  lv.image = u;
  // The two neighbours with the most matches.
  std::vector<std::pair<std::size_t, int>> by_matches;
  for (const auto& m : s.matches) {
    if (m.image_a == u || m.image_b == u) {
      by_matches.emplace_back(m.matches.size(), m.image_a == u ? m.image_b : m.image_a);
    }
  }
  std::sort(by_matches.rbegin(), by_matches.rend());
  const int r1 = by_matches.at(0).second, r2 = by_matches.at(1).second;

  // `shared` true points seen by u, r1 and r2, spread over u's keypoint list.
  auto keypoint_of = [&](int image) {
    std::map<int, int> k;
    for (std::size_t i = 0; i < s.point_of_keypoint[image].size(); ++i) {
      k[s.point_of_keypoint[image][i]] = int(i);
    }
    return k;
  };
  const auto in_r1 = keypoint_of(r1), in_r2 = keypoint_of(r2);
  std::vector<std::array<int, 3>> common;  // keypoints in u, r1, r2
  for (std::size_t ku = 0; ku < s.point_of_keypoint[u].size(); ++ku) {
    const int p = s.point_of_keypoint[u][ku];
    if (in_r1.count(p) && in_r2.count(p)) common.push_back({int(ku), in_r1.at(p), in_r2.at(p)});
  }
  std::vector<std::pair<int, int>> shared_r1, shared_r2;  // (keypoint in r, keypoint in u)
  for (std::size_t i = 0; i < shared; ++i) {
    const auto& c = common.at(i * common.size() / shared);
    shared_r1.emplace_back(c[1], c[0]);
    shared_r2.emplace_back(c[2], c[0]);
  }
  std::erase_if(s.matches, [&](const PairMatches& m) { return m.image_a == u || m.image_b == u; });

  std::mt19937 rng(seed + 1);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.3);  // pixels, as the scene's keypoints
  auto add_private = [&](int r, int count, std::vector<std::pair<int, int>> matches) {
    const Camera cu{s.truth, s.poses[u]}, cr{s.truth, s.poses[r]};
    auto inside = [&](const std::optional<Eigen::Vector2d>& p) {
      return p && p->x() >= 0 && p->y() >= 0 && p->x() <= s.truth.width - 1 &&
             p->y() <= s.truth.height - 1;
    };
    const std::size_t target = matches.size() + std::size_t(count);
    for (int tries = 0; matches.size() < target && tries < 200000; ++tries) {
      const double e = -2.0 + 4.0 * uni(rng), n = -1.5 + 3.0 * uni(rng);
      const Eigen::Vector3d X(e, n, test::ground_height(e, n));
      const auto pu = cu.project(X), pr = cr.project(X);
      if (!inside(pu) || !inside(pr)) continue;
      const int pid = int(s.points.size());
      s.points.push_back(X);
      s.keypoints[u].points.push_back(*pu + Eigen::Vector2d(noise(rng), noise(rng)));
      s.point_of_keypoint[u].push_back(pid);
      s.keypoints[r].points.push_back(*pr + Eigen::Vector2d(noise(rng), noise(rng)));
      s.point_of_keypoint[r].push_back(pid);
      matches.emplace_back(int(s.keypoints[r].points.size()) - 1,
                           int(s.keypoints[u].points.size()) - 1);
    }
    PairMatches pm;
    pm.image_a = std::min(u, r);
    pm.image_b = std::max(u, r);
    pm.model = TwoViewModel::essential;
    for (const auto& [kr, ku] : matches) pm.matches.emplace_back(r < u ? kr : ku, r < u ? ku : kr);
    s.matches.push_back(std::move(pm));
  };
  add_private(r1, private_r1, shared_r1);
  add_private(r2, private_r2, shared_r2);
  return lv;
}

// The normal resection needs resection_min_inliers (15) triangulated points; the
// lone view sees 10. Matches with its two neighbours: 160 and 90.
constexpr std::size_t kLoneShared = 10;
constexpr int kLonePrivateR1 = 150, kLonePrivateR2 = 80;

TEST(Incremental, RetryRegistersAPhotoSeenMostlyInTwoViewTracks) {
  const LoneView lv = make_lone_view(kLoneShared, kLonePrivateR1, kLonePrivateR2, 7);
  const std::size_t n = lv.scene.images.size();

  IncrementalOptions without;
  without.retry_unregistered = false;
  IncrementalSummary s0;
  const Reconstruction rec0 = run(lv.scene, &s0, without);
  EXPECT_EQ(count_registered(rec0), n - 1) << "the scene must reproduce the failure";
  EXPECT_FALSE(rec0.images[lv.image].registered);

  IncrementalSummary s1;
  const Reconstruction rec1 = run(lv.scene, &s1);
  ASSERT_EQ(count_registered(rec1), n);
  EXPECT_EQ(s1.registered_on_retry, 1u);
  EXPECT_LT(s1.reprojection_rmse_px, kRmseFactor * 0.3 * std::sqrt(2.0));
  // The retried photo is as accurate as the others: its two-view points pin it.
  const Alignment a = align_to_truth(rec1, lv.scene);
  const Eigen::Vector3d c = a.s.apply(rec1.images[lv.image].pose.centre());
  const double err = (c - lv.scene.poses[lv.image].centre()).norm();
  std::printf("[ figures  ] lone view: %zu/%zu without retry, %zu/%zu with; its centre %.2f mm, "
              "all max %.2f mm\n", s0.registered, n, s1.registered, n, err * 1e3,
              a.max_centre_error * 1e3);
  EXPECT_LT(err, kCentreTolM);
  EXPECT_LT(a.max_centre_error, kCentreTolM);
}

TEST(Incremental, RetryRefusesAPoseItsPairMatchesContradict) {
  // The same photo, but its matches with the two neighbours are scrambled (each
  // private keypoint of the photo moved to another one's place): the 10 points
  // still give a pose, the verified matches do not confirm it, so the photo stays out.
  LoneView lv = make_lone_view(kLoneShared, kLonePrivateR1, kLonePrivateR2, 7);
  auto& kp = lv.scene.keypoints[lv.image].points;
  const std::size_t first_private = kp.size() - std::size_t(kLonePrivateR1 + kLonePrivateR2);
  std::mt19937 rng(3);
  std::shuffle(kp.begin() + std::ptrdiff_t(first_private), kp.end(), rng);
  IncrementalSummary s;
  const Reconstruction rec = run(lv.scene, &s);
  EXPECT_EQ(s.registered_on_retry, 0u);
  EXPECT_FALSE(rec.images[lv.image].registered);
  EXPECT_EQ(count_registered(rec), lv.scene.images.size() - 1);
  // The pair check is what refuses it: with (almost) no agreement required, the
  // 10 points alone place it.
  IncrementalOptions lax;
  lax.retry_min_pair_agreement = 0.01;
  IncrementalSummary s_lax;
  run(lv.scene, &s_lax, lax);
  EXPECT_EQ(s_lax.registered_on_retry, 1u);
}

// --- bundle adjustment on a Reconstruction ------------------------------------------

TEST(BundleAdjust, RefinesPerturbedTruthAndKeepsTheGauge) {
  const SyntheticScene scene = make_scene({.cameras = 12, .points = 1200, .outlier_fraction = 0});
  Reconstruction rec = scene.truth_reconstruction();
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  for (std::size_t i = 2; i < rec.images.size(); ++i) {  // the gauge images stay true
    auto& pose = rec.images[i].pose;
    pose = Pose::from_centre(pose.R, pose.centre() + 0.01 * Eigen::Vector3d(n(rng), n(rng), n(rng)));
  }
  for (auto& p : rec.points) p.X += 0.005 * Eigen::Vector3d(n(rng), n(rng), n(rng));
  rec.groups[0].intrinsics.fx *= 1.01;
  rec.groups[0].intrinsics.fy *= 1.01;
  const Pose first = rec.images[0].pose;

  BundleOptions options;
  const BundleSummary s = bundle_adjust(options, rec, scene.keypoints);
  EXPECT_TRUE(s.gauge_fixed);
  EXPECT_EQ(s.control_markers, 0u);
  EXPECT_LT(s.rmse_px, kRmseFactor * 0.3 * std::sqrt(2.0));
  EXPECT_LT((rec.images[0].pose.t - first.t).norm(), 1e-15);
  EXPECT_LT(std::abs(rec.groups[0].intrinsics.fx / scene.truth.fx - 1), kFocalRelTol);
  const Alignment a = align_to_truth(rec, scene);
  EXPECT_LT(a.max_centre_error, kCentreTolM);
}

TEST(BundleAdjust, FixedIntrinsicsStayFixed) {
  const SyntheticScene scene = make_scene({.cameras = 8, .points = 600, .outlier_fraction = 0});
  Reconstruction rec = scene.truth_reconstruction();
  rec.groups[0].intrinsics.fx *= 1.02;
  rec.groups[0].intrinsics.fy *= 1.02;
  const Intrinsics before = rec.groups[0].intrinsics;
  BundleOptions options;
  options.refine = {false, false, false, false, false};
  bundle_adjust(options, rec, scene.keypoints);
  EXPECT_EQ(rec.groups[0].intrinsics.fx, before.fx);
  EXPECT_EQ(rec.groups[0].intrinsics.cx, before.cx);
  EXPECT_EQ(rec.groups[0].intrinsics.k1, before.k1);
}

// --- quality ------------------------------------------------------------------------

TEST(Quality, FiguresOfTheTruth) {
  const SyntheticScene scene = make_scene({.cameras = 8, .points = 600, .noise_px = 0});
  const Reconstruction rec = scene.truth_reconstruction();
  const auto q = measure_quality(rec, scene.keypoints);
  EXPECT_EQ(q.registered_images, 8u);
  EXPECT_EQ(q.total_images, 8u);
  EXPECT_LT(q.reprojection_rmse_px, 1e-9);
  // Depth about 1.6-2.6 m over f = 1380 px: 1.2-1.9 mm per pixel.
  EXPECT_GT(q.gsd_m, 0.0011);
  EXPECT_LT(q.gsd_m, 0.0020);
  EXPECT_GT(q.mean_track_length, 2.0);
}

}  // namespace
}  // namespace strata
