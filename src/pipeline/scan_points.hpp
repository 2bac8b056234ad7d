#pragma once
// The points of a scan file mapped into the site frame, chunk by chunk (internal to
// the pipeline). Apart from layer_scans.cpp because the point-cloud reader's Rgb8
// and the dense mesh's are different types of one name.
#include <Eigen/Core>

#include <filesystem>
#include <functional>
#include <vector>

namespace strata {

struct ScanFrameMap {
  std::function<Eigen::Vector3d(const Eigen::Vector3d&)> point;  // file frame -> site frame, metres
  Eigen::Matrix3f normal = Eigen::Matrix3f::Identity();         // normals: file frame -> site frame
};
using SiteChunkSink =
    std::function<void(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3f>& normals)>;

// Reads every point of `file` (importers/scans/point_cloud.hpp), maps it, and hands
// the chunks to `sink`; normals are renormalised after the map (empty when none).
void read_scan_points(const std::filesystem::path& file, const ScanFrameMap& map, const SiteChunkSink& sink);

}  // namespace strata
