#include "geometry/depth_tracking.hpp"

#include "core/error.hpp"
#include "core/progress.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <tuple>

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

// Whether a frame's fit from its measured step can be kept without trying the other
// starts: it converged and kept at least kConsistentShare of the share of points the
// last frames' fits kept (their median); a step that put the frame on a wrong place
// leaves much of it off the model.
constexpr double kConsistentShare = 0.75;
constexpr int kConsistentFrames = 5;

bool consistent(const IcpSummary& fit, const std::vector<IcpSummary>& previous) {
  if (!fit.converged) return false;
  std::vector<double> shares;
  for (auto it = previous.rbegin(); it != previous.rend() && int(shares.size()) < kConsistentFrames; ++it)
    if (it->converged) shares.push_back(it->inlier_share);
  if (shares.empty()) return true;
  std::nth_element(shares.begin(), shares.begin() + long(shares.size() / 2), shares.end());
  return fit.inlier_share >= kConsistentShare * shares[shares.size() / 2];
}

// Better of two fits: a converged one, then the larger share of points within the gate.
bool better(const IcpSummary& a, const IcpSummary& b) {
  if (a.converged != b.converged) return a.converged;
  return a.inlier_share > b.inlier_share;
}

// Frame i's fit to the model and what started it. From the measured step when there
// is one and its fit is consistent with the last frames'; else every other start is
// ranked by a short fit of an eighth of the points (constant velocity, no motion) and
// the best is fitted in full.
std::pair<IcpSummary, TrackingStart> track_frame(const std::vector<Eigen::Vector3d>& frame, const OrientedPoints& model,
                                                 const Eigen::Isometry3d& previous_pose,
                                                 const std::optional<Eigen::Isometry3d>& step,
                                                 const std::optional<Eigen::Isometry3d>& velocity,
                                                 const std::vector<IcpSummary>& previous,
                                                 const DepthTrackingOptions& o) {
  std::pair<IcpSummary, TrackingStart> best{IcpSummary{}, TrackingStart::none};
  if (step) {
    best = {register_point_to_plane(frame, model, previous_pose * *step, o.icp), TrackingStart::step};
    if (consistent(best.first, previous)) return best;
  }
  std::vector<std::pair<Eigen::Isometry3d, TrackingStart>> starts;
  if (velocity) starts.emplace_back(previous_pose * *velocity, TrackingStart::constant_velocity);
  starts.emplace_back(previous_pose, TrackingStart::no_motion);
  constexpr std::size_t kShortEvery = 8;  // the short fits' points: every 8th
  constexpr int kShortIterations = 30;
  std::vector<Eigen::Vector3d> thin;
  for (std::size_t k = 0; k < frame.size(); k += kShortEvery) thin.push_back(frame[k]);
  IcpOptions short_icp = o.icp;
  short_icp.max_iterations = kShortIterations;
  std::optional<std::pair<IcpSummary, TrackingStart>> ranked;
  for (const auto& [pose, how] : starts) {
    IcpSummary fit = register_point_to_plane(thin, model, pose, short_icp);
    if (!ranked || fit.inlier_share > ranked->first.inlier_share) ranked = {std::move(fit), how};
  }
  IcpSummary full = register_point_to_plane(frame, model, ranked->first.pose, o.icp);
  if (best.second == TrackingStart::none || better(full, best.first)) best = {std::move(full), ranked->second};
  return best;
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
  s.started.assign(n, TrackingStart::none);
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
      const std::optional<Eigen::Isometry3d> velocity =
          i >= 2 ? std::optional<Eigen::Isometry3d>(s.tracked[i - 2].inverse() * s.tracked[i - 1]) : std::nullopt;
      const std::vector<IcpSummary> previous(s.tracking_fit.begin() + 1, s.tracking_fit.begin() + long(i));
      std::tie(s.tracking_fit[i], s.started[i]) =
          track_frame(frames[i], model.oriented(), s.tracked[i - 1], steps[i], velocity, previous, o);
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
