#pragma once
// Range scans of a layer (schema 10, table `scans`): the original point cloud file in
// media/, what it holds, its instrument noise and how it is registered to the site.
// Callers own the transaction.
#include "project/database.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// How a scan's coordinates relate to the site frame.
enum class ScanRegistration {
  survey,        // already in a CRS (the scanner software registered it to the survey)
  transform,     // a similarity into the site frame was given
  unregistered,  // its own frame: not usable with the layer until registered
};
const char* to_string(ScanRegistration r);
ScanRegistration parse_scan_registration(const std::string& text);  // throws IoError on an unknown word

struct ScanBounds {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();  // metres, site frame
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

// How strata itself registered a scan (schema 11; docs/range.md, "Registration").
struct ScanFit {
  std::string method;            // 'icp-layer' (its layer's photo surface), 'icp-previous' or 'targets'
  std::string against;           // the layer whose surface was the reference, or the target file's name
  double rms_m = 0;              // RMS residual of the inliers (point to plane, or target), metres
  double inlier_share = 0;       // 0..1, of the thinned scan's points or of the matched targets
  double sigma_translation_m = 0;  // pose sigma, largest axis, metres
  double sigma_rotation_rad = 0;   // pose sigma, largest axis, radians
};

struct ScanRecord {
  std::int64_t id = 0;
  std::int64_t layer_id = 0;
  std::string name;        // original file name
  std::string sha256;
  std::string media_path;  // relative to the project folder
  std::int64_t bytes = 0;
  std::string format;      // as the reader describes it, e.g. "las 1.2 point format 3"
  std::int64_t points = 0;
  bool has_colour = false, has_intensity = false, has_normals = false;
  double sigma_m = 0.0;    // range noise, one sigma, metres
  ScanRegistration registration = ScanRegistration::unregistered;
  std::optional<std::string> crs;              // registration survey
  std::optional<Eigen::Matrix4d> transform;    // registration transform: scanner -> site frame
  std::optional<ScanBounds> bounds;            // registered scans
  std::optional<ScanFit> fit;                  // registered by `strata register scan`
  std::string imported_at;                     // ISO 8601 UTC; set by insert_scan
};

std::int64_t insert_scan(Database& db, const ScanRecord& s);
// An unregistered scan becomes 'transform' with the pose and box strata found, and how.
void set_scan_registered(Database& db, std::int64_t scan_id, const Eigen::Matrix4d& transform,
                         const ScanBounds& bounds, const ScanFit& fit);
std::optional<ScanRecord> find_scan_by_sha(Database& db, const std::string& sha256);
std::vector<ScanRecord> list_scans(Database& db, std::optional<std::int64_t> layer_id = std::nullopt);  // by id

}  // namespace strata
