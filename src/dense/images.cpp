// Photo reading and undistortion: the only translation unit of the module that
// includes OpenCV. The stereo and fusion code sees plain float/RGB arrays.
#include "core/error.hpp"
#include "dense/internal.hpp"

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>

namespace strata::dense {

PinholeCamera undistorted_camera(const Intrinsics& intr, const Pose& pose, double scale) {
  PinholeCamera c;
  c.width = std::max(1, static_cast<int>(std::lround(intr.width * scale)));
  c.height = std::max(1, static_cast<int>(std::lround(intr.height * scale)));
  // Exact scale of each axis after rounding the size; with pixel centres at
  // integer coordinates, u_scaled = (u + 0.5) * s - 0.5.
  const double sx = static_cast<double>(c.width) / intr.width;
  const double sy = static_cast<double>(c.height) / intr.height;
  c.fx = intr.fx * sx;
  c.fy = intr.fy * sy;
  c.cx = (intr.cx + 0.5) * sx - 0.5;
  c.cy = (intr.cy + 0.5) * sy - 0.5;
  c.pose = pose;
  return c;
}

ViewImage undistort_image(const std::filesystem::path& photo, const Intrinsics& intr,
                          const Pose& pose, double scale) {
  cv::Mat bgr = cv::imread(photo.string(), cv::IMREAD_COLOR);
  if (bgr.empty()) {
    throw IoError(fmt::format("dense.undistort: {}: cannot read the photo", photo.string()));
  }
  if (bgr.cols != intr.width || bgr.rows != intr.height) {
    throw InputError(fmt::format("dense.undistort: {}: photo is {}x{} but its camera is {}x{}",
                                 photo.string(), bgr.cols, bgr.rows, intr.width, intr.height));
  }
  ViewImage out;
  out.camera = undistorted_camera(intr, pose, scale);
  const auto& c = out.camera;
  // Downscale first with pixel-area averaging (anti-aliasing), then undistort in
  // the scaled image; the radial model acts on normalised coordinates, so only
  // fx, fy, cx, cy scale.
  if (c.width != bgr.cols || c.height != bgr.rows) {
    cv::Mat small;
    cv::resize(bgr, small, cv::Size(c.width, c.height), 0, 0, cv::INTER_AREA);
    bgr = small;
  }
  cv::Mat map_x(c.height, c.width, CV_32FC1), map_y(c.height, c.width, CV_32FC1);
  for (int v = 0; v < c.height; ++v) {
    auto* mx = map_x.ptr<float>(v);
    auto* my = map_y.ptr<float>(v);
    for (int u = 0; u < c.width; ++u) {
      const Eigen::Vector2d xn((u - c.cx) / c.fx, (v - c.cy) / c.fy);
      const Eigen::Vector2d xd = intr.distort(xn);
      mx[u] = static_cast<float>(c.fx * xd.x() + c.cx);
      my[u] = static_cast<float>(c.fy * xd.y() + c.cy);
    }
  }
  cv::Mat undist_bgr, gray8, gray, mask;
  cv::remap(bgr, undist_bgr, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar());
  cv::cvtColor(bgr, gray8, cv::COLOR_BGR2GRAY);
  gray8.convertTo(gray8, CV_32F, 1.0 / 255.0);
  cv::remap(gray8, gray, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar());
  cv::Mat ones(bgr.rows, bgr.cols, CV_32FC1, cv::Scalar(1.0f));
  cv::remap(ones, mask, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar());

  const auto n = static_cast<std::size_t>(c.width) * c.height;
  out.gray.resize(n);
  out.rgb.resize(3 * n);
  for (int v = 0; v < c.height; ++v) {
    const auto* g = gray.ptr<float>(v);
    const auto* m = mask.ptr<float>(v);
    const auto* p = undist_bgr.ptr<cv::Vec3b>(v);
    for (int u = 0; u < c.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * c.width + u;
      // Pixels that touch the outside of the photo carry no signal.
      out.gray[i] = m[u] > 0.999f ? g[u] : std::numeric_limits<float>::quiet_NaN();
      out.rgb[3 * i + 0] = p[u][2];
      out.rgb[3 * i + 1] = p[u][1];
      out.rgb[3 * i + 2] = p[u][0];
    }
  }
  return out;
}

}  // namespace strata::dense
