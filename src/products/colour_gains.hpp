#pragma once
// Colour gains between photos: one multiplicative gain per photo and channel, fitted by
// linear least squares on the log colour ratios of every pair of photos that see the
// same surface element (exposure equalisation in the manner of El-Hakim, Beraldin &
// Blais 1998). The true orthophoto fits them over its cells, the texture atlas over its
// faces; both hand the overlaps to this one solver.
#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace strata {

// The colour ratios of pairs of views over the surface elements both see.
class ColourOverlaps {
 public:
  // One surface element seen by views a and b (indices, a != b) with 8-bit sRGB colours
  // ca and cb. Dark (any channel below 8) or clipped (above 250) colours are left out:
  // their ratios say nothing about the exposure.
  void add(int a, const std::uint8_t ca[3], int b, const std::uint8_t cb[3]);
  // Whether a colour is used at all (the same rule add() applies to each side).
  static bool usable(const std::uint8_t c[3]);

  struct Pair {
    double n = 0;                     // elements seen by both
    std::array<double, 3> sum{};      // sum of ln I_a - ln I_b per channel (a < b)
    std::array<double, 3> sum2{};     //   and of its square
  };
  const std::unordered_map<std::uint64_t, Pair>& pairs() const { return pairs_; }  // key: a << 32 | b, a < b

 private:
  std::unordered_map<std::uint64_t, Pair> pairs_;
};

struct ColourGains {
  std::vector<std::array<double, 3>> gains;  // per view, RGB multiplicative; 1 for a view without overlaps
  double rms_before = 0;                     // RMS of the log colour ratios over the overlaps, before the gains
  double rms_after = 0;                      //   and after
  std::size_t overlaps = 0;                  // element pairs the fit used
};

// Per view and channel the log gain x_v minimising
//   sum over pairs (a, b) and their shared elements of (x_a + ln I_a - x_b - ln I_b)^2
// plus lambda sum x_v^2, lambda = 1e-3 x the mean weight per view: the regulariser pulls
// every gain towards 1, fixes the gauge (a common factor is unobservable; the gains'
// geometric mean stays near 1) and keeps a view without overlaps at 1.
ColourGains fit_colour_gains(const ColourOverlaps& overlaps, int n_views);

}  // namespace strata
