#pragma once
// Order statistics of samples, one definition for every figure strata reports.
#include <vector>

namespace strata {

// The q-quantile (q in [0, 1], clamped) as the sample of rank round(q (n - 1)):
// always one of the values, so a median of residuals is a residual that was
// observed. NaN for an empty sample. Takes the sample by value (it is reordered).
double percentile(std::vector<double> v, double q);

// percentile(v, 0.5): for an even count, the upper of the two middle values.
double median(std::vector<double> v);

}  // namespace strata
