#pragma once
// The registration controller (docs/range.md, "Registration"): a layer's unregistered
// range scans placed in the site frame, either on surveyed targets that the scanner
// measured (a robust similarity, geometry/similarity.hpp), or by a coarse yaw search
// and robust point-to-plane ICP (geometry/icp.hpp) against a photogrammetric surface:
// the layer's own (products/<layer>/dense/points.ply) or the previous layer's, whose
// ground outside the trench has not changed. Every scan is fitted and checked before
// anything is written; then all are stored in one transaction, or none.
#include "geometry/icp.hpp"
#include "geometry/similarity.hpp"
#include "pipeline/marker_fit.hpp"
#include "project/project.hpp"
#include "project/scan_records.hpp"

#include <filesystem>
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

// The photogrammetric surface a cloud is fitted to: the dense points of a layer
// (products/<layer>/dense/points.ply), site frame, thinned to surface_voxel_m, and the
// same with normals.
struct ReferenceSurface {
  std::string layer;                      // whose surface
  std::size_t raw_points = 0;             // in the file
  std::vector<Eigen::Vector3d> points;    // thinned (the coarse search's target)
  OrientedPoints oriented;                // thinned, with normals (the ICP's target)
};

// The file holding the surface a layer's clouds are fitted to (the layer's own, or
// the previous layer's), whether or not it exists yet. Throws InputError when there
// is no previous layer.
std::filesystem::path reference_surface_file(Project& project, const std::string& layer,
                                             RegistrationReference against);

// The surface of `layer` (against layer) or of the layer added before it (against
// previous). Throws InputError naming what to run when there is none.
ReferenceSurface load_reference_surface(Project& project, const std::string& layer, RegistrationReference against,
                                        const ScanRegistrationOptions& options);

struct SurfaceFit {
  CoarseResult coarse;
  IcpSummary icp;  // icp.pose: the cloud's frame -> site frame
};

// A levelled cloud (its z axis nearly the site's; metres, thinned to scan_voxel_m)
// placed on the surface: the coarse yaw search, then robust point-to-plane ICP.
SurfaceFit fit_to_surface(const std::vector<Eigen::Vector3d>& cloud, const ReferenceSurface& surface,
                          const ScanRegistrationOptions& options);

// Why a fit to the surface cannot be trusted (overlap, degenerate geometry,
// convergence, RMS against sqrt(sigma_m^2 + surface_sigma_m^2)), or empty. sigma_m:
// the cloud's own noise, metres.
std::string surface_fit_refusal(double sigma_m, const IcpSummary& fit, const ScanRegistrationOptions& options);

// Registration on targets: the scanner's own measurements of surveyed markers (sphere
// or checkerboard centres, named like the markers), read by importers/scans/scan_targets.
struct TargetRegistrationOptions {
  std::string scan;                 // the scan, by file name (required)
  std::filesystem::path targets;    // name,x,y,z in metres, scanner frame
  double target_sigma_m = 0.002;    // metres: a target centre as the scanner's software finds it
  // A pair is an inlier within gate_sigmas x sqrt(target sigma^2 + the largest marker
  // sigma^2 of the pairs), and never less than min_gate_m.
  double gate_sigmas = 3.0;
  double min_gate_m = 0.005;
  // A scanner measures in metres to about 1e-4; a fitted scale further from 1 than
  // this means other units or mismatched names.
  double max_scale_error = 0.005;
  void validate() const;  // throws InputError naming the field
};

struct TargetRegistrationResult {
  ScanRecord scan;                                     // as stored after the registration
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  // scanner frame -> site frame
  double scale = 1;                                    // of the robust similarity: a check; the pose is rigid
  double gate_m = 0;
  double rms_m = 0;                                    // over the inliers
  std::size_t inliers = 0;
  std::vector<TargetResidual> targets;                 // every target matched to a marker, file order
  std::vector<std::string> unmatched;                  // targets with no surveyed marker of that name
  // First-order pose sigmas from the inliers' RMS: translation rms / sqrt(n) at their
  // centroid, rotation rms / sqrt(sum of squared distances to it).
  double sigma_translation_m = 0;
  double sigma_rotation_rad = 0;
  double seconds = 0;
};

// Registers one scan of the layer on its targets and stores it as 'transform' with the
// fit (registered_by 'targets'). Throws InputError, the database unchanged, when the
// scan is unknown or was registered by its file's own CRS or transform, fewer than 3
// targets name a surveyed marker, no 3 of them agree, or the scale is off.
TargetRegistrationResult register_scan_on_targets(Project& project, const std::string& layer,
                                                  const TargetRegistrationOptions& options);

}  // namespace strata
