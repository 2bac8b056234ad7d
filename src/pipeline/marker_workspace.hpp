#pragma once
// The field station's marker workspace: what it shows of a layer's markers (each marker's
// observations by status, its residuals, the photos that see it with the position the
// alignment predicts there) and the edits a person makes in it (a click, a confirmation,
// a rejection). The clicks are the same 'clicked' observations an imported gcp_list
// gives, so `strata process` and `strata markers guide` use them as they are.
// Orchestration and records only: the prediction is the camera model's projection.
#include "georef/georeference.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace strata {

// What a person sees of a marker in one photo.
enum class ObservationStatus {
  none,       // nothing there
  clicked,    // placed by a person (clicked in the workspace, or imported)
  confirmed,  // strata's position (guided or detected) that a person confirmed
  predicted,  // found by the guide from the clicks, not yet reviewed
  detected,   // a coded target, not yet reviewed
  rejected,   // strata's position that a person rejected: not used
};
const char* to_string(ObservationStatus s);

struct StatusCounts {
  int clicked = 0, confirmed = 0, predicted = 0, detected = 0, rejected = 0;
};

struct WorkspaceMarker {
  MarkerRecord marker;
  StatusCounts counts;
  std::optional<MarkerResidual> residual;  // from the layer's last alignment
};

struct MarkerOverview {
  std::string layer;
  bool aligned = false;
  bool georeferenced = false;
  std::optional<AxisRmse> control_rmse, check_rmse;  // of the last alignment
  std::vector<WorkspaceMarker> markers;
};

// Every surveyed marker of the project, in a layer. InputError for an unknown layer.
MarkerOverview marker_overview(Project& project, const std::string& layer);

struct MarkerPhoto {
  std::string name;
  int width = 0, height = 0;  // pixels
  bool registered = false;    // the alignment placed the photo
  // The surveyed marker projects inside the photo, in front of it (georeferenced only).
  bool sees = false;
  std::optional<Eigen::Vector2d> predicted;  // pixels: the survey through the photo's camera
  std::optional<Eigen::Vector2d> pixel;      // pixels: the observation (or the rejected position)
  std::string source;                        // of the observation: clicked, guided, detected
  ObservationStatus status = ObservationStatus::none;
  std::optional<double> residual_px;  // to the survey, from the last alignment
};

struct MarkerPhotos {
  MarkerRecord marker;
  std::vector<MarkerPhoto> photos;  // those with an observation, then those that see it, then the rest
};

// The photos of `layer` for `marker`. InputError naming an unknown layer or marker.
MarkerPhotos marker_photos(Project& project, const std::string& layer, const std::string& marker);

// A person places `marker` at `pixel` (full-image pixels, (0, 0) the centre of the
// top-left pixel) in `photo` of `layer`: a clicked observation there, replacing an
// earlier click and withdrawing a review. FieldError (photo, x, y) for a photo not in
// the layer or a pixel outside it. One transaction; the caller holds the project lock.
MarkerPhoto click_marker(Project& project, const std::string& layer, const std::string& marker,
                         const std::string& photo, const Eigen::Vector2d& pixel);

enum class ReviewVerdict { confirmed, rejected, cleared };
ReviewVerdict parse_review_verdict(const std::string& text);  // FieldError "verdict"

// A person's verdict on the marker in a photo: confirmed (a guided position becomes a
// click there; a detection is kept), rejected (a guided or detected position is not used
// and not made again), cleared (the person's click, confirmation or rejection there is
// withdrawn). FieldError naming what there is not to review. One transaction.
MarkerPhoto review_observation(Project& project, const std::string& layer, const std::string& marker,
                               const std::string& photo, ReviewVerdict verdict);

}  // namespace strata
