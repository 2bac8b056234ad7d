#pragma once
// Coded targets (ArUco / AprilTag markers on the ground-control points): detection
// with sub-pixel corners, and the rule that turns a marker id into the name of a
// surveyed marker. No OpenCV types here.
#include "features/types.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace strata {

struct TargetOptions {
  // Predefined dictionary, OpenCV's name with or without "DICT_", any case:
  // "DICT_4X4_50", "5X5_100", "ARUCO_ORIGINAL", "APRILTAG_36h11" (also "tag36h11").
  std::string dictionary = "DICT_4X4_50";
  enum class Refinement {
    none,      // ArUco polygon corners (about 0.5 px)
    subpixel,  // gradient corner refinement (cv::cornerSubPix) at full resolution
    apriltag,  // AprilTag 2 quad fitting on the detection image (then subpixel-free)
  };
  Refinement refinement = Refinement::subpixel;
  // Photos whose long side exceeds this many pixels are searched downscaled
  // (detection needs only a few pixels per marker cell); the corners are then
  // refined on the full-resolution photo. 0 = always full resolution.
  int max_detection_size = 3000;
  // Smallest marker perimeter accepted, as a fraction of the detection image's
  // long side (ArUco minMarkerPerimeterRate). In (0, 4).
  double min_perimeter_rate = 0.01;
  // Sub-pixel refinement stops when a corner moves less than this, pixels.
  double refine_epsilon_px = 0.005;

  void validate() const;  // throws InputError naming the field
};

struct TargetSummary {
  std::size_t detections = 0;
  std::size_t rejected_candidates = 0;  // square shapes that decoded to no id
  bool downscaled = false;              // detection ran on a reduced image
  double seconds = 0;
};

// Detects coded targets in one photo. Corners (in the dictionary's order:
// top-left, top-right, bottom-right, bottom-left of the marker) and the centre
// are in original photo pixels, (0,0) = centre of the top-left pixel. The centre
// is the intersection of the diagonals, the image of the marker's centre under
// perspective (the mean of the corners is not). Sorted by id; an id seen twice
// is reported twice (the caller decides: two physical targets cannot share an id).
// Throws IoError for an unreadable photo, InputError for bad options.
std::vector<TargetDetection> detect_targets(const TargetOptions& options,
                                            const std::filesystem::path& image,
                                            TargetSummary* summary = nullptr);

// The same on an 8-bit grey image in memory (row-major, `width` x `height`, no
// padding), e.g. an orthophoto; pixel coordinates as above. `max_detection_size`
// applies as for a photo. Throws InputError for bad options or an empty image.
std::vector<TargetDetection> detect_targets(const TargetOptions& options, const std::uint8_t* grey, int width,
                                            int height, TargetSummary* summary = nullptr);

// Marker names from target ids.
struct TargetNaming {
  // Pattern for ids not in `names`: "{id}" is replaced by the id, "{id:N}" by the
  // id zero-padded to N digits ("GCP{id:03}" -> GCP007). Empty: unmapped ids get
  // no name (their detections are ignored).
  std::string rule = "GCP{id}";
  std::map<int, std::string> names;  // explicit id -> marker name; wins over the rule

  void validate() const;  // throws InputError for a bad rule
};

// "3=GCP_A, 7=north peg" -> {3: "GCP_A", 7: "north peg"}: comma-separated id=name
// entries, names trimmed. Throws InputError naming the bad entry.
std::map<int, std::string> parse_target_names(std::string_view text);

// The marker name of a target id; empty when the id has no name.
std::string target_name(const TargetNaming& naming, int id);

}  // namespace strata
