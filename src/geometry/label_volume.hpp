#pragma once
// The classified voxel model of the excavated volume as a dense block: what the
// volume stage reads back from its .vdb and the voxel exporters (GRASS 3D, VTK)
// write. Plain data, no OpenVDB.
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace strata {

// Unit labels on a block of voxels over the label grid's active bounding box.
struct LabelVolume {
  double voxel_size_m = 0;
  Eigen::Vector3d min_centre = Eigen::Vector3d::Zero();  // site frame, centre of voxel (0, 0, 0)
  int nx = 0, ny = 0, nz = 0;
  std::vector<std::int32_t> labels;                     // (k * ny + j) * nx + i; 0 = no unit
  std::map<std::int32_t, std::string> units;            // label -> unit code
  Eigen::Vector3d site_origin = Eigen::Vector3d::Zero();  // E, N, Z
  std::string crs;

  std::int32_t at(int i, int j, int k) const {
    return labels[(std::size_t(k) * std::size_t(ny) + std::size_t(j)) * std::size_t(nx) + std::size_t(i)];
  }
};

}  // namespace strata
