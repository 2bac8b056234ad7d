#include "georef/survey.hpp"

#include <cmath>

namespace strata {
namespace {

constexpr double kSteps[] = {1.0, 0.5, 0.25, 0.2, 0.1, 0.05, 0.02, 0.01};
// Coordinates stored from text keep about 1e-9 m of binary noise at UTM magnitudes.
constexpr double kTolerance = 1e-6;  // metres

bool multiple_of(double v, double step) {
  const double q = v / step;
  return std::abs(q - std::round(q)) * step < kTolerance;
}

double coarsest_step(const std::vector<Eigen::Vector3d>& p, int axis0, int axis1) {
  for (const double step : kSteps) {
    bool all = true;
    for (const auto& x : p) {
      for (int a = axis0; a <= axis1 && all; ++a) all = multiple_of(x[a], step);
      if (!all) break;
    }
    if (all) return step;
  }
  return 0;
}

}  // namespace

double SurveyAssessment::plan_rounding_sigma_m() const { return plan_step_m / std::sqrt(12.0); }
double SurveyAssessment::height_rounding_sigma_m() const { return height_step_m / std::sqrt(12.0); }

SurveyAssessment assess_survey(const std::vector<Eigen::Vector3d>& positions) {
  SurveyAssessment a;
  if (positions.size() < 3) return a;
  a.heights_equal = true;
  for (const auto& p : positions) a.heights_equal = a.heights_equal && p.z() == positions.front().z();
  a.plan_step_m = coarsest_step(positions, 0, 1);
  if (!a.heights_equal) a.height_step_m = coarsest_step(positions, 2, 2);
  return a;
}

}  // namespace strata
