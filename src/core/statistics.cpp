#include "core/statistics.hpp"

#include <cmath>
#include <limits>

namespace strata {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  return kth_smallest(v, static_cast<std::size_t>(std::lround(std::clamp(q, 0.0, 1.0) * double(v.size() - 1))));
}

double median(std::vector<double> v) { return percentile(std::move(v), 0.5); }

double nearest_rank_quantile(std::vector<double>& v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto rank = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(q * double(v.size()) - 1e-9)));
  return kth_smallest(v, std::min(rank, v.size()) - 1);
}

}  // namespace strata
