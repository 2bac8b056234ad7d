#pragma once
// File writers of the synthetic dataset (internal): JPEG with EXIF (OpenCV +
// exiv2), scan PLY, text files. Errors are IoError naming the file. The truth
// surfaces are GeoTIFFs written by exporters/raster.
#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace strata::synthetic {

struct ExifFields {
  bool write = true;              // false: the JPEG without any EXIF block
  std::string make, model, software, description;
  std::string datetime;           // EXIF form "YYYY:MM:DD HH:MM:SS"
  double focal_mm = 0;            // millimetres
  int focal_35mm = 0;             // millimetres, 35 mm-equivalent
  double sensor_width_mm = 0;     // millimetres, for FocalPlaneXResolution
  int width = 0, height = 0;      // pixels
};

// rgb: 8-bit, interleaved R, G, B, row-major.
void write_jpeg(const std::filesystem::path& path, const std::vector<std::uint8_t>& rgb, int width,
                int height, int quality, const ExifFields& exif);

// A point cloud as binary little-endian PLY: float x y z (metres) and float intensity.
void write_scan_ply(const std::filesystem::path& path, const std::vector<Eigen::Vector3f>& points,
                    const std::vector<float>& intensity, const std::string& comment);

// An output text file; throws IoError when it cannot be created. close() checks
// that everything reached the disk.
class TextFile {
 public:
  explicit TextFile(const std::filesystem::path& path);
  std::ofstream& out() { return out_; }
  void close();

 private:
  std::filesystem::path path_;
  std::ofstream out_;
};

// A CSV field, quoted when it holds a comma, quote or newline (RFC 4180).
std::string csv_field(const std::string& s);

}  // namespace strata::synthetic
