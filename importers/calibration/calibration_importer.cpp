#include "importers/calibration/calibration_importer.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "importers/calibration/calibration_formats.hpp"
#include "project/calibration_records.hpp"

#include <fmt/format.h>

#include <cmath>
#include <fstream>

namespace fs = std::filesystem;

namespace strata {
namespace {

// A Metashape calibration is XML whose root is <calibration> (or a cameras.xml
// <document>); OpenCV's XML has the root <opencv_storage>, its YAML starts "%YAML".
CalibrationFormat detect_format(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("importer.calibration: {}: cannot be read", file.string()));
  std::string head(4096, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));
  if (head.find("<opencv_storage") != std::string::npos) return CalibrationFormat::opencv;
  if (head.find("<calibration") != std::string::npos || head.find("<document") != std::string::npos) {
    return CalibrationFormat::metashape;
  }
  return CalibrationFormat::opencv;
}

std::string stage_of(const std::string& format) {
  return format == "metashape" ? calibration_formats::kMetashapeStage : calibration_formats::kOpenCvStage;
}

}  // namespace

CalibrationFormat parse_calibration_format(const std::string& text) {
  if (text == "auto") return CalibrationFormat::automatic;
  if (text == "opencv") return CalibrationFormat::opencv;
  if (text == "metashape") return CalibrationFormat::metashape;
  throw InputError(fmt::format("--format: '{}' is not one of auto, opencv, metashape", text));
}

CalibrationFile read_calibration_file(const fs::path& file, CalibrationFormat format) {
  door::input_file(file, "importer.calibration: calibration file", door::kMaxTextFileBytes);
  if (format == CalibrationFormat::automatic) format = detect_format(file);
  CalibrationFile out = format == CalibrationFormat::metashape ? calibration_formats::read_metashape(file)
                                                               : calibration_formats::read_opencv(file);
  validate_calibration(out.intrinsics, fmt::format("{}: {}", stage_of(out.format), file.string()));
  return out;
}

Intrinsics fit_calibration_to_size(const Intrinsics& k, int width, int height, const std::string& what,
                                   std::vector<std::string>* notes) {
  if (k.width == width && k.height == height) return k;
  const double sx = double(width) / k.width;
  const double sy = double(height) / k.height;
  if (std::abs(sx / sy - 1.0) > kMaxAspectDifference) {
    const bool rotated = k.width == height && k.height == width;
    throw InputError(fmt::format(
        "{}: calibrated for {}x{} px photos, but the camera's photos are {}x{} px{}; a calibration cannot be "
        "carried to another aspect ratio",
        what, k.width, k.height, width, height,
        rotated ? " (rotated: calibrate the photos as they are stored)" : " (cropped?)"));
  }
  // Same lens, resampled image: focal lengths scale, and the principal point with the
  // image area (pixel corners at -0.5 .. size-0.5); normalised distortion is unchanged.
  Intrinsics out = k;
  out.width = width;
  out.height = height;
  out.fx = k.fx * sx;
  out.fy = k.fy * sy;
  out.cx = (k.cx + 0.5) * sx - 0.5;
  out.cy = (k.cy + 0.5) * sy - 0.5;
  if (notes) {
    notes->push_back(fmt::format("scaled from {}x{} to the camera's {}x{} px (x {:.6g}): fx {:.6g} -> {:.6g} px",
                                 k.width, k.height, width, height, sx, k.fx, out.fx));
  }
  return out;
}

CalibrationImportSummary import_calibration(Project& project, const CalibrationImportOptions& options,
                                            const fs::path& file) {
  const CalibrationFile parsed = read_calibration_file(file, options.format);
  Database& db = project.db();
  const CameraRecord camera = resolve_camera(db, options.camera);
  CalibrationImportSummary s;
  s.camera_id = camera.id;
  s.format = parsed.format;
  s.notes = parsed.notes;
  s.intrinsics = fit_calibration_to_size(parsed.intrinsics, camera.width, camera.height,
                                         fmt::format("{}: {}", stage_of(parsed.format), file.string()), &s.notes);
  CalibrationRecord record;
  record.camera_id = camera.id;
  record.intrinsics = s.intrinsics;
  record.fixed = options.fixed;
  record.source = fmt::format("file {} ({})", file.filename().string(), parsed.format);
  Transaction tx(db);
  s.replaced = find_calibration(db, camera.id).has_value();
  upsert_calibration(db, record);
  fault::point("import.calibration.before_commit");
  tx.commit();
  return s;
}

}  // namespace strata
