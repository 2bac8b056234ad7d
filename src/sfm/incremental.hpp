#pragma once
// Incremental structure from motion (Snavely et al. 2006 "Photo tourism";
// Schoenberger & Frahm 2016 "Structure-from-motion revisited"): tracks from verified
// pairwise matches, a well-conditioned initial pair, then one image at a time by
// robust resection, triangulation, outlier filtering and bundle adjustment with
// self-calibration of each camera group.
#include "features/types.hpp"
#include "sfm/bundle_adjustment.hpp"
#include "geometry/reconstruction.hpp"

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace strata {

struct IncrementalOptions {
  // --- initial pair -------------------------------------------------------------
  int init_min_inliers = 50;               // essential-matrix inliers of the pair
  double init_min_angle_deg = 4.0;         // degrees: median triangulation angle of the pair
  // H inliers / E inliers above this mean the pair is explained by a homography
  // (pure rotation or a flat scene at small baseline): its depth is unreliable.
  double init_max_homography_ratio = 0.8;
  // degrees: from this median triangulation angle on, a pair is well conditioned
  // whatever its homography ratio (a flat surface seen with real parallax).
  double init_planar_min_angle_deg = 8.0;
  int init_max_candidates = 40;            // pairs examined, by decreasing match count

  // --- robust estimation --------------------------------------------------------
  // pixels: RANSAC inlier threshold for the essential matrix, homography and PnP.
  // Generous, because the lens distortion is unknown until the first adjustments.
  double ransac_threshold_px = 4.0;
  double ransac_confidence = 0.9999;       // probability of drawing one clean sample
  int ransac_max_iterations = 2000;

  // --- resection ----------------------------------------------------------------
  int resection_min_inliers = 15;          // 2D-3D inliers to accept a new image
  double resection_min_inlier_ratio = 0.2; // inliers / candidate correspondences

  // --- retry of photos left out -------------------------------------------------
  // When the model stops growing (no photo passes the resection above, even after a
  // global adjustment), each photo still out is tried once more per model size with
  // a relaxed inlier count. Such a photo typically overlaps mostly one or two
  // registered photos: its matches are two-view tracks without a 3D point, so it
  // sees too few triangulated points, however many verified matches it has. The
  // few-point pose is accepted only when it also explains those verified matches
  // with registered photos (Sampson distance to the epipolar geometry the poses
  // imply, Hartley & Zisserman sec. 11.4.3): many observations, independent of the
  // points it was computed from. A retried photo is followed by a global adjustment.
  bool retry_unregistered = true;
  int retry_min_inliers = 6;                // 2D-3D inliers (a pose has 6 unknowns)
  double retry_min_inlier_ratio = 0.5;      // inliers / candidate correspondences
  int retry_min_pair_matches = 60;          // verified matches with registered photos
  // fraction of those matches within ransac_threshold_px of their epipolar lines
  double retry_min_pair_agreement = 0.8;

  // --- triangulation and filtering ----------------------------------------------
  double min_triangulation_angle_deg = 1.5;  // degrees: largest ray angle of a point
  double max_reprojection_px = 4.0;          // pixels: observations beyond are outliers
  // pixels: the same, applied after the final global adjustment (the model is
  // calibrated then, so the gate can be tighter).
  double final_max_reprojection_px = 2.0;

  // --- bundle adjustment --------------------------------------------------------
  BundleOptions bundle;  // robust loss, tolerances, which intrinsics to refine
  int local_ba_images = 6;        // the new image and its best connected neighbours
  // Observations in a local adjustment, at most (0 = no bound). In a compact layer
  // every photo sees a large part of the scene, so the points of six images are
  // most of the model; the bound keeps the points seen by the new image and by the
  // most variable images (those that tie the poses together) and leaves the rest
  // to the next global adjustment.
  int local_ba_max_observations = 8000;
  // Observations in an intermediate global adjustment (while photos are still being
  // added), at most (0 = no bound). Such an adjustment only keeps the poses on track for
  // the next resections, and in a compact layer a few hundred well-spread points per
  // photo pin a pose as well as thousands do: the bound keeps the longest tracks until
  // every photo has its share (budget / registered photos) and re-triangulates the
  // points it left out from the adjusted poses. The final adjustments take every point.
  int global_ba_max_observations = 40000;
  // A global adjustment runs when the registered count has grown by this factor
  // since the last one (and for every image while fewer than `early_global_images`).
  double global_ba_growth = 1.25;
  int early_global_images = 8;
  // Intrinsics stay fixed until this many images are registered (a two-view
  // geometry cannot separate focal length from depth).
  int calibration_min_images = 3;
  // The principal point is refined only from this many images on (it trades off
  // against camera tilt and needs varied viewing directions).
  int principal_point_min_images = 6;
  // The higher lens terms (k3, k4 and the tangential p1, p2 of the brown and fisheye
  // models) join only from this many images on: with few, overlapping views they
  // trade off against focal, k1 and the poses and an early adjustment can run away
  // with them (COLMAP likewise refines extra parameters only in global adjustments).
  // The radial model's f, k1, k2 keep their earlier staging.
  int higher_order_min_images = 10;
  // Local and intermediate global adjustments only need to keep the model on track
  // for the next resections: they stop earlier than the final ones (which use
  // `bundle` as given).
  int intermediate_ba_max_iterations = 30;
  double intermediate_ba_function_tolerance = 1e-6;  // relative cost change
  // Global BA / filter / retriangulate rounds at the end, >= 1; the last filters with
  // final_max_reprojection_px, the others with max_reprojection_px. One is enough when
  // the intermediate adjustments kept the model close (a second moved no check-marker
  // figure on the full-size example, docs/performance.md).
  int final_refinement_passes = 1;
  // Relative cost change at which the last adjustment stops (the larger of this and
  // bundle.function_tolerance). Past 1e-6 the Cauchy-weighted cost creeps down for
  // dozens of iterations that move no camera by a measurable amount, and a layer with
  // markers is adjusted again with them (georeference) from this state.
  double final_ba_function_tolerance = 1e-6;

  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct IncrementalSummary {
  std::size_t images = 0;
  std::size_t registered = 0;
  std::pair<int, int> initial_pair{-1, -1};
  std::size_t tracks = 0;
  std::size_t inconsistent_tracks = 0;   // match components with two keypoints of one image
  std::size_t repaired_tracks = 0;       // tracks recovered from them (see build_tracks)
  std::size_t points = 0;
  std::size_t observations = 0;          // in the final points' tracks
  double reprojection_rmse_px = 0;
  int local_adjustments = 0;
  int global_adjustments = 0;
  int bounded_adjustments = 0;           // global ones on a subset of the points (global_ba_max_observations)
  std::size_t filtered_observations = 0; // outlier observations removed over the run
  std::size_t registered_on_retry = 0;   // photos placed by the relaxed retry
  std::vector<std::string> unregistered; // image names that could not be placed
  double initial_pair_seconds = 0;       // choosing the initial pair
  double adjustment_seconds = 0;         // all bundle adjustments
  double seconds = 0;                    // total
};

// Reconstructs one layer. `groups` hold the initial intrinsics (a group with fx <= 0
// gets the default prior f = 1.2 x long side, principal point at the centre);
// `keypoints[i]` belongs to `images[i]`; `matches` are verified pairwise inliers.
// The result is in an arbitrary frame (georeferenced = false): the first image of the
// initial pair at the origin, the baseline to the second of about unit length.
// Throws ProcessingError when no initial pair can be found; Cancelled on request.
Reconstruction reconstruct_incremental(const IncrementalOptions& options,
                                       const std::vector<CameraGroup>& groups,
                                       const std::vector<ImageInput>& images,
                                       const std::vector<ImageKeypoints>& keypoints,
                                       const std::vector<PairMatches>& matches,
                                       IncrementalSummary* summary = nullptr);

}  // namespace strata
