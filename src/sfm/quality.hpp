#pragma once
// Quality figures of a reconstruction that every layer records (docs/design.md,
// "Quality figures every reconstruction records").
#include "features/types.hpp"
#include "geometry/reconstruction.hpp"

#include <cstddef>
#include <vector>

namespace strata {

struct ReconstructionQuality {
  std::size_t registered_images = 0;
  std::size_t total_images = 0;
  std::size_t points = 0;
  std::size_t observations = 0;
  double reprojection_rmse_px = 0;  // pixels, over every track observation
  double mean_track_length = 0;     // observations per point
  double gsd_m = 0;                 // metres per pixel at the sparse points; 0 if unknown
};

// Root mean square of |projection - keypoint| over all observations of all points
// in registered images, pixels. 0 when there are none.
double reprojection_rmse_px(const Reconstruction& rec, const std::vector<ImageKeypoints>& keypoints);

// Ground sampling distance: for each registered image the median depth of the points
// it sees divided by its focal length (metres / pixel, valid at the image centre), then
// the median over images. Meaningful in metres only once georeferenced. 0 if no image
// sees a point.
double estimate_gsd_m(const Reconstruction& rec);

ReconstructionQuality measure_quality(const Reconstruction& rec,
                                      const std::vector<ImageKeypoints>& keypoints);

}  // namespace strata
