#pragma once
// Orthophoto accuracy against the surveyed markers: the coded targets
// are detected in the orthophoto itself (the same ArUco detector as in the photos,
// src/features/targets.*), each detected centre is turned into map coordinates
// and compared with the surveyed position of its marker. Acceptance: every
// visible marker's centre within `tolerance_px` orthophoto pixels of its survey.
#include "features/targets.hpp"
#include "geometry/raster.hpp"

#include <Eigen/Core>

#include <limits>
#include <string>
#include <vector>

namespace strata {

// A surveyed marker in the site frame (metres: CRS coordinates minus the origin).
struct SurveyedMarker {
  std::string name;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  std::string kind = "control";  // control|check
};

struct OrthoMarkerCheckOptions {
  TargetOptions targets;   // dictionary and corner refinement, as for the photos
  TargetNaming naming;     // target id -> marker name, as for the photos
  double tolerance_px = 2; // orthophoto pixels: a marker further off is flagged
  // The orthophoto is enlarged by these integer factors (bicubic) and searched at
  // each: at the usual 5-10 mm cell a 15 cm target is only 15-30 pixels wide, 2.5-5
  // pixels per code cell, too few for the ArUco contour and bit tests, and whether
  // ArUco's thresholds and bit sampling accept a blurred target changes from one
  // enlargement to the next. A target found at several factors is placed at the
  // mean of its centres. Each in [1, 8], at least one.
  std::vector<int> upsample = {2, 3, 4};
  // The search runs tile by tile (this many cells square, >= 64), each tile read
  // with a margin of tile_margin_m and enlarged on its own: a whole orthophoto of a
  // large site at a fine cell, enlarged 4 x, would need gigabytes. The margin must
  // exceed the targets' size (15-30 cm usually).
  int tile_cells = 1024;
  double tile_margin_m = 0.4;
  // Radius (metres) around a missed marker's survey in which the orthophoto must be
  // coloured (>= 90 % of cells) for the miss to count as not_detected rather than
  // partly_seen: a 15 cm target and its margin.
  double coverage_radius_m = 0.1;
  // Holes in the orthophoto (alpha 0) of at most this many connected cells are
  // filled from their surroundings (OpenCV Telea inpainting) in the detection
  // image only: single unseen cells on a target's white margin or code would
  // otherwise break its outline. Larger unseen areas become mid-grey. 0 = none.
  int fill_holes_max_cells = 16;
  // A missed marker whose surroundings were coloured only from photos whose pixels,
  // on the ground along the slope, are larger than this many orthophoto cells is
  // `coarse`, not `not_detected`: the photos do not resolve the orthophoto's cell
  // there (seen only from afar at grazing angles), so the orthophoto shows a smear of
  // the target, not the target. Needs the orthophoto's source pixel sizes.
  double max_source_pixel_cells = 1.0;
  // Throws InputError naming the first invalid field.
  void validate() const;
};

enum class OrthoMarkerStatus {
  detected,      // found in the orthophoto: offsets valid
  outside,       // its surveyed position is off the orthophoto grid
  not_seen,      // on the grid, but no photo coloured the cells there (alpha 0)
  partly_seen,   // its centre is coloured, but holes in the orthophoto around it
  coarse,        // coloured all around, but only from photos coarser there than the cell
  not_detected,  // coloured all around at the cell's resolution, but no target of that name found
};
const char* to_string(OrthoMarkerStatus s);

struct OrthoMarkerOffset {
  std::string name;
  std::string kind;
  OrthoMarkerStatus status = OrthoMarkerStatus::not_detected;
  Eigen::Vector2d surveyed = Eigen::Vector2d::Zero();  // metres, site frame E, N
  Eigen::Vector2d detected = Eigen::Vector2d::Zero();  // metres, site frame E, N (detected only)
  double de_m = 0, dn_m = 0;  // detected - surveyed, metres (detected only)
  double offset_m = 0;        // horizontal distance, metres
  double offset_px = 0;       //   in orthophoto pixels
  int detections = 0;         // targets of this name found (more than 1: a doubled target, e.g. at a seam)
  int scales = 0;             // enlargement factors at which the reported target was found
  // Median ground size (metres, along the slope) of the pixels of the photos that
  // coloured the orthophoto within coverage_radius_m of the survey; NaN when unknown.
  double source_pixel_m = std::numeric_limits<double>::quiet_NaN();
};

struct OrthoMarkerCheck {
  double cell_m = 0;                       // orthophoto cell, metres
  double tolerance_px = 0;
  std::vector<OrthoMarkerOffset> markers;  // every surveyed marker, in the order given
  std::vector<int> unknown_ids;            // detected target ids that name no surveyed marker
  int detected = 0;                        // markers with status detected
  int over_tolerance = 0;                  // detected markers further off than tolerance_px
  double max_px = 0, rmse_px = 0;          // horizontal offset over detected markers, pixels
  double max_m = 0, rmse_m = 0;            //   and metres (RMSE = sqrt(mean(dE^2 + dN^2)))
  double seconds = 0;
};

// Detects the targets in `ortho` and compares them with `markers`. A target seen
// more than once keeps the detection nearest its survey. `source_pixel_m` (optional,
// OrthoSummary::source_pixel_m of the same grid) tells `coarse` from `not_detected`.
// Throws InputError for bad options.
OrthoMarkerCheck check_ortho_markers(const RgbaRaster& ortho, const std::vector<SurveyedMarker>& markers,
                                     const OrthoMarkerCheckOptions& options,
                                     const std::vector<float>* source_pixel_m = nullptr);

}  // namespace strata
