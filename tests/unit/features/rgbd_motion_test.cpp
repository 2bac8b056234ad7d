// The RGB-D feature start on the synthetic depth camera's frames: two consecutive
// frames of the loop give back the true motion between them (ORB matches lifted
// through the depth, rigid RANSAC); a textureless frame gives none; and the marker
// prints the synthetic camera draws are found by the coded-target detector where the
// true pose projects their centres.
#include "features/rgbd_motion.hpp"
#include "features/targets.hpp"
#include "synthetic/depth_camera.hpp"
#include "synthetic/synthetic.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <iostream>
#include <set>

namespace strata {
namespace {

// The small synthetic site with the depth camera's wider loop that sees the markers.
SyntheticExcavationOptions options() {
  auto o = SyntheticExcavationOptions::preset(SyntheticExcavationOptions::Size::small);
  o.site.stages = 1;
  o.depth.enabled = true;
  o.depth.edge_offset_m = 1.0;
  return o;
}

RgbdCamera camera(const SyntheticExcavationOptions& o) {
  const auto& d = o.depth;
  return {d.width, d.height, d.focal_px, d.focal_px, 0.5 * (d.width - 1), 0.5 * (d.height - 1), 0.001, d.noise_k};
}

// sRGB bytes to 8-bit grey (ITU-R 601 weights, as OpenCV's conversion).
std::vector<std::uint8_t> grey_of(const synthetic::DepthFrame& f) {
  std::vector<std::uint8_t> out(f.rgb.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = std::uint8_t(std::lround(0.299 * f.rgb[3 * i] + 0.587 * f.rgb[3 * i + 1] + 0.114 * f.rgb[3 * i + 2]));
  return out;
}

// The deepest layer of that site and its depth camera's planned loop.
class RgbdFrames : public ::testing::Test {
 protected:
  const SyntheticExcavationOptions o = options();
  const synthetic::Scene scene{o};
  const int layer = scene.layers() - 1;
  const std::vector<synthetic::DepthFramePlan> plan = synthetic::plan_depth_sequence(scene, layer, o.seed);
};

// Consecutive frames 6 degrees of the loop apart (about 20 cm): the features' motion
// must be within the ICP's basin by a wide margin, and here it is far better than
// that: a few millimetres and milliradians over hundreds of matches.
constexpr double kMaxStepErrorM = 0.01;
constexpr double kMaxStepErrorRad = 0.005;
constexpr int kMinInliers = 50;

TEST_F(RgbdFrames, ConsecutiveSyntheticFramesGiveTheTrueMotion) {
  const RgbdFeatureOptions fo;
  for (const std::size_t i : {std::size_t(4), std::size_t(31)}) {
    const auto a = synthetic::render_depth_frame(scene, layer, plan[i].true_pose, 1);
    const auto b = synthetic::render_depth_frame(scene, layer, plan[i + 1].true_pose, 2);
    const RgbdFeatures fa = extract_rgbd_features(grey_of(a), a.depth_mm, camera(o), fo);
    const RgbdFeatures fb = extract_rgbd_features(grey_of(b), b.depth_mm, camera(o), fo);
    ASSERT_GT(fa.points.size(), 200u) << "frame " << i;
    const RgbdMotion m = rgbd_relative_motion(fa, fb, fo);
    ASSERT_TRUE(m.found) << "frame " << i << ": " << m.matches << " matches, " << m.inliers << " inliers";
    EXPECT_GE(m.inliers, kMinInliers);
    const Eigen::Isometry3d truth = plan[i].true_pose.inverse() * plan[i + 1].true_pose;
    EXPECT_GT(truth.translation().norm(), 0.1) << "the frames should be apart for this test to mean anything";
    EXPECT_LT((m.motion.translation() - truth.translation()).norm(), kMaxStepErrorM) << "frame " << i;
    EXPECT_LT(Eigen::AngleAxisd(truth.linear().transpose() * m.motion.linear()).angle(), kMaxStepErrorRad)
        << "frame " << i;
  }
  // A blank colour frame has no keypoints: no motion, not a wrong one.
  const auto a = synthetic::render_depth_frame(scene, layer, plan[4].true_pose, 1);
  const RgbdFeatures fa = extract_rgbd_features(grey_of(a), a.depth_mm, camera(o), fo);
  const RgbdFeatures blank =
      extract_rgbd_features(std::vector<std::uint8_t>(a.depth_mm.size(), 128), a.depth_mm, camera(o), fo);
  EXPECT_EQ(blank.keypoints, 0);
  EXPECT_FALSE(rgbd_relative_motion(fa, blank, fo).found);
}

// The coded-target detector finds the prints within a pixel or two of where the true
// pose projects the markers' centres (the print's corners are sharp at 1.5-2.5 m).
constexpr double kMaxMarkerCentrePx = 2.0;

TEST_F(RgbdFrames, SyntheticColourFramesShowTheMarkers) {
  const RgbdCamera k = camera(o);
  int found = 0, false_ids = 0;
  std::set<int> ids;
  for (std::size_t i = 0; i < plan.size(); i += 6) {
    const auto frame = synthetic::render_depth_frame(scene, layer, plan[i].true_pose, 3);
    for (const TargetDetection& t : detect_targets(TargetOptions{}, grey_of(frame).data(), k.width, k.height)) {
      const auto m = std::find_if(scene.markers().begin(), scene.markers().end(),
                                  [&](const auto& mk) { return mk.id == t.id; });
      if (m == scene.markers().end()) {  // soil read as a code: its name matches no surveyed marker
        ++false_ids;
        continue;
      }
      const Eigen::Vector3d c = plan[i].true_pose.inverse() * m->centre;
      const Eigen::Vector2d expected(k.fx * c.x() / c.z() + k.cx, k.fy * c.y() / c.z() + k.cy);
      EXPECT_LT((t.centre - expected).norm(), kMaxMarkerCentrePx) << "frame " << i << ", " << m->name;
      ++found;
      ids.insert(t.id);
    }
  }
  // Soil read as a code: it happens (about one frame in two here, at 1.5-3 m) but with
  // ids that name no marker of the scene, else the projection check above would fail.
  std::cout << found << " markers found, " << false_ids << " other codes read in the soil\n";
  EXPECT_GE(found, 5);
  EXPECT_GE(ids.size(), 3u);  // enough distinct markers for a datum
}

}  // namespace
}  // namespace strata
