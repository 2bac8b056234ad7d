// Finite-difference checks of every hand-written cost function of the bundle
// adjustment (PoseLib's verify_jacobian / ceres::GradientChecker): the automatic
// derivatives must match central differences, including at a zero rotation where the
// angle-axis formula switches to its first-order form.
#include "sfm/cost_functions.hpp"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <random>

namespace strata {
namespace {

using namespace sfm_detail;

// Central differences (relative step 1e-6) reach about 1e-9 relative on these smooth
// functions; 1e-6 leaves room for the conditioning of the projection.
constexpr double kJacobianRelTol = 1e-6;
// Angle-axis rotation vs Eigen's: both exact formulas, rounding only.
constexpr double kRotationTol = 1e-14;

ceres::NumericDiffOptions central() { return ceres::NumericDiffOptions{}; }

const std::vector<const ceres::Manifold*>* no_manifolds() { return nullptr; }

TEST(CostFunctions, AngleAxisRotateMatchesEigen) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d w(n(rng), n(rng), n(rng));
    const Eigen::Vector3d p(n(rng), n(rng), n(rng));
    Eigen::Vector3d out;
    angle_axis_rotate(w.data(), p.data(), out.data());
    const Eigen::Vector3d expected = Eigen::AngleAxisd(w.norm(), w.normalized()) * p;
    EXPECT_LT((out - expected).norm(), kRotationTol * 10);
  }
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero(), p(1, 2, 3);
  Eigen::Vector3d out;
  angle_axis_rotate(zero.data(), p.data(), out.data());
  EXPECT_LT((out - p).norm(), kRotationTol);
}

void check_reprojection(const double* rotation, const double* translation,
                        const double* intrinsics, const double* point) {
  const ReprojectionCost functor(Eigen::Vector2d(700.3, 455.9), 0.7);
  ceres::AutoDiffCostFunction<ReprojectionCost, 2, kPoseSize, kIntrinsicsSize, 3> cost(
      new ReprojectionCost(functor));
  ceres::GradientChecker checker(&cost, no_manifolds(), central());
  const double pose[kPoseSize] = {rotation[0],    rotation[1],    rotation[2],
                                  translation[0], translation[1], translation[2]};
  std::vector<const double*> params{pose, intrinsics, point};
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params.data(), kJacobianRelTol, &results)) << results.error_log;
  EXPECT_LT(results.maximum_relative_error, kJacobianRelTol);
}

TEST(CostFunctions, ReprojectionJacobianMatchesFiniteDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const double rotation[3] = {0.6 * u(rng), 0.6 * u(rng), 0.6 * u(rng)};
    const double translation[3] = {0.3 * u(rng), 0.3 * u(rng), 2.0 + 0.5 * u(rng)};
    const double intrinsics[kIntrinsicsSize] = {1400 + 50 * u(rng), 800 + 10 * u(rng),
                                                600 + 10 * u(rng), 0.05 * u(rng),
                                                0.01 * u(rng), 1.0 + 0.01 * u(rng)};
    const double point[3] = {0.8 * u(rng), 0.6 * u(rng), 0.2 * u(rng)};
    check_reprojection(rotation, translation, intrinsics, point);
  }
}

TEST(CostFunctions, ReprojectionJacobianAtZeroRotation) {
  const double rotation[3] = {0, 0, 0};
  const double translation[3] = {0.1, -0.2, 2.0};
  const double intrinsics[kIntrinsicsSize] = {1380, 812, 590, -0.04, 0.01, 1.0};
  const double point[3] = {0.3, 0.2, 0.05};
  check_reprojection(rotation, translation, intrinsics, point);
}

TEST(CostFunctions, ReprojectionRejectsPointsBehindTheCamera) {
  const ReprojectionCost cost(Eigen::Vector2d(0, 0), 1.0);
  const double pose[kPoseSize] = {0, 0, 0, 0, 0, -5};
  const double intrinsics[kIntrinsicsSize] = {1000, 500, 400, 0, 0, 1};
  const double point[3] = {0, 0, 1};
  double r[2];
  EXPECT_FALSE(cost(pose, intrinsics, point, r));
}

TEST(CostFunctions, MarkerPriorJacobianMatchesFiniteDifferences) {
  const MarkerPriorCost functor(Eigen::Vector3d(1.2, -0.4, 0.07), Eigen::Vector3d(0.002, 0.003, 0.01));
  ceres::AutoDiffCostFunction<MarkerPriorCost, 3, 3> cost(new MarkerPriorCost(functor));
  ceres::GradientChecker checker(&cost, no_manifolds(), central());
  const double point[3] = {1.205, -0.41, 0.09};
  std::vector<const double*> params{point};
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params.data(), kJacobianRelTol, &results)) << results.error_log;
  // The residual is in sigmas: 5 mm / 2 mm = 2.5 on E.
  EXPECT_NEAR(results.residuals(0), 2.5, 1e-9);
  EXPECT_NEAR(results.residuals(2), 2.0, 1e-9);
}

}  // namespace
}  // namespace strata
