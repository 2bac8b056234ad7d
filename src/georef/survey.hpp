#pragma once
// What a marker survey can and cannot tell, read off its coordinates alone: coordinates
// rounded to a coarse step (0.1 m is common when a survey is typed from a sketch) carry
// an error up to half that step whatever sigma the file states, and heights that are all
// equal (0.0 from a plan survey, or one nominal level) are unknown, not level ground.
#include <Eigen/Core>

#include <vector>

namespace strata {

struct SurveyAssessment {
  // metres: the coarsest step of {1, 0.5, 0.25, 0.2, 0.1, 0.05, 0.02, 0.01} that every
  // plan coordinate (E and N) is a multiple of; 0 when none (finer or unrounded).
  double plan_step_m = 0;
  double height_step_m = 0;  // the same for the heights (0 when all are equal)
  bool heights_equal = false;  // >= 3 markers and every height identical
  // metres: from this step on the rounding is coarse enough to say so (a warning at
  // alignment, the verdict's words in the report); finer steps only weigh the markers.
  static constexpr double kCoarseStep_m = 0.02;
  bool plan_coarse() const { return plan_step_m >= kCoarseStep_m; }
  bool height_coarse() const { return height_step_m >= kCoarseStep_m; }
  // metres, 1 sigma per axis, of the rounding: step / sqrt(12) (a uniform error).
  double plan_rounding_sigma_m() const;
  double height_rounding_sigma_m() const;
};

// `positions` in the survey's own CRS coordinates (not the site frame: the origin
// shift would hide the rounding). Needs >= 3 markers to say anything.
SurveyAssessment assess_survey(const std::vector<Eigen::Vector3d>& positions);

}  // namespace strata
