#include "pipeline/scan_points.hpp"

#include "importers/scans/point_cloud.hpp"

namespace strata {

void read_scan_points(const std::filesystem::path& file, const ScanFrameMap& map, const SiteChunkSink& sink) {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3f> normals;
  std::vector<Eigen::Matrix<std::uint8_t, 3, 1>> colours;
  read_point_cloud_chunks(file, [&](const PointCloud& chunk, std::uint64_t) {
    points.resize(chunk.size());
    for (std::size_t i = 0; i < chunk.size(); ++i) points[i] = map.point(chunk.positions[i]);
    normals.resize(chunk.normals.size());
    for (std::size_t i = 0; i < chunk.normals.size(); ++i) normals[i] = (map.normal * chunk.normals[i]).normalized();
    colours.resize(chunk.colours.size());
    for (std::size_t i = 0; i < chunk.colours.size(); ++i)
      colours[i] = {chunk.colours[i][0], chunk.colours[i][1], chunk.colours[i][2]};
    sink(points, normals, colours);
  });
}

}  // namespace strata
