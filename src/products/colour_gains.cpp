#include "products/colour_gains.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace strata {

namespace {
constexpr std::uint8_t kDarkest = 8, kBrightest = 250;  // grey levels: below or above, a ratio is noise or clipped
constexpr double kRegulariser = 1e-3;                   // of the mean weight per view
}  // namespace

bool ColourOverlaps::usable(const std::uint8_t c[3]) {
  return *std::min_element(c, c + 3) >= kDarkest && *std::max_element(c, c + 3) <= kBrightest;
}

void ColourOverlaps::add(int a, const std::uint8_t ca[3], int b, const std::uint8_t cb[3]) {
  if (a == b || !usable(ca) || !usable(cb)) return;
  const bool swap = a > b;
  Pair& acc = pairs_[(std::uint64_t(swap ? b : a) << 32) | std::uint64_t(swap ? a : b)];
  acc.n += 1;
  for (int ch = 0; ch < 3; ++ch) {
    double r = std::log(double(ca[ch])) - std::log(double(cb[ch]));
    if (swap) r = -r;
    acc.sum[ch] += r;
    acc.sum2[ch] += r * r;
  }
}

ColourGains fit_colour_gains(const ColourOverlaps& overlaps, int n_views) {
  ColourGains out;
  out.gains.assign(std::size_t(std::max(n_views, 0)), {1.0, 1.0, 1.0});
  if (n_views < 2) return out;
  double total_n = 0, before2 = 0, after2 = 0;
  for (int ch = 0; ch < 3; ++ch) {
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n_views, n_views);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_views);
    for (const auto& [key, acc] : overlaps.pairs()) {
      const int a = int(key >> 32), b = int(key & 0xffffffffu);
      // Mean of ln I_a - ln I_b over the pair's elements: want x_a - x_b = -mean.
      const double m = acc.sum[ch] / acc.n;
      A(a, a) += acc.n;
      A(b, b) += acc.n;
      A(a, b) -= acc.n;
      A(b, a) -= acc.n;
      rhs(a) -= acc.n * m;
      rhs(b) += acc.n * m;
    }
    const double lambda = kRegulariser * std::max(1.0, A.diagonal().mean());
    A.diagonal().array() += lambda;
    const Eigen::VectorXd x = A.ldlt().solve(rhs);
    for (int v = 0; v < n_views; ++v) out.gains[std::size_t(v)][std::size_t(ch)] = std::exp(x(v));
    for (const auto& [key, acc] : overlaps.pairs()) {
      const int a = int(key >> 32), b = int(key & 0xffffffffu);
      const double d = x(a) - x(b);
      before2 += acc.sum2[ch];
      after2 += acc.sum2[ch] + 2 * d * acc.sum[ch] + acc.n * d * d;
      if (ch == 0) total_n += acc.n;
    }
  }
  out.overlaps = std::size_t(total_n);
  if (total_n > 0) {
    out.rms_before = std::sqrt(before2 / (3 * total_n));
    out.rms_after = std::sqrt(std::max(0.0, after2) / (3 * total_n));
  }
  return out;
}

}  // namespace strata
