#pragma once
// Plain-language findings about one recorded layer: is it recorded well enough to
// dig away? Every rule compares a figure of the reconstruction with a named
// threshold and says what to do in the field. Std and Eigen only (testable on
// synthetic figures).
#include "report/coverage.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace strata {

struct QualityThresholds {
  // The field protocol asks for 30-60 photos; below 20 a layer rarely aligns whole.
  int min_photos = 20;
  // A point needs 3 views for a reliable dense surface (2 give no redundancy).
  int min_photos_per_area = 3;
  // A sector (1/9 of the trench) is reported when this share of it falls short;
  // smaller slivers are the natural thin rim at the trench edge.
  double min_shortfall_fraction = 0.10;
  // metres per pixel: half the 5 mm DTM cell, the coarsest GSD that still supports it.
  double max_gsd_m = 0.0025;
  // A marker needs 3 photos for a redundant position (2 rays always intersect).
  int min_marker_photos = 3;
  // A similarity in 3D needs 3 control markers; 4+ give a check on each other.
  int min_control_markers = 3;
  // metres, 3D RMSE: 1 cm is the usual tolerance of single-context plans at 1:20.
  double max_control_rmse_m = 0.010;
  double max_check_rmse_m = 0.010;
  // metres, 3D: a single marker this far off is most likely mis-surveyed or misnamed.
  double max_marker_residual_m = 0.020;
  // pixels: sharp photos of a well-solved block reproject within 1 px.
  double max_reprojection_rmse_px = 1.0;
  // Above this share of unaligned photos, parts of the trench may be missing.
  double max_unaligned_fraction = 0.10;
  // The survey's yardstick: a control or check RMSE, or one marker's residual, over
  // its fixed tolerance above is still accepted (as a warning) up to this multiple of
  // the error the survey and the photos explain (MarkerFigures::expected_m). Twice
  // covers a single marker's 3D error 99 % of the time for a Gaussian survey error
  // (1.94 sigma) and always for a rounded one (at most sqrt(3)/2 step per axis).
  double survey_allowance = 2.0;

  void validate() const;  // InputError naming the first invalid field
};

enum class Severity {
  problem,  // fix before the layer is dug away
  warning,  // worth fixing while it is still possible
  note,     // for the record
};
const char* to_string(Severity s);

struct Finding {
  Severity severity = Severity::note;
  std::string rule;     // stable identifier, e.g. "coverage_gap", "check_rmse"
  std::string message;  // what is wrong, with the figure and the threshold
  std::string advice;   // what to do about it, in the field's words
};

struct MarkerFigures {
  std::string name;
  std::string role;  // control|check|rejected
  bool triangulated = false;
  Eigen::Vector3d residual_m = Eigen::Vector3d::Zero();  // photogrammetric minus surveyed, E N Z
  double reprojection_px = 0;
  int images = 0;
  // metres, 3D, 1 sigma: the error this marker's survey (its stated sigma, the
  // rounding of its coordinates) and its photos (reprojection x GSD) explain. 0 when
  // nothing is known beyond strata's default weight: the fixed tolerances alone apply.
  double expected_m = 0;
};

// Every figure the rules look at; what a stage has not produced yet stays empty.
struct LayerFigures {
  std::string layer;
  int photos = 0;
  bool aligned = false;             // a sparse reconstruction exists
  int registered = 0;
  std::vector<std::string> unaligned;  // photo names
  bool georeferenced = false;
  std::string georeference_message;
  std::optional<double> reprojection_rmse_px;
  std::optional<double> control_rmse_m, check_rmse_m;  // 3D
  std::vector<MarkerFigures> markers;
  // The survey in the verdict's words, e.g. "a survey rounded to 0.1 m"; empty when
  // it says nothing beyond strata's defaults.
  std::string survey_words;
  bool dense = false, products = false;
  // Coverage (when cameras and a plan exist).
  bool coverage_known = false;
  std::vector<CoverageShortfall> gaps, low_resolution;
  std::vector<Eigen::Vector2d> camera_centres;  // site frame XY
  Eigen::Vector2d trench_centre = Eigen::Vector2d::Zero();
};

// Findings, most severe first.
std::vector<Finding> evaluate_layer(const LayerFigures& f, const QualityThresholds& t);

// One marker's expected 3D error (1 sigma, metres): per axis the larger of its stated
// sigma (zero when not stated) and the rounding of its coordinates, in quadrature with
// the photogrammetric term (reprojection error x GSD, metres).
double expected_marker_error_m(const Eigen::Vector3d& stated_sigma_m, double plan_rounding_sigma_m,
                               double height_rounding_sigma_m, double photo_sigma_m);

// metres, 3D: the largest residual of `m` that is no sign of a wrong marker, the fixed
// tolerance or what its survey explains times the allowance, whichever is larger.
double allowed_marker_residual_m(const MarkerFigures& m, const QualityThresholds& t);

// Millimetres, rounded for reading at the trench edge: "14 mm", "2.5 mm".
std::string format_mm(double metres);

}  // namespace strata
