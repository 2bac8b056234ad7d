// The lens models of geometry/camera.hpp: distort() against OpenCV's implementations
// of the same formulas (cv::projectPoints for radial and Brown, cv::fisheye for the
// equidistant model), and undistort() as its inverse across the image.
#include "geometry/camera.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <cmath>
#include <vector>

namespace strata {
namespace {

// Both sides evaluate the same polynomials in double precision: rounding only
// (pixels, over a 3000 px image).
constexpr double kAgreementPx = 1e-8;
// undistort() stops its Newton iteration at |error| < 1e-13 (normalised units):
// distort(undistort(x)) returns x to far below a micro-pixel.
constexpr double kRoundTripPx = 1e-7;

// Realistic lenses (docs/cameras.md, "Synthetic lenses").
Intrinsics dslr_brown() {
  Intrinsics k;
  k.width = 3000;
  k.height = 2000;
  k.fx = 2100;
  k.fy = 2102;
  k.cx = 1510;
  k.cy = 991;
  k.model = CameraModel::brown;
  k.k1 = -0.16;
  k.k2 = 0.09;
  k.k3 = -0.02;
  k.p1 = 4e-4;
  k.p2 = -6e-4;
  return k;
}

Intrinsics action_fisheye() {
  Intrinsics k;
  k.width = 2000;
  k.height = 1500;
  // Equidistant: the half-diagonal of 1250 px at 75 degrees (1.309 rad) -> f ~ 955 px.
  k.fx = k.fy = 955;
  k.cx = 1003;
  k.cy = 748;
  k.model = CameraModel::fisheye;
  k.k1 = 0.04;
  k.k2 = -0.01;
  k.k3 = 0.003;
  k.k4 = -0.0005;
  return k;
}

Intrinsics phone_radial() {
  Intrinsics k;
  k.width = 3000;
  k.height = 2000;
  k.fx = k.fy = 2400;
  k.cx = 1495;
  k.cy = 1004;
  k.model = CameraModel::radial;
  k.k1 = -0.06;
  k.k2 = 0.02;
  return k;
}

// Pixels on a grid over the whole image, corners included.
std::vector<Eigen::Vector2d> image_grid(const Intrinsics& k, int steps = 12) {
  std::vector<Eigen::Vector2d> px;
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; j <= steps; ++j) {
      px.emplace_back((k.width - 1) * double(i) / steps, (k.height - 1) * double(j) / steps);
    }
  }
  return px;
}

cv::Matx33d camera_matrix(const Intrinsics& k) {
  return {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1};
}

// Points in front of the camera at the rays of the image grid.
std::vector<cv::Point3d> object_points(const Intrinsics& k) {
  std::vector<cv::Point3d> pts;
  for (const auto& p : image_grid(k)) {
    const Eigen::Vector2d xn = k.to_normalised(p);
    pts.emplace_back(2.0 * xn.x(), 2.0 * xn.y(), 2.0);
  }
  return pts;
}

void expect_matches_opencv(const Intrinsics& k, const std::vector<cv::Point2d>& cv_px,
                           const std::vector<cv::Point3d>& pts) {
  ASSERT_EQ(cv_px.size(), pts.size());
  double worst = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector2d xn(pts[i].x / pts[i].z, pts[i].y / pts[i].z);
    const Eigen::Vector2d ours = k.to_pixel(xn);
    worst = std::max(worst, (ours - Eigen::Vector2d(cv_px[i].x, cv_px[i].y)).norm());
  }
  EXPECT_LT(worst, kAgreementPx) << to_string(k.model);
}

TEST(CameraModel, RadialAgreesWithOpenCvProjectPoints) {
  const Intrinsics k = phone_radial();
  const auto pts = object_points(k);
  std::vector<cv::Point2d> px;
  const cv::Vec<double, 5> dist(k.k1, k.k2, 0, 0, 0);
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_matrix(k), dist, px);
  expect_matches_opencv(k, px, pts);
}

TEST(CameraModel, BrownAgreesWithOpenCvProjectPoints) {
  const Intrinsics k = dslr_brown();
  const auto pts = object_points(k);
  std::vector<cv::Point2d> px;
  // OpenCV's order: k1, k2, p1, p2, k3.
  const cv::Vec<double, 5> dist(k.k1, k.k2, k.p1, k.p2, k.k3);
  cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_matrix(k), dist, px);
  expect_matches_opencv(k, px, pts);
}

TEST(CameraModel, FisheyeAgreesWithOpenCvFisheye) {
  const Intrinsics k = action_fisheye();
  const auto pts = object_points(k);
  std::vector<cv::Point2d> px;
  const cv::Vec4d dist(k.k1, k.k2, k.k3, k.k4);
  cv::fisheye::projectPoints(pts, px, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_matrix(k),
                             dist);
  expect_matches_opencv(k, px, pts);
}

TEST(CameraModel, FisheyeCornerIsSeventyFiveDegreesOffAxis) {
  // The action camera of the synthetic generator: about 150 degrees diagonally.
  const Intrinsics k = action_fisheye();
  const Eigen::Vector2d xn = k.to_normalised({0.0, 0.0});
  const double off_axis_deg = std::atan(xn.norm()) * 180.0 / M_PI;
  EXPECT_GT(off_axis_deg, 70.0);
  EXPECT_LT(off_axis_deg, 80.0);
}

TEST(CameraModel, UndistortInvertsDistortOverTheWholeImage) {
  for (const Intrinsics& k : {phone_radial(), dslr_brown(), action_fisheye()}) {
    double worst = 0;
    for (const auto& p : image_grid(k, 30)) {
      const Eigen::Vector2d back = k.to_pixel(k.to_normalised(p));
      worst = std::max(worst, (back - p).norm());
    }
    EXPECT_LT(worst, kRoundTripPx) << to_string(k.model);
  }
}

TEST(CameraModel, UndistortAgreesWithOpenCvUndistortPoints) {
  // The inverse, independently: OpenCV's iterative undistortion with enough
  // iterations to converge (its default of 5 does not at the corners of a DSLR zoom).
  const Intrinsics k = dslr_brown();
  std::vector<cv::Point2d> px, xn;
  for (const auto& p : image_grid(k)) px.emplace_back(p.x(), p.y());
  const cv::Vec<double, 5> dist(k.k1, k.k2, k.p1, k.p2, k.k3);
  cv::undistortPoints(px, xn, camera_matrix(k), dist, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-15));
  constexpr double kNormalisedTol = 1e-8;  // ~2e-5 px at f = 2100
  for (std::size_t i = 0; i < px.size(); ++i) {
    const Eigen::Vector2d ours = k.to_normalised({px[i].x, px[i].y});
    EXPECT_NEAR(ours.x(), xn[i].x, kNormalisedTol);
    EXPECT_NEAR(ours.y(), xn[i].y, kNormalisedTol);
  }
}

TEST(CameraModel, ModelNamesRoundTrip) {
  for (CameraModel m : {CameraModel::radial, CameraModel::brown, CameraModel::fisheye}) {
    EXPECT_EQ(camera_model_from_string(to_string(m)), m);
  }
  EXPECT_FALSE(camera_model_from_string("pinhole").has_value());
}

TEST(Camera, RayAndProjectAreInverseForEveryModel) {
  const Pose pose = Pose::look_at({0.5, -1.0, 2.0}, {0, 0, 0});
  for (const Intrinsics& k : {phone_radial(), dslr_brown(), action_fisheye()}) {
    const Camera cam{k, pose};
    for (const auto& p : image_grid(k, 6)) {
      const Eigen::Vector3d X = pose.centre() + 1.7 * cam.ray(p);
      const auto back = cam.project(X);
      ASSERT_TRUE(back.has_value());
      EXPECT_LT((*back - p).norm(), kRoundTripPx) << to_string(k.model);
    }
  }
}

}  // namespace
}  // namespace strata
