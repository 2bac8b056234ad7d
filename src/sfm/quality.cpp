#include "sfm/quality.hpp"

#include "core/statistics.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <cmath>

namespace strata {
double reprojection_rmse_px(const Reconstruction& rec, const std::vector<ImageKeypoints>& keypoints) {
  STRATA_CHECK(keypoints.size() == rec.images.size());
  double sum2 = 0;
  std::size_t n = 0;
  for (const auto& p : rec.points) {
    for (const auto& e : p.track) {
      const auto& im = rec.images[e.image];
      if (!im.registered) continue;
      const Camera cam{rec.groups[im.group].intrinsics, im.pose};
      const auto proj = cam.project(p.X);
      if (!proj) continue;  // behind the camera: not a reprojection error
      sum2 += (*proj - keypoints[e.image].points[e.keypoint]).squaredNorm();
      ++n;
    }
  }
  return n ? std::sqrt(sum2 / double(n)) : 0.0;
}

double estimate_gsd_m(const Reconstruction& rec) {
  std::vector<std::vector<double>> depths(rec.images.size());
  for (const auto& p : rec.points) {
    for (const auto& e : p.track) {
      const auto& im = rec.images[e.image];
      if (!im.registered) continue;
      const double z = im.pose.to_camera(p.X).z();
      if (z > 0) depths[e.image].push_back(z);
    }
  }
  std::vector<double> per_image;
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    if (depths[i].empty()) continue;
    const auto& k = rec.groups[rec.images[i].group].intrinsics;
    per_image.push_back(median(depths[i]) / (0.5 * (k.fx + k.fy)));
  }
  return per_image.empty() ? 0.0 : median(per_image);
}

ReconstructionQuality measure_quality(const Reconstruction& rec,
                                      const std::vector<ImageKeypoints>& keypoints) {
  ReconstructionQuality q;
  q.total_images = rec.images.size();
  for (const auto& im : rec.images) q.registered_images += im.registered ? 1 : 0;
  q.points = rec.points.size();
  for (const auto& p : rec.points) q.observations += p.track.size();
  q.mean_track_length = q.points ? double(q.observations) / double(q.points) : 0.0;
  q.reprojection_rmse_px = reprojection_rmse_px(rec, keypoints);
  q.gsd_m = estimate_gsd_m(rec);
  return q;
}

}  // namespace strata
