#pragma once
// The registration controller of RGB-D depth sequences (docs/range.md, "Registration
// of depth sequences"): each sequence of a layer read from media/, its frames
// back-projected and thinned, tracked frame to model (geometry/depth_tracking.hpp),
// each frame started from the motion its colour frame's features measured against
// the previous one (features/rgbd_motion.hpp) or the motion the device recorded,
// closed on its first frames and re-registered against the model of all its frames;
// then placed in the site frame by the device's first pose, by the surveyed markers
// its colour frames saw (pipeline/marker_fit.hpp), or, levelled on its ground, fitted
// to the layer's photo surface as an unregistered scan is (pipeline/register_scans.hpp).
// Every frame is fitted and
// checked before anything is written; then all are stored in one transaction, or none.
#include "features/rgbd_motion.hpp"
#include "features/targets.hpp"
#include "geometry/depth_tracking.hpp"
#include "pipeline/marker_fit.hpp"
#include "pipeline/register_scans.hpp"
#include "project/depth_records.hpp"
#include "project/project.hpp"

#include <optional>
#include <string>
#include <vector>

namespace strata {

// What starts each frame's fit when both are at hand: the motion the colour frames'
// features measured, or the one the device recorded. Either falls back on the other,
// then on constant velocity (the previous step again).
enum class DepthStart { features, recorded };

// What places the sequence in the site frame: the device's recorded first pose, the
// surveyed markers seen in the colour frames, or the photo surface (the tracked
// sequence levelled on its ground, then fitted by the coarse yaw search and ICP);
// automatic: the device's when the sequence has recorded poses, else the markers when
// its colour frames see at least 3, else the surface when the layer has one.
enum class DepthDatum { automatic, device, markers, surface };

struct DepthRegistrationOptions {
  std::optional<std::string> sequence;  // one sequence by name; default every sequence of the layer
  // docs/range.md, "Depth sequences, measured": with recorded poses the recorded start
  // came out marginally better (RMS 5.46 against 5.56 mm); without them, features.
  DepthStart start = DepthStart::recorded;
  DepthDatum datum = DepthDatum::automatic;
  RgbdFeatureOptions features;
  // The wide match, tried when the usual one finds no motion between two frames (a
  // corner turned: on the synthetic 24-frame loop, 22-40 degree turns left 0-8 of 3-21
  // matches agreeing): no ratio test (every mutual nearest match), every triple of
  // them tried up to 200 000, at least 6 agreeing (docs/range.md, "Depth sequences,
  // measured": 6-33 agreeing pairs at those corners, 4 at a 53-degree one, wrongly).
  RgbdFeatureOptions wide_features = [] {
    RgbdFeatureOptions w;
    w.ratio = 1.0;
    w.min_inliers = 6;
    w.ransac.hypotheses = 200000;
    return w;
  }();
  TargetOptions targets;                // coded-target detection in the colour frames
  TargetNaming naming;                  // target id -> marker name
  // A marker centre in the sequence's frame: its depth (k z^2 at 2-3 m: 6-14 mm a
  // pixel, the median of a few pixels and frames) and the tracked poses (5-10 mm).
  // The gate is 3 sigmas of it and of the survey; the scale check is looser than a
  // scanner's (a depth camera's scale is good to a few parts in a thousand).
  MarkerFitOptions marker_fit = {0.010, 3.0, 0.005, 0.01};
  int marker_window_px = 2;             // pixels: a marker centre's depth is the median within this of it
  double frame_voxel_m = 0.015;   // metres: each frame thinned to one point a cube, in its camera frame
  double max_depth_m = 3.0;       // metres: farther pixels are left out of the registration (noise k z^2
                                  // grows past 1 cm there); the fusion still uses them, weighted down
  // Refusals, per frame, of the last fit: the share of its thinned points kept as
  // inliers, and the inliers' RMS over the noise expected at the frame's median depth
  // (k z^2, times sqrt(2): the model is made of such points too).
  double min_inlier_share = 0.30;
  double max_rms_ratio = 3.0;
  // The surface datum: the whole tracked sequence treated as one scan (its points
  // thinned to surface.scan_voxel_m; the refusals on its fit are the scans'), against
  // surface.against. Its up direction: the normal of the plane most of its points lie
  // on within level_tolerance_m (the ground round the trench; 3 frame voxels), turned
  // to the side of the cameras.
  ScanRegistrationOptions surface;
  double level_tolerance_m = 0.045;
  DepthTrackingOptions tracking;
  void validate() const;  // throws InputError naming the field
};

struct DepthFrameResult {
  DepthFrameRecord frame;                                     // as stored after the registration
  Eigen::Matrix4d recorded = Eigen::Matrix4d::Identity();     // the device's pose
  Eigen::Matrix4d tracked = Eigen::Matrix4d::Identity();      // after frame-to-model tracking
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();         // final: camera -> site frame
  bool has_recorded = false;                                  // the device recorded a pose
  IcpSummary fit;                                             // the last fit of the frame
  std::string start;             // what started its tracking fit: features, recorded, constant-velocity ('' frame 0)
  RgbdMotion features;           // the colour frame's features against the previous frame's
  int markers_seen = 0;          // coded targets with a depth in its colour frame
  double median_depth_m = 0;
  std::size_t points_used = 0;                                // thinned
};

// A surveyed marker as the sequence saw it.
struct DepthMarkerSighting {
  std::string name;
  int frames = 0;                                    // colour frames it was found in, with a depth
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // median over them, the sequence's frame (frame 0's camera), metres
};

struct DepthSequenceResult {
  DepthSequenceRecord sequence;
  std::vector<DepthFrameResult> frames;
  std::string datum;                         // 'device', 'markers' or 'surface'
  std::vector<DepthMarkerSighting> markers;  // every marker seen (markers datum), by name
  std::optional<MarkerFit> marker_fit;       // the sequence -> site fit (markers datum)
  std::vector<std::string> unmatched;        // targets seen whose name no surveyed marker has
  // The surface datum: the sequence frame -> site frame, the fit of its levelled points
  // to the surface of `surface_layer`, the ground plane that levelled it and the angle
  // the levelling turned it by.
  std::optional<SurfaceFit> surface_fit;
  Eigen::Matrix4d surface_transform = Eigen::Matrix4d::Identity();
  std::string surface_layer;
  std::size_t surface_points_used = 0;       // the sequence's points, thinned
  double ground_share = 0;                   // of them on the levelling plane
  double level_rad = 0;
  bool loop_closed = false;
  int loop_frames = 0;
  double loop_inlier_share = 0;
  double loop_correction_m = 0;
  double loop_correction_rad = 0;
  double seconds = 0;
};

struct DepthRegistrationSummary {
  std::string layer;
  std::vector<DepthSequenceResult> sequences;
};

// Registers the layer's depth sequences (or options.sequence) and stores every frame's
// pose, box and fit. Throws InputError, the database unchanged, when the layer has no
// sequence, a sequence without recorded poses sees fewer than 3 surveyed markers and
// the layer has no photo surface (or the datum asked for is not at hand), the markers
// do not agree, the fit to the surface fails the scans' checks, or any frame's fit
// fails its checks (the message names the sequence or frame and what to do).
DepthRegistrationSummary register_layer_depth(Project& project, const std::string& layer,
                                              const DepthRegistrationOptions& options);

}  // namespace strata
