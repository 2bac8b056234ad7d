#pragma once
// writer.vdb: the voxel model as an OpenVDB file (layout in volume/voxels.hpp): one
// fog-volume FloatGrid per unit and the Int32 label grid, in the site frame, written
// through a temporary name. The caller voxelizes; this holds the grids as they fill.
// OpenVDB stays in vdb_writer.cpp.
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace strata {

// Name of the label grid (the readers in volume/voxels.cpp look it up).
inline constexpr const char* kVdbLabelGrid = "labels";

// One unit's grid once pruned.
struct VdbUnitGrid {
  double fog_volume_m3 = 0;  // sum of fractions x voxel volume
  std::size_t active_voxels = 0;
};

class VdbWriter {
 public:
  // Voxel (i, j, k) centred at (ox + i*h, oy + j*h, k*h), site frame; without an
  // offset at (i*h, j*h, k*h). h = voxel_size_m, metres.
  VdbWriter(double voxel_size_m, const std::optional<Eigen::Vector2d>& offset);
  ~VdbWriter();
  VdbWriter(const VdbWriter&) = delete;
  VdbWriter& operator=(const VdbWriter&) = delete;

  // Index coordinates of a site-frame point (voxel centres at whole numbers).
  Eigen::Vector3d index_of(const Eigen::Vector3d& site_point) const;

  // The grid of the next unit; its voxels follow, then end_unit().
  void begin_unit(const std::string& unit, std::int32_t label, const std::string& top_layer);
  // The fraction of voxel (i, j, k) inside the unit (> 0); a labelled voxel takes
  // the unit's label in the label grid (a later unit overwrites an earlier one).
  void add_voxel(const std::array<int, 3>& ijk, double fraction, bool labelled);
  VdbUnitGrid end_unit();

  // Writes the grids with the file metadata (site origin, CRS, voxel size, the
  // label -> unit code of every unit). Returns the labelled voxels per label.
  // Throws IoError("writer.vdb: ...").
  std::map<std::int32_t, std::size_t> write(const std::filesystem::path& path, const Eigen::Vector3d& site_origin,
                                            const std::string& crs,
                                            const std::vector<std::pair<std::int32_t, std::string>>& unit_labels);

 private:
  struct Grids;
  std::unique_ptr<Grids> grids_;
  double h_;
};

}  // namespace strata
