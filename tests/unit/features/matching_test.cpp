#include "core/error.hpp"
#include "core/resources.hpp"
#include "features/extraction.hpp"
#include "features/matching.hpp"
#include "support/test_support.hpp"
#include "unit/features/synthetic_images.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <opencv2/core.hpp>

#include <algorithm>
#include <filesystem>
#include <utility>
#include <iostream>

namespace strata {
namespace {

// SIFT keypoints on a texture warped by cubic interpolation repeat to about
// 0.3 px; 1 px bounds almost every verified match, and the few beyond stay
// under the RANSAC threshold used here.
constexpr double kHomographyTolerancePx = 1.0;
constexpr double kWithinToleranceFraction = 0.97;  // verified matches within 1 px
constexpr double kVerifyThresholdPx = 1.5;         // RANSAC threshold in these tests
// The texture is unambiguous: nearly every ratio-tested mutual match is right.
constexpr double kMinInlierRatio = 0.85;
constexpr std::size_t kMinInliers = 300;

constexpr int kWidth = 1200, kHeight = 900;

Eigen::Matrix3d calibration() {
  Eigen::Matrix3d K;
  K << 1000, 0, (kWidth - 1) / 2.0, 0, 1000, (kHeight - 1) / 2.0, 0, 0, 1;
  return K;
}

// A perspective homography from a real two-camera geometry (a plane 5 m ahead,
// the second camera moved sideways and turned), so the essential path applies.
Eigen::Matrix3d scene_homography() {
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(0.08, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(-0.04, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  return test::plane_homography(calibration(), R, Eigen::Vector3d(-0.9, 0.2, 0.3),
                                Eigen::Vector3d(0.1, -0.05, 1).normalized(), 5.0);
}

struct WarpedPair {
  test::ScratchDir dir{"pair"};
  Eigen::Matrix3d H;
  std::vector<FeatureImage> images;
};

void make_pair(WarpedPair& p) {
  p.H = scene_homography();
  const cv::Mat a = test::noise_texture(kWidth, kHeight, 11);
  test::write_png(p.dir / "a.png", a);
  test::write_png(p.dir / "b.png", test::warp(a, p.H, kWidth, kHeight));
  p.images = {{"a", p.dir / "a.png", ""}, {"b", p.dir / "b.png", ""}};
}

// epipolar_only: an essential-matrix inlier only has to lie near its epipolar
// line, so a wrong match along that line may stay (up to the threshold).
void expect_obeys_homography(const PairMatches& m, const std::vector<ImageKeypoints>& kp,
                             const Eigen::Matrix3d& H, bool epipolar_only = false) {
  std::size_t within = 0;
  double worst = 0;
  for (const auto& [i, j] : m.matches) {
    const double e = (test::apply(H, kp[0].points[i]) - kp[1].points[j]).norm();
    within += e < kHomographyTolerancePx ? 1 : 0;
    worst = std::max(worst, e);
  }
  EXPECT_GE(within, kWithinToleranceFraction * m.matches.size())
      << within << " of " << m.matches.size() << " within " << kHomographyTolerancePx
      << " px, worst " << worst;
  if (!epipolar_only) {
    EXPECT_LT(worst, 2 * kVerifyThresholdPx);  // no gross outlier slipped through
  }
}

TEST(Matching, WarpedPairObeysTheHomography) {
  WarpedPair p;
  make_pair(p);
  FeatureExtractionOptions fo;
  fo.max_image_size = 1000;  // smaller than the image: exercises the downscale path
  const auto kp = extract_features(fo, p.images, p.dir / "cache");

  PairSelectionSummary ps;
  const auto pairs = select_pairs({}, kp, p.dir / "cache", {}, &ps);
  ASSERT_EQ(pairs, (std::vector<ImagePair>{{0, 1}}));
  EXPECT_TRUE(ps.exhaustive);

  MatchingOptions mo;
  mo.verification.max_error_px = kVerifyThresholdPx;
  MatchingSummary s;
  const auto matches = match_pairs(mo, kp, pairs, {}, p.dir / "cache", &s);
  ASSERT_EQ(matches.size(), 1u);
  const PairMatches& m = matches[0];
  // Without a focal prior, a planar scene is recognised as such.
  EXPECT_EQ(m.model, TwoViewModel::homography);
  EXPECT_GE(m.matches.size(), kMinInliers);
  EXPECT_GE(static_cast<double>(m.matches.size()), kMinInlierRatio * s.putative_matches)
      << m.matches.size() << " inliers of " << s.putative_matches;
  expect_obeys_homography(m, kp, p.H);

  // A rerun reads the pair from the cache.
  MatchingSummary again;
  const auto cached = match_pairs(mo, kp, pairs, {}, p.dir / "cache", &again);
  EXPECT_EQ(again.from_cache, 1u);
  ASSERT_EQ(cached.size(), 1u);
  EXPECT_EQ(cached[0].matches, m.matches);
  EXPECT_EQ(cached[0].model, m.model);

  // A changed option does not reuse it.
  mo.ratio = 0.7;
  MatchingSummary changed;
  match_pairs(mo, kp, pairs, {}, p.dir / "cache", &changed);
  EXPECT_EQ(changed.from_cache, 0u);
}

TEST(Matching, EssentialMatrixWithFocalPrior) {
  WarpedPair p;
  make_pair(p);
  FeatureExtractionOptions fo;
  fo.max_features = 2500;  // brute force below is quadratic in it
  const auto kp = extract_features(fo, p.images, p.dir / "cache");
  Intrinsics k;
  k.width = kWidth;
  k.height = kHeight;
  k.fx = k.fy = calibration()(0, 0);
  k.cx = calibration()(0, 2);
  k.cy = calibration()(1, 2);
  MatchingOptions mo;
  mo.verification.max_error_px = kVerifyThresholdPx;
  for (const auto matcher : {MatchingOptions::Matcher::flann, MatchingOptions::Matcher::brute_force}) {
    mo.matcher = matcher;
    MatchingSummary s;
    const auto matches = match_pairs(mo, kp, {{0, 1}}, {k, k}, p.dir / "cache", &s);
    ASSERT_EQ(matches.size(), 1u);
    EXPECT_EQ(matches[0].model, TwoViewModel::essential);
    EXPECT_GE(matches[0].matches.size(), kMinInliers);
    // Planar scene: the homography explains (almost) all of them.
    EXPECT_GE(matches[0].homography_inliers, 0.9 * matches[0].matches.size());
    expect_obeys_homography(matches[0], kp, p.H, /*epipolar_only=*/true);
  }
}

// FLANN's randomised kd-trees draw from OpenCV's per-thread generator. What that
// generator drew before (on whichever worker builds which image's index) must not
// change the matches: a run-to-run difference once moved a photo of a CI machine's
// reconstruction 2.7 m. Few checks make the search approximate enough that
// different trees give different neighbours.
TEST(Matching, MatchesDoNotDependOnTheRandomGeneratorsPastOrTheThreads) {
  WarpedPair p;
  make_pair(p);
  FeatureExtractionOptions fo;
  fo.max_features = 3000;
  const auto kp = extract_features(fo, p.images, p.dir / "cache");
  MatchingOptions mo;
  mo.flann_checks = 4;
  mo.verification.max_error_px = kVerifyThresholdPx;
  auto run = [&](int threads, int draws) {
    std::filesystem::remove_all(p.dir / "cache" / "matches");  // computed, not read back
    mo.num_threads = threads;
    cv::RNG& rng = cv::theRNG();  // this thread's: a one-thread run builds here
    for (int i = 0; i < draws; ++i) rng.next();
    MatchingSummary s;
    const auto m = match_pairs(mo, kp, {{0, 1}}, {}, p.dir / "cache", &s);
    EXPECT_EQ(s.from_cache, 0u);
    return m;
  };
  const auto first = run(1, 0);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_GE(first[0].matches.size(), kMinInliers);
  for (const auto& [threads, draws] : {std::pair{1, 1}, std::pair{1, 977}, std::pair{2, 5}}) {
    const auto again = run(threads, draws);
    ASSERT_EQ(again.size(), 1u);
    EXPECT_EQ(again[0].matches, first[0].matches) << threads << " threads, " << draws << " draws before";
  }
}

TEST(Matching, UnrelatedImagesYieldNoVerifiedPair) {
  test::ScratchDir dir("unrelated");
  test::write_png(dir / "a.png", test::noise_texture(kWidth, kHeight, 21));
  test::write_png(dir / "b.png", test::noise_texture(kWidth, kHeight, 22));
  const auto kp =
      extract_features({}, {{"a", dir / "a.png", ""}, {"b", dir / "b.png", ""}}, dir / "cache");
  MatchingSummary s;
  const auto matches = match_pairs({}, kp, {{0, 1}}, {}, dir / "cache", &s);
  EXPECT_TRUE(matches.empty()) << matches[0].matches.size() << " inliers of "
                               << s.putative_matches;
}

TEST(PairSelection, LargeLayersUseSequenceAndRetrievalWithLinearPairCount) {
  // 12 photos of two unrelated "layers" interleaved in capture order: retrieval
  // must pair photos of the same texture even when they are far apart in time.
  test::ScratchDir dir("retrieval");
  const cv::Mat texture_a = test::noise_texture(900, 600, 31);
  const cv::Mat texture_b = test::noise_texture(900, 600, 32);
  std::vector<FeatureImage> images;
  for (int i = 0; i < 12; ++i) {
    const cv::Mat& t = i % 2 == 0 ? texture_a : texture_b;
    const int x = 40 * (i / 2);  // a sweep: each photo shifted 40 px
    const std::string name = "p" + std::to_string(i);
    test::write_png(dir / (name + ".png"), t(cv::Rect(x, 50, 600, 450)).clone());
    images.push_back({name, dir / (name + ".png"), ""});
  }
  FeatureExtractionOptions fo;
  fo.max_features = 1000;
  const auto kp = extract_features(fo, images, dir / "cache");

  PairSelectionOptions po;
  po.exhaustive_limit = 5;
  po.sequence_neighbours = 1;
  po.retrieval_neighbours = 3;
  PairSelectionSummary s;
  const auto pairs = select_pairs(po, kp, dir / "cache", {}, &s);
  EXPECT_FALSE(s.exhaustive);
  EXPECT_EQ(s.sequence_pairs, 11u);
  EXPECT_LE(pairs.size(), 11u + 12u * 3u);  // linear, not 66
  // Every photo's retrieval neighbours share its texture (same parity).
  std::size_t same = 0, retrieval = 0;
  for (const auto& [a, b] : pairs) {
    if (b == a + 1) continue;  // sequence pair
    ++retrieval;
    same += (a % 2 == b % 2) ? 1 : 0;
  }
  EXPECT_GE(retrieval, 12u);
  EXPECT_EQ(same, retrieval);

  // Capture times reorder the sequence.
  std::vector<double> times(12);
  for (int i = 0; i < 12; ++i) times[i] = (i % 2) * 100 + i;  // evens first, then odds
  po.retrieval_neighbours = 0;
  const auto by_time = select_pairs(po, kp, dir / "cache", times);
  ASSERT_EQ(by_time.size(), 11u);
  std::size_t across = 0;  // only where the evens end and the odds begin: (1, 10)
  for (const auto& [a, b] : by_time) across += (a % 2 != b % 2) ? 1 : 0;
  EXPECT_EQ(across, 1u);
  EXPECT_TRUE(std::find(by_time.begin(), by_time.end(), ImagePair{1, 10}) != by_time.end());
}

TEST(PairSelection, PreviewKeepsOverlappingPairsAndDropsUnrelatedOnes) {
  // 12 crops of two unrelated textures: every same-texture pair overlaps (shifts of
  // at most 200 px on 600 px crops), no cross-texture pair shares anything.
  test::ScratchDir dir("preview");
  const cv::Mat texture_a = test::noise_texture(900, 600, 41);
  const cv::Mat texture_b = test::noise_texture(900, 600, 42);
  std::vector<FeatureImage> images;
  for (int i = 0; i < 12; ++i) {
    const cv::Mat& t = i % 2 == 0 ? texture_a : texture_b;
    const int x = 40 * (i / 2);
    const std::string name = "q" + std::to_string(i);
    test::write_png(dir / (name + ".png"), t(cv::Rect(x, 50, 600, 450)).clone());
    images.push_back({name, dir / (name + ".png"), ""});
  }
  FeatureExtractionOptions fo;
  fo.max_features = 1000;
  const auto kp = extract_features(fo, images, dir / "cache");

  PairSelectionOptions po;  // exhaustive: 66 candidates
  po.preview_min_images = 2;
  PairSelectionSummary s;
  const auto pairs = select_pairs(po, kp, dir / "cache", {}, &s);
  EXPECT_TRUE(s.previewed);
  EXPECT_EQ(s.candidate_pairs, 66u);
  constexpr std::size_t kSameTexturePairs = 2 * 15;  // 2 x C(6, 2)
  EXPECT_EQ(pairs.size(), kSameTexturePairs);
  for (const auto& [a, b] : pairs) EXPECT_EQ(a % 2, b % 2) << a << "-" << b;
  EXPECT_EQ(s.preview_passed, kSameTexturePairs);

  // Each photo's 2 best pairs: the sweep's neighbours (40 px apart, the most overlap)
  // are kept, the pairs chosen by neither photo are not, and every photo keeps 2.
  po.preview_best_per_photo = 2;
  const auto best = select_pairs(po, kp, dir / "cache", {}, &s);
  EXPECT_EQ(s.preview_passed, kSameTexturePairs);
  EXPECT_LE(best.size(), 12u * 2u);
  EXPECT_LT(best.size(), pairs.size());
  std::vector<int> per_photo(12, 0);
  for (const auto& pr : best) {
    EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), pr) != pairs.end()) << pr.first << "-" << pr.second;
    ++per_photo[pr.first];
    ++per_photo[pr.second];
  }
  for (int i = 0; i < 12; ++i) EXPECT_GE(per_photo[i], 2) << "photo " << i;
  for (int a = 0; a + 2 < 12; ++a)
    EXPECT_TRUE(std::find(best.begin(), best.end(), ImagePair{a, a + 2}) != best.end()) << a << "-" << a + 2;
  EXPECT_TRUE(std::find(best.begin(), best.end(), ImagePair{0, 10}) == best.end());  // 200 px apart
  po.preview_best_per_photo = 0;

  // Below preview_min_images every candidate is kept.
  po.preview_min_images = 13;
  EXPECT_EQ(select_pairs(po, kp, dir / "cache", {}, &s).size(), 66u);
  EXPECT_FALSE(s.previewed);
}

TEST(Matching, RejectsBadPairsAndOptions) {
  std::vector<ImageKeypoints> kp(2);
  EXPECT_THROW(match_pairs({}, kp, {{0, 2}}, {}, "/tmp/none"), InputError);
  MatchingOptions mo;
  mo.verification.min_inliers = 3;
  try {
    mo.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("verification.min_inliers"), std::string::npos);
  }
  PairSelectionOptions po;
  po.exhaustive_limit = 1;
  EXPECT_THROW(po.validate(), InputError);
  po = {};
  po.preview_best_per_photo = -1;
  try {
    po.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("preview_best_per_photo"), std::string::npos);
  }
}

// Real photos, when the shared example data is present: three consecutive
// photos of the copr layer. Prints the timings quoted in docs/features.md.
TEST(Matching, RealPhotosWhenAvailable) {
  const auto photos = test::shared_data_dir() / "copr" / "images";
  if (!std::filesystem::exists(photos / "IMG_0022.jpg")) GTEST_SKIP() << "no " << photos;
  test::ScratchDir dir("copr");
  std::vector<FeatureImage> images;
  for (const char* name : {"IMG_0022.jpg", "IMG_0025.jpg"})
    images.push_back({name, photos / name, ""});
  FeatureExtractionSummary fs;
  const auto kp = extract_features({}, images, dir / "cache", &fs);
  MatchingSummary ms;
  const auto pairs = select_pairs({}, kp, dir / "cache");
  const auto matches = match_pairs({}, kp, pairs, {}, dir / "cache", &ms);
  std::cout << "copr: " << fs.images << " photos, " << fs.keypoints << " keypoints, "
            << fs.seconds << " s extraction (" << fs.cpu_seconds << " s CPU); " << ms.pairs << " pairs, " << ms.verified
            << " verified, " << ms.inlier_matches << " inliers, " << ms.seconds
            << " s matching (" << ms.cpu_seconds << " s CPU; " << ms.matching_seconds << " s kNN, " << ms.verification_seconds
            << " s RANSAC, summed over pairs)\n";
  EXPECT_EQ(ms.verified, 1u);
  for (const auto& m : matches) EXPECT_GE(m.matches.size(), 100u);
}

}  // namespace
}  // namespace strata
