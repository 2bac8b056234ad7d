#pragma once
// Guided marker observations ('strata markers guide'): a non-coded marker (a cross,
// a chequered quadrant, a disc) clicked by hand in a few photos is found in every
// other photo of the layer that sees it.
//
// Per marker:
//  1. triangulate it from its clicks with the layer's cameras (sfm/triangulation);
//  2. the local ground: a plane fitted (PCA) to the sparse points near it, or the
//     horizontal of the site frame when too few points lie there;
//  3. refine each click to the marker's centre of point symmetry (below);
//  4. predict the marker in every registered photo whose view contains it and faces
//     the ground (angle to the normal below max_view_angle_deg);
//  5. take the clicked appearance from the click whose view is closest in direction,
//     map it and the target photo onto the ground plane (each photo to the plane is a
//     plane-induced homography, so photo to photo is one too: Hartley & Zisserman 2004,
//     sec. 13.1), and find it by normalised cross-correlation (cv::matchTemplate,
//     TM_CCOEFF_NORMED) in a search window, the peak to sub-pixel by a parabola through
//     it and its neighbours along each axis;
//  6. refine the match to the centre of point symmetry, as for the clicks;
//  7. triangulate the marker from every refined position, dropping the worst one while
//     it reprojects farther than gate_px; those left in photos without a click are the
//     guided observations.
//
// Why point symmetry: template matching only finds the same physical point as the
// template's centre, i.e. the click's error (2 px and more) would be copied into every
// photo. The markers in use (crosses, chequered quadrants, discs, rings) are symmetric
// about their centre under a half turn, and an affine map (a small patch of a plane
// seen in perspective) preserves that symmetry and its centre. So the centre is where
// the patch best matches its own half-turn: correlating the patch (sampled on the
// plane) with its 180-degree rotation peaks at twice the offset of the centre.
// Markers that are not point-symmetric: set centre_on_symmetry = false (the guided
// positions then follow the clicked appearance, clicks' errors included).
#include "geometry/camera.hpp"
#include "sfm/triangulation.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct MarkerGuideOptions {
  // metres: printed width of the markers; sets the patch on the ground (the print,
  // plus 10 % of context each side) and the symmetry window (70 % of it).
  double marker_size_m = 0.15;
  // Normalised cross-correlation of the clicked appearance in the photo (-1..1): a
  // match below it is not the marker (occluded, blurred, another object).
  double min_score = 0.7;
  // Normalised cross-correlation of the patch with its half-turn (-1..1): below it
  // the centre of symmetry is not defined there.
  double min_symmetry = 0.6;
  // pixels: how far from its prediction the marker is sought (the prediction is off
  // by about the clicks' errors).
  int search_px = 12;
  // pixels: a kept observation reprojects within this of the marker triangulated from
  // all kept ones (the cameras' own reprojection error is a few tenths).
  double gate_px = 1.5;
  // pixels: a click farther than this from where the other rays meet is named.
  double far_click_px = 5.0;
  // degrees between the ground normal and the view: beyond it the print is too
  // foreshortened to be found reliably.
  double max_view_angle_deg = 75.0;
  // metres and count: sparse points within this radius of the marker define its plane.
  double plane_radius_m = 0.3;
  int min_plane_points = 10;
  // Refine to the centre of point symmetry (see the header comment).
  bool centre_on_symmetry = true;

  // Throws InputError naming the first invalid field.
  void validate() const;
};

// A registered photo of the layer.
struct GuidePhoto {
  std::string name;
  std::filesystem::path path;  // the original photo
  Camera camera;               // site frame
};

struct GuideClick {
  int photo = -1;                                // index into GuideInput::photos
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // original photo pixels
};

struct GuideMarker {
  std::string name;
  std::vector<GuideClick> clicks;  // >= 2, in different photos
  std::vector<int> detected_in;    // photos where a coded target of it was detected: not guided there
};

struct GuideInput {
  std::vector<GuidePhoto> photos;
  std::vector<Eigen::Vector3d> sparse_points;  // metres, site frame
  std::vector<GuideMarker> markers;
};

struct GuidedObservation {
  int photo = -1;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  double score = 0;        // NCC of the clicked appearance
  double symmetry = 0;     // NCC with its half-turn (0 when not refined)
  double residual_px = 0;  // to the final triangulation
};

struct RefinedClick {
  int photo = -1;
  Eigen::Vector2d clicked = Eigen::Vector2d::Zero();
  Eigen::Vector2d refined = Eigen::Vector2d::Zero();  // = clicked when not refined
  bool refined_ok = false;
  double moved_px = 0;      // |refined - clicked|
  double symmetry = 0;
  // pixels: the click to the marker triangulated from every other kept observation;
  // NaN when fewer than 2 others are left.
  double to_rays_px = 0;
  bool far = false;         // to_rays_px > far_click_px
};

struct GuideRejection {
  int photo = -1;
  std::string reason;  // "no match", "not symmetric", "disagrees with the rays", "at the image edge"
  double value = 0;    // the score or the pixels behind the reason
};

struct MarkerGuideResult {
  std::string name;
  bool triangulated = false;
  std::string message;              // why not, when not triangulated
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // metres, site frame, from all kept observations
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // ground normal used
  int plane_points = 0;             // sparse points behind the normal (0: the site's vertical)
  int predicted = 0;                // photos (without a click) where it was sought
  double rmse_px = 0;               // of the kept observations about `position`
  std::vector<GuidedObservation> added;
  std::vector<RefinedClick> clicks;
  std::vector<GuideRejection> rejected;
};

struct MarkerGuideSummary {
  std::vector<MarkerGuideResult> markers;
  int added = 0;
  double seconds = 0;
};

// Throws InputError for invalid options or a marker with fewer than 2 clicks, IoError
// when a photo cannot be read.
MarkerGuideSummary guide_markers(const MarkerGuideOptions& options, const GuideInput& input);

}  // namespace strata
