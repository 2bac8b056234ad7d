// Geometric consistency across depth maps (forward-backward reprojection,
// Schönberger et al. 2016 §4.4; Galliani et al. 2015 §4 "fusion"): a depth is kept
// when enough neighbour depth maps see the same 3D point. Outliers of PatchMatch
// (textureless or occluded windows) rarely agree across views; true surfaces do.
// A depth that neighbours see through (their own depth at its pixel lies well
// beyond it) is free space, not surface (Merrell et al. 2007, "free-space
// violations"): it is dropped when such neighbours outnumber the agreeing ones.
#include "core/error.hpp"
#include "dense/internal.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace strata::dense {

DepthMap filter_consistent(const DepthMap& ref, const PinholeCamera& rc,
                           const std::vector<DepthNeighbour>& neighbours,
                           const ConsistencyOptions& opt) {
  STRATA_CHECK(ref.width == rc.width && ref.height == rc.height, "depth map/camera size mismatch");
  DepthMap out;
  out.resize(ref.width, ref.height);
  const int w = ref.width, h = ref.height;
  const double max_err2 = opt.max_reprojection_px * opt.max_reprojection_px;
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        const float d = ref.depth[i];
        if (!(d > 0)) continue;
        const Eigen::Vector3d Xw = rc.to_world(rc.ray_point(x, y, d));
        int agree = 0, looked = 0, see_through = 0;
        for (const auto& nb : neighbours) {
          const PinholeCamera& sc = *nb.camera;
          const Eigen::Vector3d Xs = sc.pose.to_camera(Xw);
          if (Xs.z() <= 0) continue;
          const int u = static_cast<int>(std::lround(sc.fx * Xs.x() / Xs.z() + sc.cx));
          const int v = static_cast<int>(std::lround(sc.fy * Xs.y() / Xs.z() + sc.cy));
          if (u < 0 || v < 0 || u >= sc.width || v >= sc.height) continue;
          ++looked;
          const float ds = nb.depth->depth[static_cast<std::size_t>(v) * sc.width + u];
          if (!(ds > 0)) continue;
          // The neighbour sees a surface well beyond the point: free space where the
          // point should be.
          if (Xs.z() < ds * (1.0 - opt.free_space_margin)) {
            ++see_through;
            continue;
          }
          // Backward: the neighbour's own 3D point at that pixel, seen from the reference.
          const Eigen::Vector3d Xr = rc.pose.to_camera(sc.to_world(sc.ray_point(u, v, ds)));
          if (Xr.z() <= 0) continue;
          const double ex = rc.fx * Xr.x() / Xr.z() + rc.cx - x;
          const double ey = rc.fy * Xr.y() / Xr.z() + rc.cy - y;
          if (ex * ex + ey * ey > max_err2) continue;
          if (std::abs(Xr.z() - d) > opt.max_relative_depth * d) continue;
          ++agree;
        }
        if (agree < opt.min_consistent_views) continue;
        if (opt.max_free_space_violations > 0 && see_through >= opt.max_free_space_violations &&
            see_through > agree) {
          continue;
        }
        out.depth[i] = d;
        for (int k = 0; k < 3; ++k) out.normal[3 * i + k] = ref.normal[3 * i + k];
        // Photometric confidence scaled by the share of views that could see the
        // point and agree (a point confirmed by all neighbours counts fully).
        const float share = looked > 0 ? static_cast<float>(agree) / looked : 0.f;
        out.confidence[i] = ref.confidence[i] * (0.5f + 0.5f * share);
      }
    }
  });
  return out;
}

}  // namespace strata::dense
