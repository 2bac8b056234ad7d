#pragma once
// Order statistics of samples, one definition for every figure strata reports.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace strata {

// The q-quantile (q in [0, 1], clamped) as the sample of rank round(q (n - 1)):
// always one of the values, so a median of residuals is a residual that was
// observed. NaN for an empty sample. Takes the sample by value (it is reordered).
double percentile(std::vector<double> v, double q);

// percentile(v, 0.5): for an even count, the upper of the two middle values.
double median(std::vector<double> v);

// The q-quantile by nearest rank: the smallest sample with at least a fraction q
// of the samples at or below it (for an even count the median is the lower middle
// value, unlike median()). The rule of the volume figures. Reorders `v`; NaN when
// empty.
double nearest_rank_quantile(std::vector<double>& v, double q);

// The value of rank k (0-based, ascending) of a non-empty sample, k < v.size().
// Reorders `v` in place and copies nothing: for samples too large to copy, for
// float samples, and for estimators whose rank rule is their own (least median of
// squares' h-th smallest miss, a nearest-rank quantile).
template <class T>
T kth_smallest(std::vector<T>& v, std::size_t k) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// median() in place: the value of rank n / 2 of a non-empty sample (for an even
// count the upper of the two middle values, as median() gives).
template <class T>
T median_in_place(std::vector<T>& v) {
  return kth_smallest(v, v.size() / 2);
}

}  // namespace strata
