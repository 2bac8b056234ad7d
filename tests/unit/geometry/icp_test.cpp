// Point-to-plane ICP and the coarse yaw search on analytic surfaces with a known motion.
#include "geometry/icp.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace strata {
namespace {

constexpr double kTranslationTolerance = 1e-3;  // metres: the registration bar, 1 mm
constexpr double kRotationTolerance = 1e-3;     // radians: 1 mrad
constexpr double kCoarseYawTolerance = 0.05;    // radians: inside ICP's basin, well under the 10 degree step

struct Box {
  Eigen::Vector3d min, max;
};

// A ground plane z = 0 over [-1, 1]^2 with two boxes standing on it (no symmetry of
// the whole), sampled every `spacing` metres from `offset`, with Gaussian noise.
std::vector<Eigen::Vector3d> boxes_on_plane(double spacing, double offset, double noise, unsigned seed,
                                            bool with_boxes = true) {
  const std::vector<Box> boxes = {{{0.1, 0.1, 0}, {0.6, 0.5, 0.3}}, {{-0.7, 0.3, 0}, {-0.4, 0.8, 0.15}}};
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  std::vector<Eigen::Vector3d> out;
  auto add = [&](const Eigen::Vector3d& p) { out.push_back(p + Eigen::Vector3d(n(rng), n(rng), n(rng))); };
  auto inside = [&](double x, double y) {
    for (const Box& b : boxes)
      if (x > b.min.x() && x < b.max.x() && y > b.min.y() && y < b.max.y()) return &b;
    return static_cast<const Box*>(nullptr);
  };
  for (double x = -1 + offset; x < 1; x += spacing)
    for (double y = -1 + offset; y < 1; y += spacing) {
      const Box* b = with_boxes ? inside(x, y) : nullptr;
      add({x, y, b ? b->max.z() : 0.0});
    }
  if (!with_boxes) return out;
  for (const Box& b : boxes)
    for (double z = offset; z < b.max.z(); z += spacing) {
      for (double x = b.min.x() + offset; x < b.max.x(); x += spacing) add({x, b.min.y(), z}), add({x, b.max.y(), z});
      for (double y = b.min.y() + offset; y < b.max.y(); y += spacing) add({b.min.x(), y, z}), add({b.max.x(), y, z});
    }
  return out;
}

Eigen::Isometry3d motion(double yaw, const Eigen::Vector3d& axis_tilt, const Eigen::Vector3d& t) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(axis_tilt.norm(), axis_tilt.norm() > 0 ? axis_tilt.normalized() : Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  m.translation() = t;
  return m;
}

// The points in a "scanner frame": x_scanner = truth^-1 x_site.
std::vector<Eigen::Vector3d> into_frame(const std::vector<Eigen::Vector3d>& site, const Eigen::Isometry3d& truth) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : site) out.push_back(truth.inverse() * p);
  return out;
}

double rotation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

TEST(Icp, RecoversRigidMotionOfBoxesOnPlaneFromPerturbedStart) {
  const OrientedPoints target = estimate_normals(boxes_on_plane(0.01, 0.0, 0.0, 1), 0.03);
  const Eigen::Isometry3d truth = motion(0.7, {0.01, -0.02, 0}, {3.0, -2.0, 0.5});
  const auto source = voxel_subsample(into_frame(boxes_on_plane(0.013, 0.004, 0.001, 2), truth), 0.015);
  const Eigen::Isometry3d start = motion(0.03, {0.02, 0.01, 0}, {0.03, -0.02, 0.01}) * truth;  // 3 cm, ~2 degrees
  const IcpSummary fit = register_point_to_plane(source, target, start, IcpOptions{});
  EXPECT_TRUE(fit.converged);
  EXPECT_FALSE(fit.degenerate);
  EXPECT_LT((fit.pose.translation() - truth.translation()).norm(), kTranslationTolerance);
  EXPECT_LT(rotation_error(fit.pose, truth), kRotationTolerance);
  EXPECT_GT(fit.inlier_share, 0.8);
  EXPECT_LT(fit.rms_m, 0.003);  // 1 mm noise, edges of the sampling
  EXPECT_GT(fit.sigma_translation_m, 0);
  EXPECT_LT(fit.sigma_translation_m, kTranslationTolerance);
  EXPECT_LT(fit.sigma_rotation_rad, kRotationTolerance);
}

TEST(Icp, CoarseSearchFindsA120DegreeYaw) {
  const auto site = boxes_on_plane(0.01, 0.0, 0.0, 3);
  const Eigen::Isometry3d truth = motion(2.0 * M_PI / 3.0, Eigen::Vector3d::Zero(), {10.0, 4.0, -1.5});
  const auto source = into_frame(boxes_on_plane(0.012, 0.005, 0.001, 4), truth);
  const CoarseResult coarse = coarse_yaw_search(source, site);
  EXPECT_LT(rotation_error(coarse.pose, truth), kCoarseYawTolerance);
  EXPECT_LT((coarse.pose.translation() - truth.translation()).norm(), 0.05);
  const IcpSummary fit =
      register_point_to_plane(voxel_subsample(source, 0.015), estimate_normals(site, 0.03), coarse.pose, IcpOptions{});
  EXPECT_LT((fit.pose.translation() - truth.translation()).norm(), kTranslationTolerance);
  EXPECT_LT(rotation_error(fit.pose, truth), kRotationTolerance);
}

TEST(Icp, FeaturelessPlaneIsDegenerate) {
  const OrientedPoints target = estimate_normals(boxes_on_plane(0.01, 0.0, 0.0, 5, false), 0.03);
  const Eigen::Isometry3d truth = motion(0.3, Eigen::Vector3d::Zero(), {0.1, 0.2, 0.05});
  const auto source = voxel_subsample(into_frame(boxes_on_plane(0.013, 0.004, 0.001, 6, false), truth), 0.015);
  const IcpSummary fit = register_point_to_plane(source, target, truth, IcpOptions{});
  EXPECT_TRUE(fit.degenerate);
  EXPECT_LT(fit.support_share, IcpOptions{}.min_support_share);
}

// The ground of the boxes scene seen in a tilted frame: the plane found is the ground
// (the boxes' tops and sides are off it), its normal the frame's up to the noise.
TEST(DominantPlane, FindsTheGroundOfATiltedCloud) {
  constexpr double kNormalTolerance = 2e-3;  // radians: 2 mm noise over a 2 m plane is far less
  const std::vector<Eigen::Vector3d> site = boxes_on_plane(0.02, 0.0, 0.002, 5);
  const Eigen::Isometry3d truth = motion(0.7, {0.5, -0.3, 0.0}, {2, -1, 0.5});
  const PlaneFit ground = dominant_plane(into_frame(site, truth), 0.01);
  const Eigen::Vector3d up = truth.linear().transpose() * Eigen::Vector3d::UnitZ();  // site +z in the frame
  EXPECT_LT(std::acos(std::min(1.0, std::abs(ground.normal.dot(up)))), kNormalTolerance);
  EXPECT_GT(ground.inlier_share, 0.6);  // the boxes' tops and sides: the rest
  EXPECT_LT(ground.inlier_share, 0.95);
  EXPECT_NEAR((truth * ground.point).z(), 0.0, 0.005);
}

TEST(Icp, OptionsAreValidated) {
  IcpOptions o;
  o.trim_share = 1.0;
  EXPECT_THROW(register_point_to_plane({}, {}, Eigen::Isometry3d::Identity(), o), std::exception);
}

// The growing model of depth tracking gives the points and normals a full estimate on
// all the frames' means gives, while estimating again only the normals near what a
// frame changed: here the second and third "frames" cover a corner of the first.
TEST(GrowingModel, SameAsAFullEstimateButOnlyNearTheChange) {
  constexpr double kVoxel = 0.015, kRadius = 0.045;
  constexpr double kSameM = 1e-12;       // summation order only
  constexpr double kSameNormal = 1e-9;   // |1 - n1 . n2|
  const std::vector<Eigen::Vector3d> whole = boxes_on_plane(0.01, 0.002, 0.001, 5);
  std::vector<std::vector<Eigen::Vector3d>> frames(3);
  for (const auto& p : whole) {
    frames[0].push_back(p);
    if (p.x() > 0.3 && p.y() > 0.3) frames[1].push_back(p + Eigen::Vector3d(0.003, 0, 0.001));
    if (p.x() < -0.5 && p.y() < -0.5) frames[2].push_back(p + Eigen::Vector3d(0, -0.002, 0.002));
  }
  GrowingModel model(kVoxel, kRadius);
  VoxelMeans means(kVoxel);
  std::size_t full_estimates = 0;
  for (const auto& f : frames) {
    const std::size_t before = model.normals_estimated();
    model.add(f);
    for (const auto& p : f) means.add(p);
    const OrientedPoints full = estimate_normals(means.points(), kRadius);
    full_estimates += means.points().size();
    ASSERT_EQ(model.oriented().points.size(), full.points.size());
    for (std::size_t i = 0; i < full.points.size(); ++i) {
      ASSERT_LT((model.oriented().points[i] - full.points[i]).norm(), kSameM) << i;
      ASSERT_LT(1 - std::abs(model.oriented().normals[i].dot(full.normals[i])), kSameNormal) << i;
    }
    if (&f != &frames[0]) EXPECT_LT(model.normals_estimated() - before, means.points().size() / 2);
  }
  EXPECT_LT(model.normals_estimated(), full_estimates);
}

}  // namespace
}  // namespace strata
