// The robust similarity: exact pairs give the transform back, blunders (two targets
// with their names swapped, one far off) are named as outliers and do not move the
// fit, and too few or collinear pairs are refused.
#include "core/error.hpp"
#include "geometry/similarity.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

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

}  // namespace
}  // namespace strata
