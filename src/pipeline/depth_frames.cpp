#include "pipeline/depth_frames.hpp"

#include "core/error.hpp"
#include "importers/depth/depth_files.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

constexpr std::size_t kChunkPoints = 65536;  // as the scan readers hand them over

}  // namespace

std::vector<Eigen::Vector3d> depth_frame_points(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                                int stride) {
  STRATA_CHECK(stride >= 1, "pixel stride {}", stride);
  const DepthIntrinsics& k = sequence.intrinsics;
  const DepthImage image = read_depth_png(file, k);
  std::vector<Eigen::Vector3d> out;
  out.reserve(std::size_t(image.valid) / std::size_t(stride * stride) + 1);
  for (int v = 0; v < image.height; v += stride)
    for (int u = 0; u < image.width; u += stride) {
      const std::uint16_t d = image.values[std::size_t(v) * std::size_t(image.width) + std::size_t(u)];
      if (d == 0) continue;
      const double z = d * sequence.depth_scale_m;
      out.emplace_back((u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z);
    }
  return out;
}

RangeScanInput depth_frame_input(const std::filesystem::path& file, const DepthSequenceRecord& sequence,
                                 const DepthFrameRecord& frame, int stride) {
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
  in.read = [file, sequence, pose, stride](const RangeScanInput::ChunkSink& sink) {
    const std::vector<Eigen::Vector3d> camera = depth_frame_points(file, sequence, stride);
    std::vector<Eigen::Vector3d> chunk;
    for (std::size_t begin = 0; begin < camera.size(); begin += kChunkPoints) {
      const std::size_t end = std::min(camera.size(), begin + kChunkPoints);
      chunk.clear();
      for (std::size_t i = begin; i < end; ++i) chunk.push_back(pose * camera[i]);
      sink(chunk, {});
    }
  };
  return in;
}

}  // namespace strata
