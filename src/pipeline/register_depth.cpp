#include "pipeline/register_depth.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "core/statistics.hpp"
#include "pipeline/depth_frames.hpp"
#include "project/database.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

constexpr const char* kStage = "register.depth";

std::vector<DepthSequenceRecord> sequences_to_register(Database& db, const LayerRecord& layer,
                                                       const std::optional<std::string>& name) {
  std::vector<DepthSequenceRecord> out;
  for (const auto& s : list_depth_sequences(db, layer.id))
    if (!name || s.name == *name) out.push_back(s);
  if (out.empty()) {
    throw InputError(name ? fmt::format("{}: layer {} has no depth sequence named '{}'", kStage, layer.name, *name)
                          : fmt::format("{}: layer {} has no depth sequence (strata import depth)", kStage,
                                        layer.name));
  }
  return out;
}

// Why a frame's fit cannot be trusted, or empty.
std::string refusal(const DepthFrameResult& r, double noise_k, const DepthRegistrationOptions& o) {
  const double expected = std::sqrt(2.0) * noise_k * r.median_depth_m * r.median_depth_m;
  if (!r.fit.converged) return fmt::format("no convergence in {} iterations", r.fit.iterations);
  if (r.fit.inlier_share < o.min_inlier_share)
    return fmt::format("too little overlap with the other frames ({:.0f} % of its points within the gate, at "
                       "least {:.0f} % needed)",
                       100 * r.fit.inlier_share, 100 * o.min_inlier_share);
  if (r.fit.rms_m > o.max_rms_ratio * expected)
    return fmt::format("RMS residual {:.1f} mm, more than {} x the {:.1f} mm its depth noise explains", 1000 * r.fit.rms_m,
                       o.max_rms_ratio, 1000 * expected);
  return {};
}

ScanBounds bounds_under(const std::vector<Eigen::Vector3d>& points, const Eigen::Isometry3d& pose) {
  ScanBounds b{Eigen::Vector3d::Constant(HUGE_VAL), Eigen::Vector3d::Constant(-HUGE_VAL)};
  for (const auto& p : points) {
    const Eigen::Vector3d q = pose * p;
    b.min = b.min.cwiseMin(q);
    b.max = b.max.cwiseMax(q);
  }
  return b;
}

DepthSequenceResult register_sequence(Project& project, const DepthSequenceRecord& seq,
                                      const DepthRegistrationOptions& o) {
  const Stopwatch sw;
  DepthSequenceResult out;
  out.sequence = seq;
  const std::vector<DepthFrameRecord> records = list_depth_frames(project.db(), seq.id);
  if (records.size() < 2)
    throw InputError(fmt::format("{}: sequence '{}' has {} frame(s); tracking needs at least 2", kStage, seq.name,
                                 records.size()));
  std::vector<std::vector<Eigen::Vector3d>> frames;
  std::vector<Eigen::Isometry3d> recorded;
  {
    Progress progress(fmt::format("depth: reading {}", seq.name), records.size());
    for (const auto& f : records) {
      check_cancelled();
      if (!f.recorded_pose) {
        throw InputError(fmt::format("{}: sequence '{}': frame {} has no recorded pose; import the sequence with "
                                     "--poses (the device's own tracking) so that its first frame places it in the "
                                     "site frame",
                                     kStage, seq.name, f.name));
      }
      std::vector<Eigen::Vector3d> points = depth_frame_points(project.dir() / f.media_path, seq);
      std::erase_if(points, [&](const Eigen::Vector3d& p) { return p.z() > o.max_depth_m; });
      if (points.empty())
        throw InputError(fmt::format("{}: sequence '{}': frame {} has no depth nearer than {} m", kStage, seq.name,
                                     f.name, o.max_depth_m));
      std::vector<double> z;
      z.reserve(points.size());
      for (const auto& p : points) z.push_back(p.z());
      DepthFrameResult r;
      r.frame = f;
      r.recorded = *f.recorded_pose;
      r.median_depth_m = median_in_place(z);
      frames.push_back(voxel_subsample(points, o.frame_voxel_m));
      r.points_used = frames.back().size();
      recorded.emplace_back(*f.recorded_pose);
      out.frames.push_back(std::move(r));
      progress.step();
    }
    progress.finish();
  }
  const DepthTrackingSummary t = track_depth_sequence(frames, recorded, o.tracking);
  out.loop_closed = t.loop_closed;
  out.loop_frames = t.loop_frames;
  out.loop_inlier_share = t.loop_fit.inlier_share;
  out.loop_correction_m = t.loop_correction_m;
  out.loop_correction_rad = t.loop_correction_rad;
  for (std::size_t i = 0; i < out.frames.size(); ++i) {
    DepthFrameResult& r = out.frames[i];
    r.tracked = t.tracked[i].matrix();
    r.pose = t.poses[i].matrix();
    r.fit = t.fit[i];
    const bool fitted = i > 0 || r.fit.iterations > 0;  // the first frame is fitted only in the rounds
    if (const std::string why = fitted ? refusal(r, seq.noise_k, o) : std::string(); !why.empty())
      throw InputError(fmt::format("{}: sequence '{}': frame {}: cannot register it: {}. Nothing was changed. "
                                   "Check the frame (a blurred or empty view) and its recorded pose, or import "
                                   "the sequence without it",
                                   kStage, seq.name, r.frame.name, why));
    r.frame.pose = r.pose;
    r.frame.bounds = bounds_under(frames[i], t.poses[i]);
    r.frame.fit = DepthFrameFit{t.loop_closed ? "loop-closure" : "tracking", r.fit.rms_m, r.fit.inlier_share,
                                r.fit.sigma_translation_m, r.fit.sigma_rotation_rad};
  }
  out.seconds = sw.seconds();
  log::info("{}: sequence '{}': {} frames registered in {:.1f} s; loop {}", kStage, seq.name, out.frames.size(),
            out.seconds,
            t.loop_closed ? fmt::format("closed on the first {} frames (the last camera moved {:.1f} mm, {:.2f} mrad)",
                                        t.loop_frames, 1000 * t.loop_correction_m, 1000 * t.loop_correction_rad)
                          : std::string("not closed (the last frame does not overlap the first ones)"));
  return out;
}

}  // namespace

void DepthRegistrationOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("{}: {} must be {}", kStage, field, what));
  };
  need(frame_voxel_m > 0, "frame_voxel_m", "> 0 (metres)");
  need(max_depth_m > 0, "max_depth_m", "> 0 (metres)");
  need(min_inlier_share > 0 && min_inlier_share < 1, "min_inlier_share", "in (0, 1)");
  need(max_rms_ratio > 0, "max_rms_ratio", "> 0");
  tracking.validate();
}

DepthRegistrationSummary register_layer_depth(Project& project, const std::string& layer_name,
                                              const DepthRegistrationOptions& options) {
  options.validate();
  Database& db = project.db();
  const LayerRecord layer = require_layer(db, layer_name);
  DepthRegistrationSummary out;
  out.layer = layer_name;
  for (const auto& seq : sequences_to_register(db, layer, options.sequence))
    out.sequences.push_back(register_sequence(project, seq, options));
  Transaction tx(db);
  for (const auto& s : out.sequences)
    for (const auto& r : s.frames) set_depth_frame_registered(db, r.frame.id, r.pose, *r.frame.bounds, *r.frame.fit);
  tx.commit();
  return out;
}

}  // namespace strata
