// Finite-difference checks of every hand-written cost function of the bundle
// adjustment (PoseLib's verify_jacobian / ceres::GradientChecker): the automatic
// derivatives must match central differences, including at a zero rotation where the
// angle-axis formula switches to its first-order form.
#include "sfm/bundle_problem.hpp"
#include "sfm/cost_functions.hpp"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <array>
#include <cmath>
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

constexpr CameraModel kModels[] = {CameraModel::radial, CameraModel::brown, CameraModel::fisheye};

void check_reprojection(CameraModel model, const double* rotation, const double* translation,
                        const double* intrinsics, const double* point) {
  const ReprojectionCost functor(Eigen::Vector2d(700.3, 455.9), 0.7, model);
  ceres::AutoDiffCostFunction<ReprojectionCost, 2, kPoseSize, kIntrinsicsSize, 3> cost(
      new ReprojectionCost(functor));
  ceres::GradientChecker checker(&cost, no_manifolds(), central());
  const double pose[kPoseSize] = {rotation[0],    rotation[1],    rotation[2],
                                  translation[0], translation[1], translation[2]};
  std::vector<const double*> params{pose, intrinsics, point};
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params.data(), kJacobianRelTol, &results))
      << to_string(model) << "\n" << results.error_log;
  EXPECT_LT(results.maximum_relative_error, kJacobianRelTol) << to_string(model);
}

// A block with every coefficient set (the model ignores those it does not have).
std::array<double, kIntrinsicsSize> random_block(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::array<double, kIntrinsicsSize> b{};
  b[kFocal] = 1400 + 50 * u(rng);
  b[kCx] = 800 + 10 * u(rng);
  b[kCy] = 600 + 10 * u(rng);
  b[kK1] = 0.05 * u(rng);
  b[kK2] = 0.01 * u(rng);
  b[kAspect] = 1.0 + 0.01 * u(rng);
  b[kK3] = 0.005 * u(rng);
  b[kK4] = 0.001 * u(rng);
  b[kP1] = 1e-3 * u(rng);
  b[kP2] = 1e-3 * u(rng);
  return b;
}

TEST(CostFunctions, ReprojectionJacobianMatchesFiniteDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (CameraModel model : kModels) {
    for (int trial = 0; trial < 20; ++trial) {
      const double rotation[3] = {0.6 * u(rng), 0.6 * u(rng), 0.6 * u(rng)};
      const double translation[3] = {0.3 * u(rng), 0.3 * u(rng), 2.0 + 0.5 * u(rng)};
      const auto intrinsics = random_block(rng);
      // At least 0.2 normalised units off the axis: there the derivatives by the
      // highest terms (theta^9 for k4) are well above the finite differences' noise,
      // so the relative comparison means something.
      double point[3];
      for (;;) {
        point[0] = 0.8 * u(rng);
        point[1] = 0.6 * u(rng);
        point[2] = 0.2 * u(rng);
        double xc[3];
        angle_axis_rotate(rotation, point, xc);
        for (int i = 0; i < 3; ++i) xc[i] += translation[i];
        if (std::hypot(xc[0], xc[1]) / xc[2] > 0.2) break;
      }
      check_reprojection(model, rotation, translation, intrinsics.data(), point);
    }
  }
}

TEST(CostFunctions, ReprojectionJacobianAtZeroRotation) {
  const double rotation[3] = {0, 0, 0};
  const double translation[3] = {0.1, -0.2, 2.0};
  const double intrinsics[kIntrinsicsSize] = {1380, 812, 590, -0.04, 0.01, 1.0,
                                              0.002, -0.0004, 3e-4, -2e-4};
  const double point[3] = {0.3, 0.2, 0.05};
  for (CameraModel model : kModels) check_reprojection(model, rotation, translation, intrinsics, point);
}

TEST(CostFunctions, FisheyeJacobianOnTheOpticalAxis) {
  // r = 0: theta_d / r is taken as its limit 1 (the formula's sqrt has no derivative).
  const double rotation[3] = {0, 0, 0};
  const double translation[3] = {0, 0, 2.0};
  const double intrinsics[kIntrinsicsSize] = {900, 800, 600, 0.03, -0.01, 1.0, 0.002, -0.0004, 0, 0};
  const double point[3] = {0, 0, 0.5};
  check_reprojection(CameraModel::fisheye, rotation, translation, intrinsics, point);
}

TEST(CostFunctions, ProjectionAgreesWithTheCameraModel) {
  // The templated lens formulas of the adjustment and Intrinsics::to_pixel are
  // written separately: they must give the same pixel.
  constexpr double kAgreementPx = 1e-9;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (CameraModel model : kModels) {
    for (int trial = 0; trial < 50; ++trial) {
      const auto b = random_block(rng);
      Intrinsics k;
      k.model = model;
      from_block(b, k);
      // Unused fields as from_block leaves them must not matter: zero them the way
      // to_block does and compare to the block as given.
      const Eigen::Vector3d X(0.9 * u(rng), 0.7 * u(rng), 1.5 + 0.3 * u(rng));
      const Eigen::Vector2d xn = X.head<2>() / X.z();
      const Eigen::Vector2d observed(0, 0);
      const ReprojectionCost cost(observed, 1.0, model);
      const double pose[kPoseSize] = {0, 0, 0, 0, 0, 0};
      const auto used = to_block(k);  // coefficients of other models zeroed
      double r[2];
      ASSERT_TRUE(cost(pose, used.data(), X.data(), r));
      if (model == CameraModel::radial) {
        k.k3 = k.k4 = k.p1 = k.p2 = 0;
      } else if (model == CameraModel::brown) {
        k.k4 = 0;
      } else {
        k.p1 = k.p2 = 0;
      }
      const Eigen::Vector2d px = k.to_pixel(xn);
      EXPECT_NEAR(r[0], px.x(), kAgreementPx) << to_string(model);
      EXPECT_NEAR(r[1], px.y(), kAgreementPx) << to_string(model);
    }
  }
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
