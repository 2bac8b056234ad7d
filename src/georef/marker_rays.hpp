#pragma once
// Where a marker is, from the rays of its image observations, when not every
// observation is good.
//
// Real markers are objects (a cone, a nail with a disc, a board 10 cm across) clicked
// at their visible centre from every side, or placed by another program's projection:
// their rays do not meet in one point to the click precision but scatter about it in
// object space, and a few are plainly wrong. Both are modelled per marker:
//   e_i ~ N(0, sigma_i^2) per image axis,  sigma_i^2 = c^2 + (s / g_i)^2,
// with c the click precision (pixels), g_i the ground size of a pixel of photo i at the
// marker (depth / focal, frame units per pixel) and s the marker's own dispersion in
// object space (frame units), estimated from the rays that agree. Rays farther than
// `agree_factor` sigma_i from the fitted point are the disagreeing ones.
//
// The point is found robustly first: every pair of rays wide enough apart proposes a
// point, and the one whose h-th smallest object-space miss (h = half the rays) is the
// smallest wins (least median of squares, Rousseeuw 1984), so up to half the rays may
// be gross errors. Then point, dispersion and agreeing set are iterated: the point by
// weighted least squares on the agreeing rays, the dispersion by matching their
// chi-square to its degrees of freedom (2 n - 3), the set by the 3-sigma gate.
#include "geometry/camera.hpp"

#include <Eigen/Core>

#include <limits>
#include <vector>

namespace strata {

struct MarkerRayOptions {
  // degrees: the widest pair of agreeing rays must be at least this far apart.
  double min_angle_deg = 2.0;
  // pixels: standard deviation of one observation of a sharp target (the floor of
  // sigma_i; the caller passes the a posteriori value once the block is adjusted).
  double click_sigma_px = 1.0;
  // unitless: a ray agrees when it reprojects within this many sigma_i of the point
  // (4: 0.03 % of good 2D observations fall outside, so a layer with 100 marker
  // observations names a good one in 3 % of cases; at 3 it would be 67 %).
  double agree_factor = 4.0;
  // pixels: never call a ray within this of the point a disagreement: a pixel or two
  // of detection or click jitter is not a wrong click, whatever sigma the others reach.
  double min_gate_px = 2.0;
  // unitless: a dispersion above this fraction of the mean viewing distance is not one
  // point any more (clicks on different objects, a wrong name): the marker is not usable.
  double max_relative_dispersion = 0.1;

  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct MarkerRayFit {
  bool ok = false;                // >= 2 agreeing rays, wide enough apart, one point
  Eigen::Vector3d X = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double dispersion = 0;          // s: frame units (metres once georeferenced), 1 sigma per axis
  double mean_footprint = 0;      // frame units per pixel, mean over the agreeing rays
  double mean_depth = 0;          // frame units, mean over the agreeing rays
  double rmse_px = 0;             // RMS reprojection over the agreeing rays
  double max_angle_deg = 0;       // widest pair of agreeing rays
  int agreeing = 0;
  bool too_dispersed = false;     // dispersion beyond max_relative_dispersion
  struct Ray {
    double error_px = 0;          // reprojection of X in this photo (infinite: behind it)
    double sigma_px = 0;          // sigma_i: what this photo is expected to achieve
    double footprint = 0;         // g_i, frame units per pixel
    bool agrees = false;
  };
  std::vector<Ray> rays;          // one per input ray, in input order
};

// Fits one marker from its rays (>= 2 needed for a point). `cameras[i]` sees `pixels[i]`.
MarkerRayFit fit_marker_rays(const std::vector<Camera>& cameras, const std::vector<Eigen::Vector2d>& pixels,
                             const MarkerRayOptions& options);

}  // namespace strata
