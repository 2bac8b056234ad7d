#include "geometry/depth_tracking.hpp"

#include "core/error.hpp"
#include "core/progress.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

// The thinned model of the frames [begin, end) at their poses, with normals.
OrientedPoints build_model(const std::vector<std::vector<Eigen::Vector3d>>& frames,
                           const std::vector<Eigen::Isometry3d>& poses, std::size_t begin, std::size_t end,
                           const DepthTrackingOptions& o) {
  VoxelMeans model(o.model_voxel_m);
  for (std::size_t i = begin; i < end; ++i)
    for (const auto& p : frames[i]) model.add(poses[i] * p);
  return estimate_normals(model.points(), o.normal_radius_m);
}

// A share `s` of the rigid motion `c` (site frame, applied on the left), taken as a
// rotation about `centre` and a translation: s = 0 is the identity, s = 1 is `c`.
Eigen::Isometry3d partial_motion(const Eigen::Isometry3d& c, const Eigen::Vector3d& centre, double s) {
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(c.linear()));
  const Eigen::Matrix3d R = Eigen::AngleAxisd(s * aa.angle(), aa.axis()).toRotationMatrix();
  // c(x) = R_c (x - centre) + centre + t_c, with t_c = c(centre) - centre.
  const Eigen::Vector3d t = c * centre - centre;
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = R;
  out.translation() = centre + s * t - R * centre;
  return out;
}

}  // namespace

void DepthTrackingOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("depth tracking: {} must be {}", field, what));
  };
  need(model_voxel_m > 0, "model_voxel_m", "> 0 (metres)");
  need(normal_radius_m >= 2 * model_voxel_m, "normal_radius_m", ">= 2 x model_voxel_m (metres)");
  need(loop_share > 0 && loop_share < 1, "loop_share", "in (0, 1)");
  need(min_loop_frames >= 1, "min_loop_frames", ">= 1");
  need(min_loop_inlier_share > 0 && min_loop_inlier_share < 1, "min_loop_inlier_share", "in (0, 1)");
  need(refine_rounds >= 0 && refine_rounds <= 10, "refine_rounds", "0..10");
  icp.validate();
}

DepthTrackingSummary track_depth_sequence(const std::vector<std::vector<Eigen::Vector3d>>& frames,
                                          const std::vector<Eigen::Isometry3d>& recorded,
                                          const DepthTrackingOptions& o) {
  STRATA_CHECK(!recorded.empty() && recorded.size() == frames.size(), "{} frames, {} recorded poses", frames.size(),
               recorded.size());
  std::vector<std::optional<Eigen::Isometry3d>> steps(recorded.size());
  for (std::size_t i = 1; i < recorded.size(); ++i) steps[i] = recorded[i - 1].inverse() * recorded[i];
  return track_depth_sequence(frames, recorded[0], steps, o);
}

DepthTrackingSummary track_depth_sequence(const std::vector<std::vector<Eigen::Vector3d>>& frames,
                                          const Eigen::Isometry3d& first,
                                          const std::vector<std::optional<Eigen::Isometry3d>>& steps,
                                          const DepthTrackingOptions& o) {
  o.validate();
  const std::size_t n = frames.size();
  STRATA_CHECK(n >= 2 && steps.size() == n, "{} frames, {} steps", n, steps.size());
  DepthTrackingSummary s;

  // 1. Frame to model.
  s.tracked.assign(n, first);
  s.tracking_fit.assign(n, IcpSummary{});
  {
    Progress progress("depth: tracking", n - 1);
    GrowingModel model(o.model_voxel_m, o.normal_radius_m);  // grows by each frame once registered
    const auto add = [&](std::size_t i) {
      std::vector<Eigen::Vector3d> site;
      site.reserve(frames[i].size());
      for (const auto& p : frames[i]) site.push_back(s.tracked[i] * p);
      model.add(site);
    };
    add(0);
    for (std::size_t i = 1; i < n; ++i) {
      check_cancelled();
      if (steps[i]) {
        s.tracking_fit[i] = register_point_to_plane(frames[i], model.oriented(), s.tracked[i - 1] * *steps[i], o.icp);
      } else {
        // No step measured: constant velocity (the previous frame's motion again) and
        // no motion are both tried, the fit keeping more points within the gate wins
        // (a hand-held camera that turned a corner may have stopped or slowed down).
        const Eigen::Isometry3d velocity =
            i >= 2 ? Eigen::Isometry3d(s.tracked[i - 2].inverse() * s.tracked[i - 1]) : Eigen::Isometry3d::Identity();
        s.tracking_fit[i] = register_point_to_plane(frames[i], model.oriented(), s.tracked[i - 1] * velocity, o.icp);
        if (i >= 2) {
          IcpSummary still = register_point_to_plane(frames[i], model.oriented(), s.tracked[i - 1], o.icp);
          if (still.converged && (!s.tracking_fit[i].converged ||
                                  still.inlier_share > s.tracking_fit[i].inlier_share))
            s.tracking_fit[i] = std::move(still);
        }
      }
      s.tracked[i] = s.tracking_fit[i].pose;
      add(i);
      progress.step();
    }
    progress.finish();
  }
  s.poses = s.tracked;
  s.fit = s.tracking_fit;

  // 2. Loop closure on the first frames.
  s.loop_frames = int(std::max<double>(o.min_loop_frames, std::round(o.loop_share * double(n))));
  if (std::size_t(s.loop_frames) < n - 1) {
    const OrientedPoints first = build_model(frames, s.tracked, 0, std::size_t(s.loop_frames), o);
    s.loop_fit = register_point_to_plane(frames[n - 1], first, s.tracked[n - 1], o.icp);
    s.loop_closed = s.loop_fit.converged && s.loop_fit.inlier_share >= o.min_loop_inlier_share;
  }
  if (s.loop_closed) {
    const Eigen::Isometry3d correction = s.loop_fit.pose * s.tracked[n - 1].inverse();
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : s.tracked) centre += p.translation();
    centre /= double(n);
    for (std::size_t i = 0; i < n; ++i)
      s.poses[i] = partial_motion(correction, centre, double(i) / double(n - 1)) * s.tracked[i];
    s.loop_correction_m = (s.poses[n - 1].translation() - s.tracked[n - 1].translation()).norm();
    s.loop_correction_rad = Eigen::AngleAxisd(Eigen::Matrix3d(s.poses[n - 1].linear() * s.tracked[n - 1].linear().transpose())).angle();
  }

  // 3. Every frame again on the model of all frames.
  for (int round = 0; round < o.refine_rounds; ++round) {
    check_cancelled();
    const OrientedPoints model = build_model(frames, s.poses, 0, n, o);
    std::vector<Eigen::Isometry3d> next(n);
    Progress progress(fmt::format("depth: re-registration {}/{}", round + 1, o.refine_rounds), n);
    for (std::size_t i = 0; i < n; ++i) {
      s.fit[i] = register_point_to_plane(frames[i], model, s.poses[i], o.icp);
      // The first frame stays where it was put: it fixes the sequence's frame (its
      // fit is computed for its residuals only).
      next[i] = i == 0 ? s.poses[0] : s.fit[i].pose;
      progress.step();
    }
    progress.finish();
    s.poses = std::move(next);
  }
  return s;
}

}  // namespace strata
