// The robust similarity: exact pairs give the transform back, blunders (two targets
// with their names swapped, one far off) are named as outliers and do not move the
// fit, and too few or collinear pairs are refused. The rigid RANSAC of RGB-D feature
// matches finds a known motion among 60 % wrong matches, with a gate per pair.
#include "core/error.hpp"
#include "geometry/similarity.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <optional>
#include <random>

namespace strata {
namespace {

Similarity3 known_transform() {
  Similarity3 s;
  s.scale = 1.0004;
  s.R = (Eigen::AngleAxisd(2.1, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
  s.t = {12.5, -3.2, 1.45};
  return s;
}

// Targets around a 4 x 3 m trench, 0.2 m of relief, in the scanner's frame.
std::vector<Eigen::Vector3d> targets() {
  return {{-2.0, -1.5, -1.4}, {2.1, -1.6, -1.3}, {2.0, 1.5, -1.5}, {-2.1, 1.4, -1.35},
          {0.0, -1.7, -1.25}, {0.1, 1.6, -1.45}, {-2.2, 0.0, -1.3}};
}

TEST(RobustSimilarity, NoisyPairsGiveTheTransformBack) {
  const Similarity3 truth = known_transform();
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.002);
  std::vector<Eigen::Vector3d> src = targets(), dst;
  for (const auto& p : src) dst.push_back(truth.apply(p) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  const RobustSimilarity r = fit_similarity_robust(src, dst, 0.01);
  EXPECT_EQ(r.inliers, src.size());
  EXPECT_LT(r.rms_m, 0.004);
  EXPECT_NEAR(r.fit.scale, truth.scale, 1e-3);
  EXPECT_LT(Eigen::AngleAxisd(truth.R.transpose() * r.fit.R).angle(), 2e-3);
  // At the targets' centroid the fit is as good as the targets (a few mm).
  EXPECT_LT((r.fit.apply(Eigen::Vector3d(0, 0, -1.4)) - truth.apply(Eigen::Vector3d(0, 0, -1.4))).norm(), 0.003);
}

TEST(RobustSimilarity, SwappedNamesAndAFarBlunderAreOutliers) {
  const Similarity3 truth = known_transform();
  std::vector<Eigen::Vector3d> src = targets(), dst;
  for (const auto& p : src) dst.push_back(truth.apply(p));
  std::swap(dst[1], dst[4]);           // two targets with each other's names
  dst[6] += Eigen::Vector3d(0.5, 0, 0);  // a disturbed marker
  const RobustSimilarity r = fit_similarity_robust(src, dst, 0.01);
  EXPECT_EQ(r.inliers, 4u);
  for (std::size_t i : {1u, 4u, 6u}) {
    EXPECT_FALSE(r.inlier[i]) << i;
    EXPECT_GT(r.residual_m[i], 0.1) << i;
  }
  EXPECT_LT(r.rms_m, 1e-9);
  EXPECT_NEAR(r.fit.scale, truth.scale, 1e-9);
  EXPECT_LT((r.fit.t - truth.t).norm(), 1e-8);
}

TEST(RobustSimilarity, TooFewOrCollinearPairsAreRefused) {
  const Similarity3 truth = known_transform();
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(fit_similarity_robust(two, {truth.apply(two[0]), truth.apply(two[1])}, 0.01), InputError);
  std::vector<Eigen::Vector3d> line, image;
  for (int i = 0; i < 5; ++i) {
    line.emplace_back(0.5 * i, 0.25 * i, 0);
    image.push_back(truth.apply(line.back()));
  }
  try {
    fit_similarity_robust(line, image, 0.01);
    ADD_FAILURE() << "collinear pairs accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("on a line"), std::string::npos) << e.what();
  }
}

// Feature points of a depth frame, 1-3 m in front of the camera, depth noise k z^2.
constexpr double kNoiseK = 0.0015;          // 1/m, the default depth camera
constexpr double kRansacGateSigmas = 3.0;   // a pair's gate: 3 sigmas of both depths' noise
// With 80 good pairs of about 5 mm noise the least-squares motion is good to about
// 1 mm and 1 mrad at the points; well above it lies a fit pulled by a wrong match.
constexpr double kRansacTranslationM = 0.003;
constexpr double kRansacRotationRad = 0.003;

TEST(RigidRansac, KnownMotionAmongWrongMatches) {
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();  // frame b's camera -> frame a's
  truth.linear() = (Eigen::AngleAxisd(0.08, Eigen::Vector3d(0.2, 1, 0.1).normalized())).toRotationMatrix();
  truth.translation() = Eigen::Vector3d(0.12, -0.03, 0.02);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> across(-1.0, 1.0), range(1.0, 3.0);
  std::normal_distribution<double> normal;
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<double> gate;
  std::vector<bool> wrong;
  for (int i = 0; i < 200; ++i) {
    const double z = range(rng);
    const Eigen::Vector3d b(0.6 * z * across(rng), 0.45 * z * across(rng), z);
    const double sigma = kNoiseK * z * z;
    Eigen::Vector3d a = truth * b + Eigen::Vector3d(0, 0, sigma * normal(rng));
    const bool bad = i % 5 != 0 && i % 5 != 1;  // 60 % wrong matches: another point of the view
    if (bad) a = Eigen::Vector3d(0.6 * z * across(rng), 0.45 * z * across(rng), range(rng));
    src.push_back(b + Eigen::Vector3d(0, 0, sigma * normal(rng)));
    dst.push_back(a);
    gate.push_back(kRansacGateSigmas * std::sqrt(2.0) * sigma);
    wrong.push_back(bad);
  }
  const std::optional<RobustSimilarity> r = fit_rigid_ransac(src, dst, gate);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->fit.scale, 1.0);
  EXPECT_LT((r->fit.t - truth.translation()).norm(), kRansacTranslationM);
  EXPECT_LT(Eigen::AngleAxisd(truth.linear().transpose() * r->fit.R).angle(), kRansacRotationRad);
  std::size_t good_kept = 0, wrong_kept = 0;
  for (std::size_t i = 0; i < src.size(); ++i) (wrong[i] ? wrong_kept : good_kept) += r->inlier[i] ? 1 : 0;
  EXPECT_GE(good_kept, 75u);  // of 80: a 3-sigma gate keeps about 99 %
  EXPECT_LE(wrong_kept, 3u);  // a random point seldom falls within a few millimetres
  // Without a clean triple nothing is returned: every pair wrong.
  std::vector<Eigen::Vector3d> scrambled = dst;
  std::shuffle(scrambled.begin(), scrambled.end(), rng);
  const auto none = fit_rigid_ransac(std::vector<Eigen::Vector3d>(src.begin(), src.begin() + 5),
                                     std::vector<Eigen::Vector3d>(scrambled.begin(), scrambled.begin() + 5),
                                     std::vector<double>(gate.begin(), gate.begin() + 5));
  EXPECT_FALSE(none.has_value());
  EXPECT_FALSE(fit_rigid_ransac({src[0], src[1]}, {dst[0], dst[1]}, {gate[0], gate[1]}).has_value());
}

}  // namespace
}  // namespace strata
