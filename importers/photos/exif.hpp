#pragma once
// What strata reads from a photo's EXIF (through exiv2).
#include <filesystem>
#include <optional>
#include <string>

namespace strata {

struct PhotoMetadata {
  int width = 0, height = 0;             // pixels, from the image itself
  std::string make, model;
  std::optional<double> focal_mm;        // FocalLength
  std::optional<double> focal_35mm;      // FocalLengthIn35mmFilm
  std::optional<std::string> captured_at;  // DateTimeOriginal, ISO 8601 (no zone)
  std::optional<int> exif_width, exif_height;  // PixelX/YDimension (may be the original size)
  std::optional<double> focal_plane_x_res;     // FocalPlaneXResolution, pixels per unit
  std::optional<double> focal_plane_unit_mm;   // FocalPlaneResolutionUnit in mm
  bool has_exif = false;
};

// Reads the metadata; throws InputError when exiv2 cannot parse the file.
PhotoMetadata read_photo_metadata(const std::filesystem::path& path);

// Focal length prior in pixels from the metadata, and how it was found:
// 1) FocalLength with a sensor width from the shipped list, 2) FocalLength with the
// EXIF focal-plane resolution, 3) FocalLengthIn35mmFilm scaled by the image diagonal
// (the 35 mm equivalent is defined on the 43.27 mm diagonal).
struct FocalPrior {
  std::optional<double> focal_px;
  std::optional<double> sensor_width_mm;
  std::string source = "unknown";  // sensor_list|focal_plane|35mm|unknown
};
FocalPrior focal_prior(const PhotoMetadata& m);

}  // namespace strata
