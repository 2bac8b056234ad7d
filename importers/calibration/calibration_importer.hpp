#pragma once
// importer.calibration.opencv and importer.calibration.metashape: a known camera
// calibration from a file, converted to strata's conventions (docs/cameras.md,
// "Known calibrations") and stored for one camera of the project. All or nothing:
// a refused file leaves the project unchanged.
#include "geometry/camera.hpp"
#include "project/project.hpp"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

enum class CalibrationFormat { automatic, opencv, metashape };
CalibrationFormat parse_calibration_format(const std::string& text);  // auto|opencv|metashape

// A calibration as a file states it, already in strata's conventions: pixels with
// (0,0) at the centre of the top-left pixel, OpenCV's order of the tangential terms,
// the file's own image size.
struct CalibrationFile {
  Intrinsics intrinsics;
  std::string format;              // "opencv" | "metashape"
  std::vector<std::string> notes;  // conversions applied, one sentence each
};

// Reads and converts; InputError starting with the stage name and the file, and
// naming the element (or line) at fault.
CalibrationFile read_calibration_file(const std::filesystem::path& file,
                                      CalibrationFormat format = CalibrationFormat::automatic);

// The same lens at another image size. Equal sizes: unchanged. The same aspect ratio
// (within kMaxAspectDifference): focal lengths and principal point scaled, the
// distortion coefficients (on normalised coordinates) kept, and a note added. Another
// aspect ratio (a crop, or a rotated image) cannot be converted: InputError.
Intrinsics fit_calibration_to_size(const Intrinsics& k, int width, int height, const std::string& what,
                                   std::vector<std::string>* notes);
// Relative difference of width/height ratios still taken as one aspect ratio:
// 6000x4000 photos resized to 1000x667 differ by 5e-4 from rounding.
constexpr double kMaxAspectDifference = 2e-3;

struct CalibrationImportOptions {
  std::string camera;  // camera id (strata camera list) or the name of one of its photos
  bool fixed = false;  // hold the calibration constant in every adjustment
  CalibrationFormat format = CalibrationFormat::automatic;
};

struct CalibrationImportSummary {
  std::int64_t camera_id = 0;
  std::string format;
  Intrinsics intrinsics;  // as stored: the camera's image size
  bool replaced = false;  // the camera had a calibration before
  std::vector<std::string> notes;
};

CalibrationImportSummary import_calibration(Project& project, const CalibrationImportOptions& options,
                                            const std::filesystem::path& file);

}  // namespace strata
