#pragma once
// RGB-D depth sequences of a layer (schema 13, tables `depth_sequences` and
// `depth_frames`; docs/range.md, "Depth sequences"): the camera's intrinsics and
// noise, each frame's original PNG in media/, the pose the device recorded and the
// pose strata registered. Callers own the transaction.
#include "project/database.hpp"
#include "project/scan_records.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// Pinhole intrinsics of a depth camera (no distortion: depth frames come rectified).
struct DepthIntrinsics {
  int width = 0, height = 0;  // pixels
  double fx = 0, fy = 0;      // pixels
  double cx = 0, cy = 0;      // pixels; (0, 0) is the centre of the top-left pixel
};

struct DepthSequenceRecord {
  std::int64_t id = 0;
  std::int64_t layer_id = 0;
  std::string name;
  DepthIntrinsics intrinsics;
  double depth_scale_m = 0.001;  // metres per unit of the 16-bit PNG
  double noise_k = 0;            // 1/m: depth noise, one sigma = noise_k z^2 (z in metres)
  std::string intrinsics_file;
  std::optional<std::string> poses_file;
  std::string imported_at;       // ISO 8601 UTC; set by insert_depth_sequence
};

// How `strata register depth` placed a frame.
struct DepthFrameFit {
  std::string method;              // 'tracking' (frame to model) or 'loop-closure'
  double rms_m = 0;                // RMS point-to-plane residual of the inliers, metres
  double inlier_share = 0;         // 0..1 of the thinned frame's points
  double sigma_translation_m = 0;  // pose sigma, largest axis, metres (a lower bound)
  double sigma_rotation_rad = 0;   // pose sigma, largest axis, radians (a lower bound)
};

struct DepthFrameRecord {
  std::int64_t id = 0;
  std::int64_t sequence_id = 0;
  int frame = 0;                   // 0-based order in the sequence
  std::string name;
  std::string sha256;
  std::string media_path;          // relative to the project folder
  std::int64_t bytes = 0;
  std::int64_t valid_pixels = 0;
  std::optional<std::string> colour_name, colour_sha256, colour_media_path;
  std::optional<Eigen::Matrix4d> recorded_pose;  // camera -> site frame, from the device
  std::optional<Eigen::Matrix4d> pose;           // camera -> site frame, registered
  std::optional<DepthFrameFit> fit;
  std::optional<ScanBounds> bounds;              // site frame, when registered
};

std::int64_t insert_depth_sequence(Database& db, const DepthSequenceRecord& s);
std::int64_t insert_depth_frame(Database& db, const DepthFrameRecord& f);
void set_depth_frame_registered(Database& db, std::int64_t frame_id, const Eigen::Matrix4d& pose,
                                const ScanBounds& bounds, const DepthFrameFit& fit);
std::vector<DepthSequenceRecord> list_depth_sequences(Database& db, std::optional<std::int64_t> layer_id = std::nullopt);
std::vector<DepthFrameRecord> list_depth_frames(Database& db, std::int64_t sequence_id);  // in frame order
std::optional<DepthFrameRecord> find_depth_frame_by_sha(Database& db, const std::string& sha256);

}  // namespace strata
