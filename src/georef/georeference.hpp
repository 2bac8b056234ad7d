#pragma once
// Georeferencing a layer's reconstruction onto surveyed markers:
//  1. triangulate every marker from its image observations (>= 2 rays, angle check);
//  2. a robust similarity (Umeyama 1991) from >= 3 non-collinear control markers,
//     rejecting gross outliers by a consensus over marker triples when >= 4 are
//     available;
//  3. apply it to cameras and points (site frame, metres);
//  4. a bundle adjustment in the site frame with the control markers as weighted
//     constraints (their sigma), so photo geometry and survey are fitted together;
//  5. control and check residuals: each marker triangulated from the final cameras
//     (photos only) minus its surveyed position. Check markers never enter 2 or 4.
#include "features/types.hpp"
#include "geometry/similarity.hpp"
#include "sfm/bundle_adjustment.hpp"
#include "sfm/reconstruction.hpp"
#include "sfm/triangulation.hpp"

#include <cstddef>
#include <string>
#include <vector>

namespace strata {

struct GeoreferenceOptions {
  // Marker triangulation gates: degrees between rays, pixels of reprojection.
  // Looser than for keypoints because markers may be clicked by hand.
  TriangulationOptions triangulation{2.0, 10.0, true};
  // Smallest second/first singular value of the centred control set (unitless);
  // below it the markers are treated as collinear (see fit_similarity).
  double min_spread_ratio = 0.02;
  // Gross-outlier rejection (only with >= 4 usable control markers): a marker farther
  // than max(outlier_threshold_m, outlier_sigma_factor x |sigma|) from the best
  // consensus similarity of marker triples is excluded.
  double outlier_threshold_m = 0.05;  // metres
  double outlier_sigma_factor = 5.0;  // unitless
  // The adjustment in the site frame (robust loss, marker pixel sigma, intrinsics).
  BundleOptions bundle;
  bool adjust = true;  // false: similarity only (a quick look)

  // Throws InputError naming the first invalid field.
  void validate() const;
};

enum class MarkerRole { control, check, rejected };  // rejected: control excluded as outlier
const char* to_string(MarkerRole role);

struct MarkerResidual {
  std::string name;
  MarkerRole role = MarkerRole::control;
  bool triangulated = false;   // false: fewer than 2 usable rays or too small an angle
  double dE = 0, dN = 0, dZ = 0;  // metres: photo triangulation minus survey
  double reprojection_px = 0;  // RMS reprojection of the triangulated marker, pixels
  int images = 0;              // registered images observing it
};

struct AxisRmse {
  double e = 0, n = 0, z = 0;  // metres, per axis (east, north, height)
  double xyz = 0;              // metres, 3D: sqrt(mean(dE^2 + dN^2 + dZ^2))
  std::size_t markers = 0;     // markers that contributed
};

struct GeoreferenceSummary {
  bool georeferenced = false;
  Similarity3 similarity;                   // reconstruction frame -> site frame
  std::vector<std::string> control_used;    // markers that drove the fit
  std::vector<std::string> rejected;        // control markers rejected as gross outliers
  std::vector<std::string> unusable;        // markers that could not be triangulated
  AxisRmse control;                         // over control_used
  AxisRmse check;                           // over the check markers that triangulate
  std::vector<MarkerResidual> residuals;    // one row per marker given
  BundleSummary bundle;
  double seconds = 0;
  std::string message;
};

// Georeferences `rec` in place (cameras and points move to the site frame, intrinsics
// are refined by the adjustment) and sets rec.georeferenced. `keypoints[i]` belongs
// to rec.images[i] (needed by the adjustment). Observations of unknown markers or
// unregistered images are ignored.
// Throws InputError, naming the markers, when fewer than 3 control markers can be
// triangulated or when they are (nearly) collinear; rec is unchanged then.
GeoreferenceSummary georeference(const GeoreferenceOptions& options,
                                 const std::vector<MarkerConstraint>& markers,
                                 const std::vector<MarkerObservation>& observations,
                                 const std::vector<ImageKeypoints>& keypoints,
                                 Reconstruction& rec);

// For a layer without markers: leaves the arbitrary frame as it is, sets
// rec.georeferenced = false and returns a summary saying so (the caller warns).
GeoreferenceSummary keep_arbitrary_frame(Reconstruction& rec);

// Applies a similarity to every registered camera and every point:
// X' = s R X + t, camera centre C' = S(C), rotation R_cam' = R_cam R^T, intrinsics kept.
void transform_reconstruction(const Similarity3& s, Reconstruction& rec);

}  // namespace strata
