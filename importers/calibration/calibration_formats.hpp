#pragma once
// The readers behind read_calibration_file(), one per format (internal).
#include "importers/calibration/calibration_importer.hpp"

namespace strata::calibration_formats {

constexpr const char* kOpenCvStage = "importer.calibration.opencv";
constexpr const char* kMetashapeStage = "importer.calibration.metashape";

CalibrationFile read_opencv(const std::filesystem::path& file);
CalibrationFile read_metashape(const std::filesystem::path& file);

// The simplest of strata's models that holds every non-zero coefficient: radial when
// only k1, k2 are used, brown when k3 or a tangential term is. Fisheye is never
// inferred; a file says so.
CameraModel frame_model_for(const Intrinsics& k);

}  // namespace strata::calibration_formats
