#pragma once
// The alignment controller: features -> matches -> coded targets -> incremental
// SfM -> georeference, for one layer of a project. It orchestrates and records;
// the maths lives in features/, sfm/ and georef/.
#include "features/features.hpp"
#include "georef/georeference.hpp"
#include "pipeline/lens_setup.hpp"
#include "pipeline/stage_results.hpp"
#include "project/project.hpp"
#include "sfm/incremental.hpp"

#include <string>

namespace strata {

struct AlignOptions {
  FeatureExtractionOptions features;
  PairSelectionOptions pairs;
  MatchingOptions matching;
  bool detect_targets = true;  // coded targets -> observations (source 'detected')
  TargetOptions targets;
  TargetNaming naming;
  LensChoiceOptions lens;          // the lens model of each camera (docs/cameras.md)
  FocalSearchOptions focal_search; // photos without EXIF focal length
  IncrementalOptions sfm;
  GeoreferenceOptions georef;
  Unkeyed<bool> force = false;  // rerun even when inputs and options are unchanged

  void validate() const;
};

struct AlignResult {
  bool skipped = false;       // up to date: nothing recomputed
  AlignmentQuality quality;   // the figures stored with the reconstruction
};

// Aligns one layer and stores cameras, points, residuals and quality in the
// project (one transaction). Throws ProcessingError when nothing can be aligned.
AlignResult align_layer(Project& project, const std::string& layer, const AlignOptions& options);

}  // namespace strata
