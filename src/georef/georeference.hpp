#pragma once
// Georeferencing a layer's reconstruction onto surveyed markers, the way a surveyor
// adjusts a photo block on ground control:
//  1. fit every marker from its rays robustly (marker_rays.hpp): the point, the marker's
//     own dispersion in object space (an object clicked from every side scatters), and
//     which observations agree; those that do not are named and left out, and two
//     markers clicked at the same pixel of one photo are resolved by their other photos;
//  2. a marker is usable from >= 2 agreeing rays wide enough apart; its observations
//     are weighed by what each photo can achieve on it (click precision and dispersion);
//  3. a robust similarity from >= 3 non-collinear control markers: a consensus over
//     marker triples (>= 4 markers), then a fit weighted by the survey sigmas per axis;
//     a marker surveyed in plan only (height sigma >= horizontal_only_sigma_m) is
//     horizontal control;
//  4. apply it to cameras and points (site frame, metres);
//  5. a bundle adjustment in the site frame with the control markers as weighted
//     constraints (their sigma), so photo geometry and survey are fitted together;
//  6. residuals: each marker triangulated from the final cameras (photos only) minus
//     its surveyed position, per-observation pixel residuals, a leave-one-out
//     similarity residual per control marker and a survey-vs-photo distance misfit;
//     a control marker still inconsistent there is rejected and the adjustment redone.
// Check markers never enter 3 or 5. Every drop is named, with its size, in `blunders`.
#include "features/types.hpp"
#include "geometry/similarity.hpp"
#include "georef/marker_rays.hpp"
#include "sfm/bundle_adjustment.hpp"
#include "geometry/reconstruction.hpp"
#include "sfm/triangulation.hpp"

#include <cstddef>
#include <optional>
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
  // The limit also includes the photo precision of the marker: marker_sigma_px
  // times its ground size of a pixel (depth / focal), so a kite photo at 2 cm per pixel
  // is not held to a survey sigma of 1 cm.
  double outlier_threshold_m = 0.05;  // metres
  double outlier_sigma_factor = 5.0;  // unitless
  // The robust fit of each marker from its rays: agreement gate (sigma multiples),
  // widest-pair angle, dispersion limit. Its click_sigma_px is set from
  // bundle.marker_sigma_px (and the a posteriori estimate) by georeference().
  MarkerRayOptions rays;
  // Two different markers observed within this distance in one photo: one of them is
  // clicked on the other's target, pixels.
  double duplicate_px = 3.0;
  // Markers whose height sigma reaches this are horizontal control (surveyed in plan
  // only): their height enters only as a weak prior and never the height figures, metres.
  double horizontal_only_sigma_m = 1.0;
  // Height sigma the layer alignment gives markers of a survey without heights (every
  // height exactly 0.0), metres: large enough to let the photos decide the relief,
  // small enough to keep the block level on average.
  double unknown_height_sigma_m = 10.0;
  // Rounds of post-adjustment rejection (a control marker whose leave-one-out residual
  // exceeds its limit is rejected, the worst first, and the adjustment redone).
  int max_rejection_rounds = 2;
  // Refusal of photos that cannot carry this survey (another place, clicks made on other
  // photos; see refuse_foreign_photos in georeference.cpp and docs/georeference.md):
  // control markers that miss their survey by more than max_relative_misfit of their
  // spread, beyond their survey sigma, agreeing only through the scatter of their
  // clicks (unitless; real blocks fit to a few per cent: copr 5 %); or an adjustment
  // that raised the keypoint reprojection RMSE beyond max_bending_factor times that of
  // the free block and min_bent_rmse_px (pixels).
  double max_relative_misfit = 0.1;
  double max_bending_factor = 5.0;
  double min_bent_rmse_px = 2.0;
  // The adjustment in the site frame (robust loss, marker pixel sigma, intrinsics).
  BundleOptions bundle;
  // Weigh the photos by their measured precision instead of bundle.keypoint_sigma_px and
  // bundle.marker_sigma_px: after a first adjustment with those, the keypoint sigma
  // becomes the a posteriori sigma per axis of the keypoint residuals (sum |e|^2 over
  // 2 obs - 3 points - 6 cameras), the marker sigma that of the marker rays about their
  // intersections (sum e^2 / sum (2 n - 3)), never below the keypoint sigma nor
  // min_observation_sigma_px, and the block is adjusted again. Survey sigmas are then
  // weighed against what the photos really achieve (variance components, as a
  // surveyor's adjustment does), so a 3 mm survey does not bend a block that is good
  // to a fraction of a pixel. Costs a second adjustment.
  bool estimate_observation_sigmas = true;
  double min_observation_sigma_px = 0.1;  // pixels
  bool adjust = true;  // false: similarity only (a quick look)

  // Throws InputError naming the first invalid field.
  void validate() const;
};

enum class MarkerRole { control, check, rejected };  // rejected: control excluded as outlier
const char* to_string(MarkerRole role);

// One image observation of a marker after the adjustment.
struct ObservationResidual {
  int image = -1;              // index into rec.images
  std::string image_name;
  double to_rays_px = 0;       // pixels: to the marker triangulated from its kept rays
  double to_survey_px = 0;     // pixels: to the surveyed position (height from the photos
                               // when the marker is horizontal control); NaN if not seen
  double sigma_px = 0;         // pixels: what this photo was expected to achieve on it
  bool dropped = false;        // disagrees with the marker's other rays (see blunders)
};

struct MarkerResidual {
  std::string name;
  MarkerRole role = MarkerRole::control;
  bool height_known = true;    // false: horizontal control (height sigma large)
  bool triangulated = false;   // false: fewer than 2 usable rays or too small an angle
  double dE = 0, dN = 0, dZ = 0;  // metres: photo triangulation minus survey
  double reprojection_px = 0;  // RMS reprojection over the agreeing rays, pixels
  int images = 0;              // registered images whose observation agrees (kept)
  int observed = 0;            // registered images observing it (all observations)
  // The marker's own scatter about its point, metres (1 sigma per axis), and the same
  // in pixels of a typical photo of it (dispersion / mean ground size of a pixel).
  double dispersion_m = 0;
  double dispersion_px = 0;
  // Why its rays do not meet as one point, in words, when they do not (empty: fine).
  std::string diagnosis;
  // Leave-one-out (control and rejected markers): photo triangulation minus the
  // survey, through the similarity fitted on the other control markers, metres.
  bool loo = false;
  double loo_dE = 0, loo_dN = 0, loo_dZ = 0;
  // Median over the other triangulated markers of |photo distance - survey distance|
  // (plan distances when either height is unknown), metres; NaN without a partner.
  double distance_misfit_m = 0;
  std::vector<ObservationResidual> observations;
};

// Something dropped from the solution: an observation (image set) or a whole marker.
struct Blunder {
  std::string marker;
  std::string image;           // empty: the whole marker
  double amount = 0;           // pixels for an observation, metres for a marker
  std::string unit;            // "px" or "m"
  std::string reason;
};

struct AxisRmse {
  double e = 0, n = 0, z = 0;  // metres, per axis (east, north, height)
  double horizontal = 0;       // metres: sqrt(mean(dE^2 + dN^2))
  // metres, 3D: sqrt(e^2 + n^2 + z^2); the height over markers with a known height
  // only, so without any it equals `horizontal`.
  double xyz = 0;
  std::size_t markers = 0;     // markers that contributed
  std::size_t markers_z = 0;   // of which with a known height
};

struct GeoreferenceSummary {
  bool georeferenced = false;
  Similarity3 similarity;                   // reconstruction frame -> site frame
  std::vector<std::string> control_used;    // markers that drove the fit
  std::vector<std::string> rejected;        // control markers rejected as gross outliers
  std::vector<std::string> unusable;        // markers that could not be triangulated
  std::vector<Blunder> blunders;            // dropped observations and rejected markers
  AxisRmse control;                         // over control_used
  AxisRmse check;                           // over the check markers that triangulate
  AxisRmse leave_one_out;                   // over control_used, each left out in turn
  std::vector<MarkerResidual> residuals;    // one row per marker given
  BundleSummary bundle;
  double keypoint_sigma_px = 0;             // pixels, the sigmas the adjustment used
  double marker_sigma_px = 0;
  double seconds = 0;
  std::string message;
  // Findings about the block as a whole from the marker rays (e.g. residuals that grow
  // toward the photo edges: the lens model), each a sentence with what to do.
  std::vector<std::string> diagnosis;
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

// For a layer without markers: keeps the arbitrary frame's scale and heading but
// turns it so that "up" is +Z, taken from the cameras (up_from_cameras), sets
// rec.georeferenced = false and returns a summary saying so (the caller warns).
GeoreferenceSummary keep_arbitrary_frame(Reconstruction& rec);

// The frame's up direction (unit) from the registered cameras' optical axes, which
// look down at a trench; nullopt when they point every way.
std::optional<Eigen::Vector3d> up_from_cameras(const Reconstruction& rec);

// Applies a similarity to every registered camera and every point:
// X' = s R X + t, camera centre C' = S(C), rotation R_cam' = R_cam R^T, intrinsics kept.
void transform_reconstruction(const Similarity3& s, Reconstruction& rec);

}  // namespace strata
