// guide_markers() on rendered views of one chequered quadrant target lying on a
// textured ground plane, with known cameras: the guided positions and the refined
// clicks against the true projections of the marker's centre.
#include "core/error.hpp"
#include "georef/guide.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>

namespace strata {
namespace {

constexpr double kMarkerSize = 0.15;   // metres, as printed
constexpr double kYaw = 0.4;           // radians, the print's rotation on the ground
constexpr int kSupersample = 4;        // per pixel axis: antialiased edges
// Tolerances: the renderer is exact up to its 4 x 4 supersampling and 8-bit levels;
// a tenth of a pixel leaves room for both.
constexpr double kMaxGuidedErrorPx = 0.15;
constexpr double kMaxRefinedClickErrorPx = 0.15;

Intrinsics test_intrinsics() {
  Intrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = k.fy = 600;
  k.cx = 321.3;
  k.cy = 238.6;
  k.k1 = -0.05;
  k.k2 = 0.01;
  return k;
}

// Reflectance of the ground at (x, y) metres: the quadrant target (white border, black
// top-left and bottom-right quadrants) on a smooth texture.
double reflectance(double x, double y) {
  const double c = std::cos(kYaw), s = std::sin(kYaw);
  const double a = c * x + s * y, b = -s * x + c * y, half = 0.5 * kMarkerSize, cell = kMarkerSize / 8;
  if (std::abs(a) < half && std::abs(b) < half) {
    if (std::abs(a) > half - cell || std::abs(b) > half - cell) return 0.85;
    return (a < 0) == (b > 0) ? 0.04 : 0.85;
  }
  return 0.35 + 0.12 * std::sin(23 * x + 3 * y) * std::cos(17 * y - 5 * x) + 0.08 * std::sin(61 * x * y + 40 * y);
}

void render(const Camera& cam, const std::filesystem::path& path) {
  cv::Mat img(cam.intrinsics.height, cam.intrinsics.width, CV_8U);
  for (int v = 0; v < img.rows; ++v) {
    for (int u = 0; u < img.cols; ++u) {
      double sum = 0;
      for (int i = 0; i < kSupersample; ++i) {
        for (int j = 0; j < kSupersample; ++j) {
          const Eigen::Vector2d px(u - 0.5 + (i + 0.5) / kSupersample, v - 0.5 + (j + 0.5) / kSupersample);
          const Eigen::Vector3d d = cam.ray(px), c = cam.pose.centre();
          const Eigen::Vector3d P = c - c.z() / d.z() * d;  // ground z = 0
          sum += reflectance(P.x(), P.y());
        }
      }
      img.at<std::uint8_t>(v, u) = cv::saturate_cast<std::uint8_t>(255 * sum / (kSupersample * kSupersample));
    }
  }
  cv::imwrite(path.string(), img);
}

TEST(MarkerGuide, FindsARenderedQuadrantTargetToATenthOfAPixel) {
  test::ScratchDir dir("marker_guide");
  GuideInput input;
  // Six views around the marker, 1.4-2.2 m away, 35-60 degrees from the vertical.
  const double azimuths[] = {0.2, 1.1, 2.3, 3.0, 4.1, 5.3};
  for (int i = 0; i < 6; ++i) {
    const double dist = 1.0 + 0.15 * i, height = 1.2 + 0.1 * (i % 3);
    const Eigen::Vector3d centre(dist * std::cos(azimuths[i]), dist * std::sin(azimuths[i]), height);
    const Eigen::Vector3d target(0.03 * (i % 2), -0.02 * (i % 3), 0);  // the marker off the image centre
    Camera cam{test_intrinsics(), Pose::look_at(centre, target)};
    const auto path = dir / ("v" + std::to_string(i) + ".png");
    render(cam, path);
    input.photos.push_back({path.filename().string(), path, cam});
  }
  const Eigen::Vector3d X(0, 0, 0);
  // Sparse points on the ground around it (1 mm of noise): they give the plane.
  for (int i = 0; i < 40; ++i) {
    const double a = 0.5 * i, rad = 0.1 + 0.005 * i;
    input.sparse_points.push_back({rad * std::cos(a), rad * std::sin(a), 0.001 * std::sin(7.0 * i)});
  }
  // Clicks 2-3 px off in two views; a third click 8 px off (a careless click).
  GuideMarker m;
  m.name = "Q1";
  m.clicks.push_back({0, *input.photos[0].camera.project(X) + Eigen::Vector2d(2.0, -1.5)});
  m.clicks.push_back({3, *input.photos[3].camera.project(X) + Eigen::Vector2d(-1.0, 2.5)});
  m.clicks.push_back({5, *input.photos[5].camera.project(X) + Eigen::Vector2d(8.0, 0.0)});
  input.markers.push_back(m);

  MarkerGuideOptions options;
  options.marker_size_m = kMarkerSize;
  const MarkerGuideSummary s = guide_markers(options, input);
  ASSERT_EQ(s.markers.size(), 1u);
  const MarkerGuideResult& r = s.markers[0];
  ASSERT_TRUE(r.triangulated) << r.message;
  EXPECT_EQ(r.plane_points, 40);
  EXPECT_GT(r.normal.z(), std::cos(1.0 * 3.14159265358979 / 180));  // within a degree of up, turned up
  EXPECT_EQ(r.predicted, 3);
  ASSERT_EQ(r.added.size(), 3u);
  for (const auto& g : r.added) {
    const Eigen::Vector2d truth = *input.photos[std::size_t(g.photo)].camera.project(X);
    EXPECT_LT((g.pixel - truth).norm(), kMaxGuidedErrorPx) << input.photos[std::size_t(g.photo)].name;
    EXPECT_GT(g.score, options.min_score);
  }
  ASSERT_EQ(r.clicks.size(), 3u);
  for (const auto& c : r.clicks) {
    const Eigen::Vector2d truth = *input.photos[std::size_t(c.photo)].camera.project(X);
    ASSERT_TRUE(c.refined_ok) << input.photos[std::size_t(c.photo)].name;
    EXPECT_LT((c.refined - truth).norm(), kMaxRefinedClickErrorPx) << input.photos[std::size_t(c.photo)].name;
  }
  // The wrong click is named, with about its error; the good ones are not.
  EXPECT_FALSE(r.clicks[0].far);
  EXPECT_FALSE(r.clicks[1].far);
  EXPECT_TRUE(r.clicks[2].far);
  EXPECT_NEAR(r.clicks[2].to_rays_px, 8.0, 0.5);
  EXPECT_LT(r.position.norm(), 1e-3);  // metres
}

TEST(MarkerGuide, RefusesAMarkerWithOneClickAndInvalidOptions) {
  GuideInput input;
  input.photos.push_back({"a.jpg", "a.jpg", Camera{test_intrinsics(), Pose::look_at({1, 0, 1}, {0, 0, 0})}});
  input.markers.push_back({"Q1", {{0, {320, 240}}}, {}});
  try {
    guide_markers(MarkerGuideOptions{}, input);
    FAIL() << "a marker with one click was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("marker Q1 has 1 click"), std::string::npos) << e.what();
  }
  MarkerGuideOptions bad;
  bad.search_px = 0;
  try {
    bad.validate();
    FAIL() << "search_px 0 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("search_px"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace strata
