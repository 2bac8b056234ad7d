#pragma once
// importer.scans: range scans (point clouds from a terrestrial laser scanner or a
// phone LiDAR app) of one layer. Each file is read through and checked, then copied
// unchanged into the media store and recorded in the `scans` table with what it
// holds, its instrument noise and its registration state. All or nothing: one bad
// file and nothing is imported.
#include "geometry/similarity.hpp"
#include "importers/scans/point_cloud.hpp"
#include "project/project.hpp"
#include "project/scan_records.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// A terrestrial phase or time-of-flight scanner at 10-25 m measures range to 2-5 mm
// (one sigma); phone LiDAR is nearer 10-20 mm: give --sigma for those.
constexpr double kDefaultScanSigmaM = 0.005;

struct ScanImportOptions {
  std::string layer;                              // required: the layer the scans record
  std::optional<std::string> crs;                 // the files' coordinates are in this CRS (e.g. "EPSG:32636")
  std::optional<std::filesystem::path> transform; // 4x4 similarity file: scanner frame -> site frame
  double sigma_m = kDefaultScanSigmaM;            // instrument range noise, one sigma, metres; > 0
};

struct ImportedScan {
  std::string file;
  PointCloudInfo info;
  ScanRegistration registration = ScanRegistration::unregistered;
  std::optional<ScanBounds> bounds;  // site frame, when registered
};

struct ScanImportSummary {
  std::vector<ImportedScan> imported;
  std::vector<std::string> already_present;  // same content already in the layer (or the batch)
};

ScanImportSummary import_scans(Project& project, const ScanImportOptions& options,
                               const std::vector<std::filesystem::path>& files);

// A scan's pose from a text file of 16 numbers, a row-major 4x4 matrix (whitespace
// or comma separated, '#' comments), as CloudCompare and most registration tools
// write it. Refused (InputError naming the file) unless it is a similarity: last row
// 0 0 0 1, upper 3x3 a positive scale times a rotation (no shear, no reflection).
struct ScanTransform {
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  Similarity3 similarity;
};
ScanTransform read_scan_transform(const std::filesystem::path& file);

}  // namespace strata
