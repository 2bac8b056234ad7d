// Georeferencing synthetic layers onto surveyed markers with known truth.
// World coordinates are site-frame metres (CRS minus the site origin), so the numbers
// stay small as in production.
#include "core/error.hpp"
#include "georef/georeference.hpp"
#include "sfm/incremental.hpp"
#include "unit/sfm/synthetic_scene.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>

namespace strata {
namespace {

using test::make_scene;
using test::SceneMarker;
using test::SceneOptions;
using test::SyntheticScene;

// --- tolerances ------------------------------------------------------------------
// A marker seen in ~8 photos with 0.2 px noise at ~1.5 mm/px triangulates to well
// under 1 mm; the photo block itself is good to about a millimetre: a check marker
// within 5 mm (the acceptance figure) is a real measurement, not luck.
constexpr double kCheckTolM = 0.005;
// Camera centres against the truth after georeferencing (absolute, no alignment).
constexpr double kCentreTolM = 0.005;
// Same input, same arithmetic: a check marker must not change a single bit; the
// tolerance only guards against a multi-threaded reduction order.
constexpr double kIdenticalTol = 1e-12;
// The perturbation applied to one surveyed height in the sigma test, metres.
constexpr double kSurveyBlunderM = 0.03;

// The truth moved into an arbitrary frame, as SfM would deliver it, with a 1 % focal
// error so the adjustment has work to do.
Reconstruction arbitrary_frame(const SyntheticScene& scene) {
  Reconstruction rec = scene.truth_reconstruction();
  Similarity3 s;
  s.scale = 0.37;
  s.R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.5, 1.0).normalized()).toRotationMatrix();
  s.t = Eigen::Vector3d(3.0, -1.0, 12.0);
  transform_reconstruction(s, rec);
  rec.groups[0].intrinsics.fx *= 1.01;
  rec.groups[0].intrinsics.fy *= 1.01;
  return rec;
}

std::vector<MarkerConstraint> only(const SyntheticScene& scene, std::initializer_list<const char*> names) {
  std::vector<MarkerConstraint> out;
  for (const char* n : names) {
    for (const auto& m : scene.markers) {
      if (m.name == n) out.push_back(m);
    }
  }
  return out;
}

const MarkerResidual& row(const GeoreferenceSummary& s, const std::string& name) {
  for (const auto& r : s.residuals) {
    if (r.name == name) return r;
  }
  throw std::runtime_error("no residual row " + name);
}

double max_centre_error(const Reconstruction& rec, const SyntheticScene& scene) {
  double worst = 0;
  for (std::size_t i = 0; i < rec.images.size(); ++i) {
    if (!rec.images[i].registered) continue;
    worst = std::max(worst, (rec.images[i].pose.centre() - scene.poses[i].centre()).norm());
  }
  return worst;
}

const SyntheticScene& scene() {
  static const SyntheticScene s = make_scene({.cameras = 14, .points = 1500});
  return s;
}

TEST(Georeference, ExactlyThreeControlMarkersWork) {
  Reconstruction rec = arbitrary_frame(scene());
  const auto markers = only(scene(), {"C1", "C2", "C3", "K1", "K2"});
  const auto s = georeference({}, markers, scene().marker_observations, scene().keypoints, rec);
  ASSERT_TRUE(s.georeferenced);
  EXPECT_TRUE(rec.georeferenced);
  EXPECT_EQ(s.control_used.size(), 3u);
  EXPECT_TRUE(s.rejected.empty());
  EXPECT_EQ(s.residuals.size(), 5u);
  EXPECT_EQ(s.check.markers, 2u);
  std::printf("[ figures  ] 3 GCP: control rmse %.2f mm, check rmse E %.2f N %.2f Z %.2f 3D %.2f mm, "
              "centres max %.2f mm, K1 reproj %.2f px in %d images\n",
              s.control.xyz * 1e3, s.check.e * 1e3, s.check.n * 1e3, s.check.z * 1e3,
              s.check.xyz * 1e3, max_centre_error(rec, scene()) * 1e3,
              row(s, "K1").reprojection_px, row(s, "K1").images);
  EXPECT_LT(s.check.xyz, kCheckTolM);
  EXPECT_LT(s.control.xyz, kCheckTolM);
  EXPECT_TRUE(row(s, "K1").triangulated);
  EXPECT_EQ(row(s, "K1").role, MarkerRole::check);
  EXPECT_GE(row(s, "K1").images, 2);
  EXPECT_LT(max_centre_error(rec, scene()), kCentreTolM);
  EXPECT_NEAR(rec.groups[0].intrinsics.fx, scene().truth.fx, 0.005 * scene().truth.fx);
}

TEST(Georeference, TwoControlMarkersAreRefusedByName) {
  Reconstruction rec = arbitrary_frame(scene());
  const Reconstruction before = rec;
  const auto markers = only(scene(), {"C1", "C2", "K1"});
  try {
    georeference({}, markers, scene().marker_observations, scene().keypoints, rec);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("at least 3 control markers"), std::string::npos) << msg;
    EXPECT_NE(msg.find("C1"), std::string::npos) << msg;
    EXPECT_NE(msg.find("C2"), std::string::npos) << msg;
  }
  EXPECT_FALSE(rec.georeferenced);
  EXPECT_EQ(rec.images[3].pose.t, before.images[3].pose.t) << "refusal leaves rec unchanged";
}

TEST(Georeference, ThreeCollinearControlMarkersAreRefusedByName) {
  SceneOptions o;
  o.cameras = 10;
  o.points = 800;
  o.markers = {{"L1", {-1.2, -0.6}, true}, {"L2", {0.0, 0.0}, true}, {"L3", {1.2, 0.6}, true}};
  const SyntheticScene line = make_scene(o);
  Reconstruction rec = arbitrary_frame(line);
  try {
    georeference({}, line.markers, line.marker_observations, line.keypoints, rec);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("collinear"), std::string::npos) << msg;
    EXPECT_NE(msg.find("L1, L2, L3"), std::string::npos) << msg;
  }
  EXPECT_FALSE(rec.georeferenced);
}

TEST(Georeference, CheckMarkersNeverChangeTheSolution) {
  Reconstruction with = arbitrary_frame(scene());
  Reconstruction without = with;
  GeoreferenceOptions options;
  options.bundle.num_threads = 1;  // a fixed reduction order
  auto check_moved = only(scene(), {"C1", "C2", "C3", "C4", "K1", "K2"});
  check_moved[4].position.x() += 1.0;  // a check marker badly surveyed: measured, not used
  const auto s_with = georeference(options, check_moved, scene().marker_observations,
                                   scene().keypoints, with);
  const auto s_without = georeference(options, only(scene(), {"C1", "C2", "C3", "C4"}),
                                      scene().marker_observations, scene().keypoints, without);
  for (std::size_t i = 0; i < with.images.size(); ++i) {
    EXPECT_LT((with.images[i].pose.t - without.images[i].pose.t).norm(), kIdenticalTol);
    EXPECT_LT((with.images[i].pose.R - without.images[i].pose.R).norm(), kIdenticalTol);
  }
  EXPECT_EQ(with.groups[0].intrinsics.fx, without.groups[0].intrinsics.fx);
  EXPECT_NEAR(s_with.control.xyz, s_without.control.xyz, kIdenticalTol);
  EXPECT_NEAR(row(s_with, "K1").dE, -1.0, kCheckTolM) << "the residual shows the bad survey";
}

TEST(Georeference, MarkerConstraintsRespectTheirSigmaPerAxis) {
  auto solve = [](double sigma_z) {
    Reconstruction rec = arbitrary_frame(scene());
    auto markers = only(scene(), {"C1", "C2", "C3", "C4"});
    markers[3].position.z() += kSurveyBlunderM;
    markers[3].sigma.z() = sigma_z;
    return georeference({}, markers, scene().marker_observations, scene().keypoints, rec);
  };
  const auto tight = solve(0.002);  // the blunder is trusted: the block bends towards it
  const auto loose = solve(10.0);   // the height is ignored: the photos decide
  const auto& t = row(tight, "C4");
  const auto& l = row(loose, "C4");
  std::printf("[ figures  ] sigma test: C4 dZ tight %.2f mm, loose %.2f mm\n", t.dZ * 1e3, l.dZ * 1e3);
  // Loose: the photo triangulation sits at the true height, 3 cm below the survey.
  EXPECT_NEAR(l.dZ, -kSurveyBlunderM, 0.003);
  // Tight: the blunder is trusted as much as the other markers, so the block tilts
  // and the 3 cm are shared among the four (about 40 % stays on C4 here).
  EXPECT_LT(std::abs(t.dZ), 0.6 * kSurveyBlunderM);
  EXPECT_GT(std::abs(t.dZ), 0.2 * kSurveyBlunderM);
  // E and N keep their 2 mm sigma in both cases.
  EXPECT_LT(std::hypot(l.dE, l.dN), kCheckTolM);
}

TEST(Georeference, GrossOutlierAmongFourIsRejectedAndReported) {
  Reconstruction rec = arbitrary_frame(scene());
  auto markers = only(scene(), {"C1", "C2", "C3", "C4", "K1"});
  markers[2].position += Eigen::Vector3d(0.4, -0.3, 0.2);  // C3 mistyped
  const auto s = georeference({}, markers, scene().marker_observations, scene().keypoints, rec);
  ASSERT_EQ(s.rejected.size(), 1u);
  EXPECT_EQ(s.rejected[0], "C3");
  EXPECT_EQ(row(s, "C3").role, MarkerRole::rejected);
  EXPECT_NEAR(std::hypot(row(s, "C3").dE, row(s, "C3").dN, row(s, "C3").dZ), 0.5385, 0.005);
  EXPECT_LT(s.control.xyz, kCheckTolM);
  EXPECT_LT(s.check.xyz, kCheckTolM);
}

TEST(Georeference, WithoutMarkersTheFrameStaysArbitrary) {
  Reconstruction rec = arbitrary_frame(scene());
  const auto t = rec.images[0].pose.t;
  const auto s = keep_arbitrary_frame(rec);
  EXPECT_FALSE(s.georeferenced);
  EXPECT_FALSE(rec.georeferenced);
  EXPECT_FALSE(s.message.empty());
  EXPECT_EQ(rec.images[0].pose.t, t);
}

TEST(Georeference, OptionsAndSigmasAreValidated) {
  Reconstruction rec = arbitrary_frame(scene());
  GeoreferenceOptions bad;
  bad.outlier_threshold_m = 0;
  EXPECT_THROW(georeference(bad, scene().markers, scene().marker_observations, scene().keypoints, rec),
               InputError);
  auto markers = scene().markers;
  markers[0].sigma.z() = 0;
  EXPECT_THROW(georeference({}, markers, scene().marker_observations, scene().keypoints, rec),
               InputError);
}

// The whole chain on a noisy layer: incremental SfM in an arbitrary frame, then the
// georeference; absolute accuracy against the truth (the acceptance figures).
TEST(Georeference, EndToEndFromIncrementalReconstruction) {
  const SyntheticScene& sc = scene();
  IncrementalSummary sfm;
  Reconstruction rec = reconstruct_incremental({}, sc.groups, sc.images, sc.keypoints, sc.matches, &sfm);
  ASSERT_EQ(sfm.registered, sc.images.size());
  const auto s = georeference({}, sc.markers, sc.marker_observations, sc.keypoints, rec);
  std::printf("[ figures  ] end to end: sfm %.2f s, rmse %.3f px; georef %.2f s, control %.2f mm, "
              "check E %.2f N %.2f Z %.2f 3D %.2f mm, centres max %.2f mm\n",
              sfm.seconds, s.bundle.rmse_px, s.seconds, s.control.xyz * 1e3, s.check.e * 1e3,
              s.check.n * 1e3, s.check.z * 1e3, s.check.xyz * 1e3, max_centre_error(rec, sc) * 1e3);
  EXPECT_EQ(s.check.markers, 2u);
  EXPECT_LT(s.check.xyz, kCheckTolM);
  EXPECT_LT(max_centre_error(rec, sc), kCentreTolM);
  EXPECT_LT(s.bundle.rmse_px, 0.5);
}

}  // namespace
}  // namespace strata
