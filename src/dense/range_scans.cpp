// Range scans in the dense stage: the rays their points are fused along, their point
// spacing and noise (the voxel size of a layer without photos) and the loop that hands their
// chunks to the volume (fusion.cpp, the only file that includes OpenVDB).
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/statistics.hpp"
#include "dense/internal.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace strata::dense {
namespace {

constexpr double kSpacingCell = 0.01;  // metres: XY cell over which the point density is counted

}  // namespace

std::vector<Eigen::Vector3d> scan_ray_directions(const RangeScanInput& scan, const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<Eigen::Vector3f>& normals) {
  std::vector<Eigen::Vector3d> dirs(points.size(), -Eigen::Vector3d::UnitZ());
  const bool with_normals = normals.size() == points.size();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (scan.station) {
      const Eigen::Vector3d d = points[i] - *scan.station;
      const double r = d.norm();
      if (r > 0) dirs[i] = d / r;
    } else if (with_normals) {
      Eigen::Vector3d n = normals[i].cast<double>();
      const double len = n.norm();
      if (!(len > 0)) continue;
      n /= len;
      if (n.z() < 0) n = -n;  // a normal's sign is not known: the sensor looked from above
      dirs[i] = -n;
    }
  }
  return dirs;
}

ScanSampling scan_sampling(const std::vector<RangeScanInput>& scans) {
  std::unordered_map<std::int64_t, std::uint32_t> cells;
  std::vector<double> noise;  // per input: the median of its points' sigmas
  for (const auto& scan : scans) {
    check_cancelled();
    std::vector<double> sigmas;
    std::size_t points = 0;
    scan.read([&](const std::vector<Eigen::Vector3d>& chunk, const std::vector<Eigen::Vector3f>&,
                  const std::vector<Rgb8>&) {
      for (const auto& p : chunk) {
        const auto i = static_cast<std::int64_t>(std::floor(p.x() / kSpacingCell));
        const auto j = static_cast<std::int64_t>(std::floor(p.y() / kSpacingCell));
        ++cells[(i << 32) ^ (j & 0xffffffff)];
        if (scan.point_sigma) sigmas.push_back(scan.point_sigma(p));
      }
      points += chunk.size();
    });
    if (points == 0) continue;
    noise.push_back(scan.point_sigma ? median_in_place(sigmas) : scan.sigma_m);
  }
  if (cells.empty()) throw ProcessingError("dense: the scans hold no points");
  std::vector<double> spacing;
  spacing.reserve(cells.size());
  for (const auto& [key, count] : cells) spacing.push_back(kSpacingCell / std::sqrt(double(count)));
  return {median_in_place(spacing), median_in_place(noise)};
}

ScanFusionFigures fuse_scans(TsdfVolume& volume, const std::vector<RangeScanInput>& scans, double unit_sigma_m) {
  STRATA_CHECK(unit_sigma_m > 0, "bad unit sigma {}", unit_sigma_m);
  ScanFusionFigures f;
  Progress progress("dense: scans", scans.size());
  for (const auto& scan : scans) {
    check_cancelled();
    std::uint64_t points = 0;
    std::vector<double> relative;  // (sigma_m / point sigma)^2, when the noise varies
    scan.read([&](const std::vector<Eigen::Vector3d>& chunk, const std::vector<Eigen::Vector3f>& normals,
                  const std::vector<Rgb8>& colours) {
      relative.clear();
      if (scan.point_sigma) {
        relative.reserve(chunk.size());
        for (const auto& p : chunk) {
          const double sigma = scan.point_sigma(p);
          STRATA_CHECK(sigma > 0 && std::isfinite(sigma), "scan {}: point sigma {}", scan.name, sigma);
          relative.push_back(std::pow(scan.sigma_m / sigma, 2));
        }
      }
      volume.add_scan_points(chunk, scan_ray_directions(scan, chunk, normals), relative, colours);
      points += chunk.size();
    });
    // Inverse variance in the fusion's unit weight (FusionOptions::photo_depth_sigma_gsd).
    const double per_point = std::pow(unit_sigma_m / scan.sigma_m, 2);
    const TsdfVolume::ScanFusion added = volume.end_scan(per_point);
    f.weight += added.weight;
    f.points += points;
    ++f.scans;
    progress.step();
  }
  return f;
}

}  // namespace strata::dense
