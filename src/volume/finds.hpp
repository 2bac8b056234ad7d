#pragma once
// Finds in place: which unit's solid holds each find, from the voxel label model
// that `strata volume` writes (products/volume/units.vdb), and whether that
// contradicts the unit the find was recorded in.
//
// The geometric unit of a find is the label of the voxel that contains its point
// (none when the voxel is unlabelled or outside the model). Its distance to the
// recorded unit's solid is the Euclidean distance from the point to the nearest
// voxel cube of that unit (0 inside one). A find conflicts when the two units
// differ and that distance exceeds the tolerance: a point within a voxel or a
// survey error of its recorded unit's solid is consistent with it.
#include "project/find_records.hpp"
#include "project/project.hpp"
#include "volume/voxels.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// Total-station error on a find's point (a prism pole held on an object in the
// section), metres: what the tolerance allows beyond one voxel.
inline constexpr double kFindSurveyError = 0.01;

struct FindCheckOptions {
  // Distance to the recorded unit's solid (metres) beyond which a find that lies in
  // another unit, or in none, conflicts. 0: one voxel edge of the model plus
  // kFindSurveyError (0.02 m with the default 1 cm voxels).
  double tolerance_m = 0;
  void validate() const;  // InputError naming the field
};

struct FindPlacement {
  FindRecord find;
  std::optional<std::string> geometric_unit;  // unit whose solid holds the point
  // Metres from the point to the recorded unit's solid, 0 inside it; nothing when
  // the recorded unit has no voxel in the model (not excavated, or no surfaces).
  std::optional<double> distance_m;
  bool conflict = false;
};

struct FindsCheck {
  double voxel_size_m = 0;
  double tolerance_m = 0;  // as used
  std::vector<FindPlacement> finds;
  int conflicts() const;
};

// Places every find in the label model; positions in the site CRS.
FindsCheck place_finds(const LabelVolume& model, const std::vector<FindRecord>& finds, const FindCheckOptions& options);

// The voxel model of the units `strata volume` wrote (the latest "voxels" product),
// absolute path; nothing when there is none or its file is gone.
std::optional<std::filesystem::path> project_voxel_model(Project& project);

// The project's finds against its voxel model (the latest "voxels" product).
// InputError telling the user to run `strata volume` first when there is none.
FindsCheck check_project_finds(Project& project, const FindCheckOptions& options);

}  // namespace strata
