#pragma once
// What each stage of a layer hands on: plain structs, units in the names. The
// stages fill them, the command line prints them and the report reads them; JSON
// exists only where strata writes them for a user or into the database's quality
// columns, in one place (pipeline/stage_json.hpp).
#include "dense/dense.hpp"
#include "georef/georeference.hpp"
#include "georef/survey.hpp"
#include "pipeline/camera_calibration.hpp"
#include "pipeline/lens_setup.hpp"
#include "products/ortho_markers.hpp"
#include "sfm/quality.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strata {

// One solved camera of the layer: its intrinsics, and where its lens model and
// starting values came from.
struct CameraFigures {
  std::optional<std::int64_t> camera_id;  // the project's camera row
  Intrinsics intrinsics;                  // as solved; the model's own coefficients only
  LensChoice lens;                        // why this lens model
  std::string focal_source;               // calibration | exif | default
  std::string calibration_source;
  bool calibration_fixed = false;
};

struct PairCounts {
  std::size_t selected = 0;
  std::size_t verified = 0;   // geometrically verified
  bool exhaustive = false;    // every pair was tried
};

struct AlignmentTimings {
  double features_s = 0;
  double matching_s = 0;
  std::optional<double> targets_s;  // when coded targets were looked for
  double sfm_s = 0;
  double georeference_s = 0;
  double total_s = 0;
};

// The sparse stage's figures: alignment, lens, georeference and its markers.
struct AlignmentQuality {
  std::string layer;
  std::size_t images_total = 0;
  ReconstructionQuality sparse;            // registered images, points, tracks, RMSE, GSD
  std::vector<std::string> unregistered;   // photos that could not be placed
  std::vector<CameraFigures> cameras;      // per camera group
  std::optional<FocalSearchSummary> focal_search;  // photos without an EXIF focal length
  bool georeferenced = false;
  AxisRmse control_rmse;
  AxisRmse check_rmse;
  AxisRmse leave_one_out_rmse;
  std::vector<std::string> rejected_markers;
  std::vector<std::string> unusable_markers;
  std::vector<Blunder> blunders;
  double keypoint_sigma_px = 0;            // the observation sigmas the adjustment used
  double marker_sigma_px = 0;
  std::size_t detected_observations = 0;   // coded targets found in the photos
  PairCounts pairs;
  std::vector<MarkerResidual> markers;     // one row per marker seen
  std::string georeference_message;        // empty: none
  std::vector<std::string> georeference_diagnosis;
  std::vector<CalibrationCheck> calibration_check;  // self-calibration against the priors
  SurveyAssessment survey;
  AlignmentTimings timings;
  double peak_memory_mb = 0;

  // The RMSE a user quotes: over the check markers when there are any (independent
  // of the fit), else over the control markers; nullptr when neither has any.
  const AxisRmse* quoted_rmse() const;
};

// The dense stage's figures: what run_dense measured (its StepFigures: time and
// peak memory per step), and what the layer gave it.
struct DenseQuality {
  std::string layer;
  bool photos = true;                           // false: range scans alone
  std::vector<std::string> scans_unregistered;  // not fused
  DenseSummary figures;                         // its product files are recorded, not part of the quality
};

struct DtmSigmaFigures {
  std::string path;      // relative to the project folder
  double median_m = 0;   // metres, one sigma, over the cells with a sigma
  double p95_m = 0;
};

struct DtmFigures {
  std::string path;      // relative to the project folder
  double cell_m = 0;
  int width = 0;
  int height = 0;
  std::size_t valid_cells = 0;
  double area_m2 = 0;
  double min_m = 0;      // absolute heights
  double max_m = 0;
  double mean_m = 0;
  double median_distance_sparse_m = 0;   // |DTM - sparse point|, an independent check
  std::size_t sparse_points_compared = 0;
  std::optional<DtmSigmaFigures> sigma;  // when the surface carried one
};

struct OrthoFigures {
  std::string path;
  double cell_m = 0;
  int views = 0;          // photos given
  int views_used = 0;     // photos that colour at least one cell
  double coverage = 0;    // fraction of the DTM's valid cells coloured
  double seam_fraction = 0;
  double balance_rms_before = 0;  // RMS of log colour ratios over overlaps
  double balance_rms_after = 0;
  double gain_min = 1;    // the per-photo colour gains' range
  double gain_max = 1;
};

// A coded target in the orthophoto against its survey.
struct OrthoMarkerFigures {
  std::string marker;
  std::string role;                       // control | check
  OrthoMarkerStatus status = OrthoMarkerStatus::not_detected;
  std::optional<double> source_pixel_mm;  // the photos' ground pixel there
  // When detected: where the orthophoto shows it (site CRS, metres) and the offset.
  double e_m = 0;
  double n_m = 0;
  double de_mm = 0;
  double dn_mm = 0;
  double offset_mm = 0;
  double offset_px = 0;
  bool within_tolerance = false;
  int detections = 0;
  int scales = 0;
};

struct OrthoMarkerCheckFigures {
  double cell_m = 0;
  double tolerance_px = 0;
  std::size_t surveyed = 0;
  int detected = 0;
  int over_tolerance = 0;
  double max_px = 0;
  double rmse_px = 0;
  double max_mm = 0;
  double rmse_mm = 0;
  std::vector<int> unknown_target_ids;
  std::vector<OrthoMarkerFigures> markers;
};

struct ContourFigures {
  double interval_m = 0;
  std::size_t lines = 0;
};

struct FootprintFigures {
  double area_m2 = 0;
  double perimeter_m = 0;
  std::size_t polygons = 0;
};

struct ProductsSteps {
  StepFigures dtm;
  std::optional<StepFigures> ortho;          // with photos
  std::optional<StepFigures> ortho_markers;  // when checked
  StepFigures vectors;
  std::optional<StepFigures> gpkg_rasters;   // when written into project.gpkg
  StepFigures total;
};

// The products stage's figures: DTM, orthophoto and its marker check, site plan.
struct ProductsQuality {
  std::string layer;
  DtmFigures dtm;
  std::optional<OrthoFigures> ortho;  // none without photos
  std::optional<OrthoMarkerCheckFigures> ortho_markers;
  ContourFigures contours;
  FootprintFigures footprint;
  ProductsSteps steps;
};

}  // namespace strata
