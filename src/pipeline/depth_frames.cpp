#include "pipeline/depth_frames.hpp"

#include "core/error.hpp"
#include "importers/depth/depth_files.hpp"

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

constexpr std::size_t kChunkPoints = 65536;  // as the scan readers hand them over

}  // namespace

std::vector<Eigen::Vector3d> depth_frame_points(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                                int stride, std::vector<std::size_t>* pixels) {
  STRATA_CHECK(stride >= 1, "pixel stride {}", stride);
  const DepthIntrinsics& k = sequence.intrinsics;
  const DepthImage image = read_depth_png(file, k);
  std::vector<Eigen::Vector3d> out;
  out.reserve(std::size_t(image.valid) / std::size_t(stride * stride) + 1);
  if (pixels) pixels->clear();
  for (int v = 0; v < image.height; v += stride)
    for (int u = 0; u < image.width; u += stride) {
      const std::size_t p = std::size_t(v) * std::size_t(image.width) + std::size_t(u);
      const std::uint16_t d = image.values[p];
      if (d == 0) continue;
      const double z = d * sequence.depth_scale_m;
      out.emplace_back((u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z);
      if (pixels) pixels->push_back(p);
    }
  return out;
}

std::vector<std::uint8_t> depth_colour_frame(const std::filesystem::path& file, const DepthIntrinsics& intrinsics) {
  // Checked when imported (importer.depth.colour); read again from media/ here.
  cv::Mat bgr;
  try {
    bgr = cv::imread(file.string(), cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    throw IoError(fmt::format("dense.depth: {}: the colour frame cannot be decoded ({})", file.string(), e.what()));
  }
  if (bgr.empty()) throw IoError(fmt::format("dense.depth: {}: the colour frame cannot be read", file.string()));
  if (bgr.cols != intrinsics.width || bgr.rows != intrinsics.height) {
    throw IoError(fmt::format("dense.depth: {}: the colour frame is {} x {} pixels, the intrinsics say {} x {}",
                              file.string(), bgr.cols, bgr.rows, intrinsics.width, intrinsics.height));
  }
  STRATA_CHECK(bgr.type() == CV_8UC3, "{}: decoded as type {}", file.string(), bgr.type());
  std::vector<std::uint8_t> rgb(std::size_t(bgr.cols) * std::size_t(bgr.rows) * 3);
  for (int r = 0; r < bgr.rows; ++r) {
    const auto* row = bgr.ptr<cv::Vec3b>(r);
    for (int c = 0; c < bgr.cols; ++c) {
      const std::size_t p = 3 * (std::size_t(r) * std::size_t(bgr.cols) + std::size_t(c));
      rgb[p] = row[c][2];
      rgb[p + 1] = row[c][1];
      rgb[p + 2] = row[c][0];
    }
  }
  return rgb;
}

RangeScanInput depth_frame_input(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                 const DepthFrameRecord& frame, int stride,
                                 const std::optional<std::filesystem::path>& colour) {
  STRATA_CHECK(frame.pose.has_value(), "depth frame {} is not registered", frame.name);
  const Eigen::Isometry3d pose(*frame.pose);
  const Eigen::Vector3d centre = pose.translation();
  const Eigen::Vector3d axis = pose.linear().col(2);  // the optical axis in the site frame
  const double k = sequence.noise_k;
  // No point is trusted beyond the rounding of its stored depth (a uniform error of
  // one unit: sigma = unit / sqrt(12)).
  const double floor_m = sequence.depth_scale_m / std::sqrt(12.0);
  RangeScanInput in;
  in.name = sequence.name + "/" + frame.name;
  in.sigma_m = k;  // the noise at 1 m: the scale of the points' relative weights
  in.station = centre;
  in.point_sigma = [centre, axis, k, floor_m](const Eigen::Vector3d& p) {
    const double z = (p - centre).dot(axis);
    return std::max(k * z * z, floor_m);
  };
  in.read = [file, sequence, pose, stride, colour](const RangeScanInput::ChunkSink& sink) {
    std::vector<std::size_t> pixels;
    const std::vector<Eigen::Vector3d> camera = depth_frame_points(file, sequence, stride, &pixels);
    std::vector<std::uint8_t> rgb;
    if (colour) rgb = depth_colour_frame(*colour, sequence.intrinsics);
    std::vector<Eigen::Vector3d> chunk;
    std::vector<Rgb8> colours;
    for (std::size_t begin = 0; begin < camera.size(); begin += kChunkPoints) {
      const std::size_t end = std::min(camera.size(), begin + kChunkPoints);
      chunk.clear();
      colours.clear();
      for (std::size_t i = begin; i < end; ++i) {
        chunk.push_back(pose * camera[i]);
        if (!rgb.empty()) colours.emplace_back(rgb[3 * pixels[i]], rgb[3 * pixels[i] + 1], rgb[3 * pixels[i] + 2]);
      }
      sink(chunk, {}, colours);
    }
  };
  return in;
}

}  // namespace strata
