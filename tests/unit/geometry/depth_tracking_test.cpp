// Depth-sequence registration on a synthetic trench with known poses: frame-to-model
// tracking removes the recorded poses' drift, the loop is found when the path closes
// and not when it does not.
#include "geometry/depth_tracking.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace strata {
namespace {

constexpr double kNoiseK = 0.0015;  // 1/m: the default depth noise, sigma = k z^2
// The recorded poses drift by several centimetres round the loop (checked below);
// registration must bring every camera within about one sigma of a single point's
// depth noise at 2.3 m (8 mm), and several times closer than the device put it.
constexpr double kMinRecordedDriftM = 0.03;
constexpr double kMaxPositionErrorM = 0.01;
constexpr double kMaxRotationErrorRad = 0.003;
constexpr double kMinDriftReduction = 3.0;
constexpr double kMinInlierShare = 0.5;

// A 4 m x 3 m trench 0.4 m deep with sloping sides (sampled as a height field, a
// vertical side would hold no points), two blocks standing in it and bumps of a few
// centimetres: enough relief to fix all six degrees of freedom.
double height(double x, double y) {
  auto step = [](double t) { return 0.5 * (1 + std::tanh(t / 0.12)); };
  const double inside = step(x) * step(4.0 - x) * step(y) * step(3.0 - y);
  const double block = (std::abs(x - 2.6) < 0.3 && std::abs(y - 1.2) < 0.2 ? 0.2 : 0.0) +
                       (std::abs(x - 1.1) < 0.15 && std::abs(y - 2.0) < 0.35 ? 0.15 : 0.0);
  return 0.03 * std::sin(14.0 * x) * std::cos(17.0 * y) + 0.02 * std::sin(1.3 * x + 0.7 * y) - 0.4 * inside +
         block * inside;
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& c, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - c).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() << x, z.cross(x), z;
  pose.translation() = c;
  return pose;
}

struct Sequence {
  std::vector<Eigen::Isometry3d> truth, recorded;
  std::vector<std::vector<Eigen::Vector3d>> frames;  // camera frame, thinned
};

// `share` of a loop round the trench, `n` frames; the surface sampled every 2.5 cm and
// kept where a 63 x 49 degree camera sees it within 3 m, with noise k z^2 on depth.
Sequence make_sequence(int n, double share, unsigned seed) {
  Sequence s;
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  Eigen::Isometry3d recorded = Eigen::Isometry3d::Identity();
  for (int i = 0; i < n; ++i) {
    const double t = 2 * std::numbers::pi * share * i / n;
    const Eigen::Vector3d c(2.0 + 2.3 * std::cos(t), 1.5 + 1.8 * std::sin(t), 1.2);
    const Eigen::Vector3d aim(2.0 + 0.7 * std::cos(t), 1.5 + 0.55 * std::sin(t), -0.4);
    s.truth.push_back(look_at(c, aim));
    if (i == 0) {
      recorded = s.truth[0];
    } else {
      // The device's error on each step: 1 mrad and 2 mm a frame, plus a bias.
      const Eigen::Vector3d w(1e-3 * normal(rng), 1e-3 * normal(rng) + 1e-3, 1e-3 * normal(rng));
      Eigen::Isometry3d error = Eigen::Isometry3d::Identity();
      error.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
      error.translation() = 0.002 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
      recorded = recorded * (s.truth[std::size_t(i) - 1].inverse() * s.truth[std::size_t(i)]) * error;
    }
    s.recorded.push_back(recorded);
    std::vector<Eigen::Vector3d> points;
    const Eigen::Isometry3d to_camera = s.truth.back().inverse();
    for (double x = -1.0; x <= 5.0; x += 0.025)
      for (double y = -1.0; y <= 4.0; y += 0.025) {
        const Eigen::Vector3d p = to_camera * Eigen::Vector3d(x, y, height(x, y));
        if (p.z() < 0.3 || p.z() > 3.0 || std::abs(p.x() / p.z()) > 0.61 || std::abs(p.y() / p.z()) > 0.457) continue;
        points.push_back(p * (1 + kNoiseK * p.z() * normal(rng)));  // along the ray: depth z(1 + k z e)
      }
    s.frames.push_back(voxel_subsample(points, 0.015));
  }
  return s;
}

double position_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}
double rotation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

TEST(DepthTracking, RemovesTheRecordedDriftAndClosesTheLoop) {
  const int n = 24;
  const Sequence s = make_sequence(n, 1.0, 7);  // the last frame one step short of the first
  ASSERT_GT(position_error(s.recorded.back(), s.truth.back()), kMinRecordedDriftM);
  const DepthTrackingSummary t = track_depth_sequence(s.frames, s.recorded, DepthTrackingOptions{});
  EXPECT_TRUE(t.loop_closed);
  ASSERT_EQ(t.poses.size(), std::size_t(n));
  EXPECT_EQ(position_error(t.poses[0], s.truth[0]), 0.0);  // the first frame fixes the sequence
  double worst_recorded = 0, worst = 0;
  for (int i = 0; i < n; ++i) {
    const std::size_t k = std::size_t(i);
    worst_recorded = std::max(worst_recorded, position_error(s.recorded[k], s.truth[k]));
    worst = std::max(worst, position_error(t.poses[k], s.truth[k]));
    EXPECT_LT(position_error(t.poses[k], s.truth[k]), kMaxPositionErrorM) << "frame " << i;
    EXPECT_LT(rotation_error(t.poses[k], s.truth[k]), kMaxRotationErrorRad) << "frame " << i;
    EXPECT_GT(t.fit[k].inlier_share, kMinInlierShare) << "frame " << i;
  }
  EXPECT_GT(worst_recorded, kMinDriftReduction * worst);
}

TEST(DepthTracking, NoLoopWhenThePathDoesNotReturn) {
  const Sequence s = make_sequence(10, 0.4, 3);
  DepthTrackingOptions o;
  o.refine_rounds = 0;
  const DepthTrackingSummary t = track_depth_sequence(s.frames, s.recorded, o);
  EXPECT_FALSE(t.loop_closed);
  for (std::size_t i = 0; i < s.truth.size(); ++i) {
    EXPECT_LT(position_error(t.poses[i], s.truth[i]), kMaxPositionErrorM) << "frame " << i;
    EXPECT_EQ(t.poses[i].matrix(), t.tracked[i].matrix());  // no loop, no rounds: the tracked poses
  }
}

TEST(DepthTracking, OptionsAreValidatedNamingTheField) {
  DepthTrackingOptions o;
  o.loop_share = 1.5;
  try {
    o.validate();
    ADD_FAILURE() << "accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("loop_share"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace strata
