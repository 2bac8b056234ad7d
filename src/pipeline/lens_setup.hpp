#pragma once
// How the alignment starts each camera group: which lens model (from the lens, or as
// the user says), and, for photos without a focal length in their EXIF, which focal
// prior (a default, then a few others when the first attempt fails). Policy only:
// the models themselves are in geometry/camera.hpp, the estimation in sfm/.
// See docs/cameras.md.
#include "project/records.hpp"
#include "sfm/incremental.hpp"
#include "geometry/reconstruction.hpp"


#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace strata {

struct LensChoiceOptions {
  // "auto" (from the lens, below) or a model name: radial | brown | fisheye.
  std::string model = "auto";
  // millimetres, 35 mm-equivalent focal length (on the 36 mm width): below the first
  // the lens is taken as a fisheye, below the second as a wide rectilinear lens that
  // needs the full Brown model; from the second on the radial model (k1, k2) is
  // enough. docs/cameras.md gives the figures behind the two thresholds.
  double fisheye_below_35mm = 20.0;
  double brown_below_35mm = 28.0;

  // Throws InputError naming the field.
  void validate() const;
};

struct LensChoice {
  CameraModel model = CameraModel::radial;
  // option | lens_name (a fisheye word in the camera's make/model) | focal_35mm |
  // default (nothing known about the lens) | calibration (a known calibration's model)
  std::string source = "default";
  std::optional<double> focal_35mm;  // millimetres, what the choice was based on
  std::string reason;                // one line for the log and the report
};

// The 35 mm-equivalent focal length of a camera: EXIF FocalLengthIn35mmFilm, else
// the focal length in pixels over the image width x 36 mm.
std::optional<double> equivalent_focal_35mm(const CameraRecord& camera);

// The model for one camera (nullopt: nothing known about it, e.g. no EXIF).
LensChoice choose_lens_model(const LensChoiceOptions& options,
                             const std::optional<CameraRecord>& camera);

// Sets the group's lens model to the choice unless the group carries a known
// calibration (its own model wins, source "calibration").
void apply_lens_choice(CameraGroup& group, LensChoice& choice);

// ---- photos without EXIF focal length ------------------------------------------------

struct FocalSearchOptions {
  bool enabled = true;
  // Focal priors tried, in multiples of the long image side; the first is the default
  // (1.2: about 45 degrees across the long side, as COLMAP assumes). The others span
  // 0.8 (a wide lens, ~64 degrees) to 2.2 (a short telephoto, ~26 degrees).
  std::vector<double> factors = {1.2, 0.8, 1.6, 2.2};
  // The first attempt is accepted when at least this fraction of the photos is
  // registered and its reprojection RMSE is at most `max_rmse_px`; otherwise the
  // other priors are tried and the best attempt is kept (most photos, then lowest RMSE).
  double min_registered_fraction = 0.9;
  double max_rmse_px = 1.0;  // pixels

  void validate() const;
};

struct FocalAttempt {
  double factor = 0;            // prior = factor x long side
  std::vector<double> prior_px; // per group searched, pixels
  std::size_t registered = 0;
  double rmse_px = 0;           // pixels; infinity when the attempt failed
  std::vector<double> focal_px; // per group searched, after self-calibration
  std::string failure;          // why the attempt produced no model, empty otherwise
  bool chosen = false;
};

struct FocalSearchSummary {
  std::vector<int> groups;            // the groups without a focal prior (searched)
  std::vector<FocalAttempt> attempts; // in the order run
};

// Runs `reconstruct` (a wrapper of reconstruct_incremental) with the groups as
// given and, when some group has no focal prior (focal_from_exif false and no known
// calibration) and the result is poor by `options`, again with each other prior for
// those groups. Returns the best reconstruction and fills `summary` (its summary in
// `best_summary`). Rethrows the first attempt's ProcessingError when no attempt
// produced a model.
using ReconstructFunction =
    std::function<Reconstruction(const std::vector<CameraGroup>&, IncrementalSummary&)>;
Reconstruction reconstruct_with_focal_search(const FocalSearchOptions& options,
                                             const std::vector<CameraGroup>& groups,
                                             const ReconstructFunction& reconstruct,
                                             IncrementalSummary& best_summary,
                                             FocalSearchSummary& summary);

}  // namespace strata
