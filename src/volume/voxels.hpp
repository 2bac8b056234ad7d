#pragma once
// The voxel model of the excavated volume (OpenVDB stays in voxels.cpp). Its
// exports for GRASS (r3.in.ascii) and ParaView (VTK image data) are in
// exporters/voxels.
//
// One .vdb file holds, in the site frame (the grids' linear transform: voxel
// (i, j, k) centred at (ox + i*h, oy + j*h, k*h), metres, with 0 <= ox, oy < h
// chosen so that voxel faces fall on faces of the measurement grid):
//   - one FloatGrid per unit, named by its code, class "fog volume": the fraction
//     of each voxel inside the unit's solid, by height-field differencing per
//     voxel column: (sum over the grid cells whose centres fall in the column of
//     the overlap of [bottom, top] with the voxel's z range x cell area) / h^3.
//     The sum of fractions x h^3 is therefore exactly the raster volume.
//   - one Int32Grid "labels": the unit label (unit id) of every voxel more than
//     half inside a unit, the classified model of the whole excavated volume.
// File metadata: site_origin_e/n/z, crs, voxel_size_m, and "label_<n>" = unit code.
#include "geometry/label_volume.hpp"
#include "volume/volume.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace strata {

struct VoxelOptions {
  double voxel_size_m = 0.01;  // metres; 1 cm keeps a 2 m3 unit near 2 million voxels
  void validate() const;       // InputError naming the field
};

struct VoxelUnit {
  std::string unit;
  std::int32_t label = 0;
  double fog_volume_m3 = 0;    // sum of fractions x voxel volume
  double label_volume_m3 = 0;  // labelled voxels x voxel volume
  std::size_t active_voxels = 0;
  std::size_t labelled_voxels = 0;
};

struct VoxelSummary {
  double voxel_size_m = 0;
  std::vector<VoxelUnit> units;
};

// Voxelizes the solids and writes the .vdb (temporary file, then rename).
// labels: unit code -> label written into the label grid (the unit's database
// id); units without an entry get 1, 2, ... in order.
VoxelSummary write_unit_voxels(const std::filesystem::path& path, const std::vector<UnitSolid>& solids,
                               const std::map<std::string, std::int32_t>& labels, const VoxelOptions& options,
                               const Eigen::Vector3d& site_origin, const std::string& crs);

// Sum of fractions x voxel volume of every unit grid in a .vdb written above, m3,
// by unit code. Throws IoError when unreadable.
std::map<std::string, double> read_voxel_volumes(const std::filesystem::path& path);

// The label grid of a .vdb written above as a dense block (geometry/label_volume.hpp).
LabelVolume read_label_volume(const std::filesystem::path& path);

}  // namespace strata
