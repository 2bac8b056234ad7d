#include "features/rgbd_motion.hpp"

#include "core/error.hpp"

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

constexpr int kOrbBytes = 32;  // an ORB descriptor: 256 bits

// The depth (metres) at the pixel nearest (x, y), or 0 when that pixel or one of its
// eight neighbours has none or the nine span more than `max_step` (a depth edge: the
// keypoint may belong to either side).
double depth_at(const std::vector<std::uint16_t>& depth, const RgbdCamera& k, double x, double y, double max_step) {
  const int u = int(std::lround(x)), v = int(std::lround(y));
  if (u < 1 || v < 1 || u >= k.width - 1 || v >= k.height - 1) return 0;
  int lo = 65535, hi = 0;
  for (int dv = -1; dv <= 1; ++dv)
    for (int du = -1; du <= 1; ++du) {
      const int d = depth[std::size_t(v + dv) * std::size_t(k.width) + std::size_t(u + du)];
      if (d == 0) return 0;
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  if ((hi - lo) * k.depth_scale_m > max_step) return 0;
  return depth[std::size_t(v) * std::size_t(k.width) + std::size_t(u)] * k.depth_scale_m;
}

cv::Mat descriptor_rows(const RgbdFeatures& f) {
  // A view of the stored bytes (not copied): valid while `f` lives.
  return cv::Mat(int(f.points.size()), kOrbBytes, CV_8U, const_cast<std::uint8_t*>(f.descriptors.data()));
}

}  // namespace

void RgbdFeatureOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("rgbd features: {} must be {}", field, what));
  };
  need(max_features >= 10, "max_features", ">= 10");
  need(fast_threshold >= 1 && fast_threshold <= 255, "fast_threshold", "1..255 (grey levels)");
  need(ratio > 0 && ratio <= 1, "ratio", "in (0, 1]");
  need(pixel_sigma > 0, "pixel_sigma", "> 0 (pixels)");
  need(max_depth_m > 0, "max_depth_m", "> 0 (metres)");
  need(max_depth_step_m > 0, "max_depth_step_m", "> 0 (metres)");
  need(gate_sigmas > 0, "gate_sigmas", "> 0");
  need(min_inliers >= 3, "min_inliers", ">= 3");
  ransac.validate();
}

std::vector<std::uint8_t> read_grey_frame(const std::filesystem::path& file, int width, int height) {
  const cv::Mat grey = cv::imread(file.string(), cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
  if (grey.empty()) throw IoError(fmt::format("rgbd features: cannot read the colour frame {}", file.string()));
  if (grey.cols != width || grey.rows != height)
    throw InputError(fmt::format("rgbd features: {}: {} x {} pixels, the depth frames are {} x {}", file.string(),
                                 grey.cols, grey.rows, width, height));
  std::vector<std::uint8_t> out(std::size_t(width) * std::size_t(height));
  for (int r = 0; r < height; ++r) std::copy_n(grey.ptr<std::uint8_t>(r), width, out.data() + std::size_t(r) * width);
  return out;
}

RgbdFeatures extract_rgbd_features(const std::vector<std::uint8_t>& grey, const std::vector<std::uint16_t>& depth,
                                   const RgbdCamera& k, const RgbdFeatureOptions& o) {
  o.validate();
  const std::size_t pixels = std::size_t(k.width) * std::size_t(k.height);
  STRATA_CHECK(k.width > 2 && k.height > 2 && grey.size() == pixels && depth.size() == pixels,
               "{} x {} frame, {} grey and {} depth values", k.width, k.height, grey.size(), depth.size());
  const cv::Mat image(k.height, k.width, CV_8U, const_cast<std::uint8_t*>(grey.data()));
  // ORB: OpenCV's defaults (8 levels, x 1.2) but a lower FAST threshold.
  cv::Ptr<cv::ORB> orb = cv::ORB::create(o.max_features, 1.2f, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31,
                                         o.fast_threshold);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  orb->detectAndCompute(image, cv::noArray(), keypoints, descriptors);
  RgbdFeatures out;
  out.keypoints = int(keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const cv::Point2f& p = keypoints[i].pt;
    const double z = depth_at(depth, k, p.x, p.y, o.max_depth_step_m);
    if (z <= 0 || z > o.max_depth_m) continue;
    out.pixels.emplace_back(p.x, p.y);
    out.points.emplace_back((p.x - k.cx) * z / k.fx, (p.y - k.cy) * z / k.fy, z);
    // Along the ray the depth noise k z^2; across it the keypoint's position, worse on
    // the coarser pyramid levels (x 1.2 a level).
    const double across = z * o.pixel_sigma * std::pow(1.2, keypoints[i].octave) / k.fx;
    out.sigma_m.push_back(std::hypot(k.noise_k * z * z, across));
    const std::uint8_t* row = descriptors.ptr<std::uint8_t>(int(i));
    out.descriptors.insert(out.descriptors.end(), row, row + kOrbBytes);
  }
  return out;
}

RgbdMotion rgbd_relative_motion(const RgbdFeatures& a, const RgbdFeatures& b, const RgbdFeatureOptions& o) {
  o.validate();
  RgbdMotion out;
  if (a.points.size() < 3 || b.points.size() < 3) return out;
  const cv::Mat da = descriptor_rows(a), db = descriptor_rows(b);
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> forward;
  std::vector<cv::DMatch> backward;
  matcher.knnMatch(db, da, forward, 2);  // each of b's keypoints: its two nearest in a
  matcher.match(da, db, backward);       // each of a's keypoints: its nearest in b
  std::vector<Eigen::Vector3d> src, dst;  // b's points, a's points
  std::vector<double> gate;
  for (const auto& m : forward) {
    if (m.size() < 2 || m[0].distance >= o.ratio * m[1].distance) continue;  // ambiguous
    const int ib = m[0].queryIdx, ia = m[0].trainIdx;
    if (backward[std::size_t(ia)].trainIdx != ib) continue;  // not mutual
    src.push_back(b.points[std::size_t(ib)]);
    dst.push_back(a.points[std::size_t(ia)]);
    gate.push_back(o.gate_sigmas * std::hypot(a.sigma_m[std::size_t(ia)], b.sigma_m[std::size_t(ib)]));
  }
  out.matches = int(src.size());
  const std::optional<RobustSimilarity> fit = fit_rigid_ransac(src, dst, gate, o.ransac);
  if (!fit || int(fit->inliers) < o.min_inliers) {
    out.inliers = fit ? int(fit->inliers) : 0;
    return out;
  }
  out.found = true;
  out.inliers = int(fit->inliers);
  out.rms_m = fit->rms_m;
  out.motion.linear() = fit->fit.R;
  out.motion.translation() = fit->fit.t;
  return out;
}

}  // namespace strata
