#pragma once
// The points of a scan file mapped into the site frame, chunk by chunk (internal to
// the pipeline). Apart from layer_scans.cpp because the point-cloud reader's Rgb8
// and the dense mesh's are different types of one name.
#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <vector>

namespace strata {

struct ScanFrameMap {
  std::function<Eigen::Vector3d(const Eigen::Vector3d&)> point;  // file frame -> site frame, metres
  Eigen::Matrix3f normal = Eigen::Matrix3f::Identity();         // normals: file frame -> site frame
};
// The colours as the dense stage takes them (geometry/mesh.hpp's Rgb8).
using SiteChunkSink =
    std::function<void(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3f>& normals,
                       const std::vector<Eigen::Matrix<std::uint8_t, 3, 1>>& colours)>;

// Reads every point of `file` (importers/scans/point_cloud.hpp), maps it, and hands
// the chunks to `sink`; normals are renormalised after the map (empty when none);
// colours as the file holds them (empty when none).
void read_scan_points(const std::filesystem::path& file, const ScanFrameMap& map, const SiteChunkSink& sink);

}  // namespace strata
