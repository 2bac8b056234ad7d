#pragma once
// The registration controller (docs/range.md, "Registration"): a layer's unregistered
// range scans placed in the site frame by a coarse yaw search and robust
// point-to-plane ICP (geometry/icp.hpp) against a photogrammetric surface: the
// layer's own (products/<layer>/dense/points.ply) or the previous layer's, whose
// ground outside the trench has not changed. Every scan is fitted and checked before
// anything is written; then all are stored in one transaction, or none.
#include "geometry/icp.hpp"
#include "project/project.hpp"
#include "project/scan_records.hpp"

#include <optional>
#include <string>
#include <vector>

namespace strata {

enum class RegistrationReference { layer, previous };

struct ScanRegistrationOptions {
  RegistrationReference against = RegistrationReference::layer;
  std::optional<std::string> scan;  // one scan by file name; default every unregistered scan of the layer
  double scan_voxel_m = 0.015;      // metres: the scan thinned to one point a cube (1-2 cm: even density)
  double surface_voxel_m = 0.01;    // metres: the reference surface thinned likewise
  double normal_radius_m = 0.03;    // metres: neighbours of a surface normal (3 surface voxels)
  // Refusals: the share of the thinned scan within the final gate of the surface
  // (below it the overlap is too small to trust), and the inliers' RMS over the
  // noise expected of a good fit: sqrt(scan sigma^2 + surface_sigma_m^2).
  double min_inlier_share = 0.30;
  double max_rms_ratio = 3.0;
  double surface_sigma_m = 0.004;   // metres: the photo surface's own noise (its DTM: ~1 mm median, p95 ~1 cm)
  IcpOptions icp;
  CoarseOptions coarse;
  void validate() const;  // throws InputError naming the field
};

struct ScanRegistrationResult {
  ScanRecord scan;               // as stored after the registration
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  // scanner frame -> site frame
  IcpSummary icp;
  CoarseResult coarse;
  std::size_t points_used = 0;   // the thinned scan
  std::size_t surface_points = 0;
  double seconds = 0;
};

struct LayerRegistrationSummary {
  std::string layer;
  std::string reference_layer;   // whose surface the scans were fitted to
  std::vector<ScanRegistrationResult> scans;
};

// Registers the layer's unregistered scans (or options.scan) and stores each as
// 'transform' with its fit. Throws InputError, the database unchanged, when the layer
// has no scan to register, the reference surface is missing, or any scan cannot be
// registered (too little overlap, no convergence, a degenerate surface, residuals far
// above its noise): the message names the scan, which check failed and what to do.
LayerRegistrationSummary register_layer_scans(Project& project, const std::string& layer,
                                              const ScanRegistrationOptions& options);

}  // namespace strata
