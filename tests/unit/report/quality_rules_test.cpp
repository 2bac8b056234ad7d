// Warning rules of the field report on synthetic figures: coverage gaps and the
// side to photograph them from, marker photo counts, RMSE thresholds.
#include "core/error.hpp"
#include "report/coverage.hpp"
#include "report/quality_rules.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace strata {
namespace {

// A GSD comparison only needs to resolve the 0.1 mm steps of the test geometry.
constexpr double kGsdTolerance_m = 1e-6;

// 3 m x 3 m trench at z = 0, 30 x 30 cells of 10 cm, every cell seen by `n` photos.
CoverageMap flat_map(int n) {
  CoverageMap m = coverage_grid(-1.5, 1.5, 0.1, 30, 30, std::vector<float>(900, 0.0f));
  std::fill(m.count.begin(), m.count.end(), n);
  std::fill(m.gsd_m.begin(), m.gsd_m.end(), 0.0005f);
  return m;
}

// Sets the count of every cell whose centre is in [x0, x1] x [y0, y1].
void set_counts(CoverageMap& m, double x0, double x1, double y0, double y1, int n) {
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const double x = m.x_centre(c), y = m.y_centre(r);
      if (x >= x0 && x <= x1 && y >= y0 && y <= y1) m.count[m.index(c, r)] = n;
    }
  }
}

// A ring of cameras around the origin at radius r, leaving out those whose
// bearing (degrees from east, anticlockwise) lies in [skip_from, skip_to].
std::vector<Eigen::Vector2d> ring(double r, int n, double skip_from = 1000, double skip_to = 1000) {
  std::vector<Eigen::Vector2d> out;
  for (int i = 0; i < n; ++i) {
    const double deg = 360.0 * i / n;
    if (deg >= skip_from && deg <= skip_to) continue;
    const double a = deg * std::numbers::pi / 180;
    out.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  return out;
}

LayerFigures good_layer() {
  LayerFigures f;
  f.layer = "L1";
  f.photos = 40;
  f.aligned = true;
  f.registered = 40;
  f.georeferenced = true;
  f.reprojection_rmse_px = 0.6;
  f.control_rmse_m = 0.004;
  f.check_rmse_m = 0.006;
  for (const char* name : {"GCP1", "GCP2", "GCP3", "GCP4"}) {
    f.markers.push_back({name, "control", true, Eigen::Vector3d(0.002, -0.003, 0.004), 0.5, 8});
  }
  f.markers.push_back({"GCP5", "check", true, Eigen::Vector3d(0.003, 0.002, -0.005), 0.6, 7});
  f.dense = f.products = true;
  f.coverage_known = true;
  f.camera_centres = ring(2.5, 16);
  return f;
}

const Finding* find_rule(const std::vector<Finding>& fs, const std::string& rule) {
  for (const auto& f : fs) {
    if (f.rule == rule) return &f;
  }
  return nullptr;
}

TEST(Coverage, SectorNames) {
  EXPECT_EQ(sector_of(2, 2).name, "north-east corner");
  EXPECT_EQ(sector_of(0, 0).name, "south-west corner");
  EXPECT_EQ(sector_of(1, 2).name, "north edge");
  EXPECT_EQ(sector_of(0, 1).name, "west edge");
  EXPECT_EQ(sector_of(1, 1).name, "centre");
  EXPECT_EQ(sector_of(2, 2).sides, (std::vector<std::string>{"east", "north"}));
}

TEST(Coverage, GapInTheNorthEastCornerIsFoundThere) {
  CoverageMap m = flat_map(8);
  set_counts(m, 0.5, 1.5, 0.5, 1.5, 1);  // the whole NE ninth (cells 20-29), one photo
  const auto gaps = find_coverage_gaps(m, 3, 0.10);
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].sector.name, "north-east corner");
  EXPECT_EQ(gaps[0].min_count, 1);
  EXPECT_NEAR(gaps[0].fraction, 1.0, 1e-9);
  EXPECT_GT(gaps[0].centroid.x(), 0.5);
  EXPECT_GT(gaps[0].centroid.y(), 0.5);
}

TEST(Coverage, ThinRimAtTheTrenchEdgeIsNotAGap) {
  // The outermost ring of cells, seen by 2 photos, is normal at the edge of a
  // reconstruction: 1 cell of 10 per sector is below the 10 % share.
  CoverageMap m = flat_map(8);
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      if (r == 0 || c == 0 || r == m.height - 1 || c == m.width - 1) m.count[m.index(c, r)] = 2;
    }
  }
  EXPECT_TRUE(find_coverage_gaps(m, 3, 0.2).empty());
}

TEST(Coverage, CellsOutsideTheAreaAreIgnored) {
  CoverageMap m = flat_map(0);
  // Only the west half is recorded; it is well covered, the east half is not the trench.
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      if (c >= 15) m.z[m.index(c, r)] = NAN;
      else m.count[m.index(c, r)] = 6;
    }
  }
  EXPECT_TRUE(find_coverage_gaps(m, 3, 0.10).empty());
}

TEST(Coverage, SideWithTheThinnerStretchOfTheCameraRing) {
  CoverageMap m = flat_map(8);
  set_counts(m, 0.6, 1.5, 0.6, 1.5, 0);
  const auto gaps = find_coverage_gaps(m, 3, 0.10);
  ASSERT_EQ(gaps.size(), 1u);
  // No camera east of the trench: photograph from the east.
  EXPECT_EQ(side_to_photograph(gaps[0], ring(2.5, 16, -1, 40), {0, 0}), "east");
  EXPECT_EQ(side_to_photograph(gaps[0], ring(2.5, 16, 315, 360), {0, 0}), "east");
  // No camera north of the trench: photograph from the north.
  EXPECT_EQ(side_to_photograph(gaps[0], ring(2.5, 16, 50, 130), {0, 0}), "north");
  // A gap in the middle is photographed from above.
  CoverageMap c = flat_map(8);
  set_counts(c, -0.4, 0.4, -0.4, 0.4, 1);
  const auto centre = find_coverage_gaps(c, 3, 0.10);
  ASSERT_EQ(centre.size(), 1u);
  EXPECT_EQ(centre[0].sector.name, "centre");
  EXPECT_EQ(side_to_photograph(centre[0], ring(2.5, 16), {0, 0}), "");
}

TEST(Coverage, NadirCameraSeesItsFootprintAtItsGsd) {
  CoverageMap m = coverage_grid(-1.5, 1.5, 0.1, 30, 30, std::vector<float>(900, 0.0f));
  Camera cam;
  cam.intrinsics = {1000, 1000, 1000, 1000, 499.5, 499.5, 0, 0};  // 1 m footprint at 2 m height
  cam.pose = Pose::look_at({0, 0, 2}, {0, 0, 0}, Eigen::Vector3d::UnitY());
  count_coverage(m, {cam});
  int seen = 0;
  for (std::size_t i = 0; i < m.count.size(); ++i) {
    if (m.count[i] == 0) continue;
    ++seen;
    EXPECT_NEAR(m.gsd_m[i], 2.0 / 1000, kGsdTolerance_m);
  }
  EXPECT_EQ(seen, 20 * 20);  // footprint 2 m x 2 m (height 2 m, 1000 px at f 1000 px) of 0.1 m cells
  EXPECT_EQ(m.count[m.index(0, 0)], 0);
}

TEST(Coverage, GridFromSparsePointsIgnoresStrayPoints) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 30; ++j) pts.emplace_back(-1 + 2.0 * i / 39, -0.75 + 1.5 * j / 29, 0.1);
  }
  pts.emplace_back(50, 50, 3);  // far outlier
  const CoverageMap m = coverage_grid_from_points(pts, 40);
  ASSERT_GT(m.width, 0);
  EXPECT_LT(m.width * m.cell, 2.1);
  EXPECT_LT(m.height * m.cell, 1.6);
  EXPECT_EQ(m.area_cells(), m.z.size());  // holes filled
  EXPECT_NEAR(m.z[m.index(m.width / 2, m.height / 2)], 0.1, 1e-6);
}

TEST(Rules, GoodLayerHasNoProblemOrWarning) {
  const auto fs = evaluate_layer(good_layer(), {});
  for (const auto& f : fs) EXPECT_EQ(f.severity, Severity::note) << f.message;
}

TEST(Rules, CornerGapTellsWhereAndFromWhichSide) {
  LayerFigures f = good_layer();
  f.camera_centres = ring(2.5, 16, -1, 40);  // nobody stood on the east side
  CoverageMap m = flat_map(8);
  set_counts(m, 0.6, 1.5, 0.6, 1.5, 0);
  f.gaps = find_coverage_gaps(m, 3, 0.10);
  const auto fs = evaluate_layer(f, {});
  const Finding* gap = find_rule(fs, "coverage_gap");
  ASSERT_NE(gap, nullptr);
  EXPECT_EQ(gap->severity, Severity::problem);
  EXPECT_NE(gap->message.find("the north-east corner is seen by fewer than 3 photos"), std::string::npos) << gap->message;
  EXPECT_NE(gap->advice.find("take 4 more photos from the east side"), std::string::npos) << gap->advice;
  EXPECT_EQ(fs.front().severity, Severity::problem);  // most severe first
}

TEST(Rules, MarkerSeenInTooFewPhotos) {
  LayerFigures f = good_layer();
  f.markers.back().images = 2;
  f.markers.back().name = "GCP5";
  const auto fs = evaluate_layer(f, {});
  const Finding* m = find_rule(fs, "marker_photos");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->message, "marker GCP5 seen in only 2 photos");
  // Exactly the threshold is enough.
  f.markers.back().images = QualityThresholds{}.min_marker_photos;
  EXPECT_EQ(find_rule(evaluate_layer(f, {}), "marker_photos"), nullptr);
}

TEST(Rules, CheckRmseOverTheThreshold) {
  LayerFigures f = good_layer();
  f.check_rmse_m = 0.014;
  const auto fs = evaluate_layer(f, {});
  const Finding* c = find_rule(fs, "check_rmse");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->severity, Severity::problem);
  EXPECT_EQ(c->message, "check RMSE 14 mm exceeds 10 mm");
  QualityThresholds loose;
  loose.max_check_rmse_m = 0.015;
  EXPECT_EQ(find_rule(evaluate_layer(f, loose), "check_rmse"), nullptr);
  f.control_rmse_m = 0.012;
  EXPECT_NE(find_rule(evaluate_layer(f, {}), "control_rmse"), nullptr);
}

TEST(Rules, NotGeoreferencedAndTooFewControlMarkers) {
  LayerFigures f = good_layer();
  f.georeferenced = false;
  f.markers.clear();
  auto fs = evaluate_layer(f, {});
  const Finding* g = find_rule(fs, "not_georeferenced");
  ASSERT_NE(g, nullptr);
  EXPECT_EQ(g->severity, Severity::problem);
  EXPECT_NE(g->message.find("layer not georeferenced"), std::string::npos);
  EXPECT_EQ(find_rule(fs, "no_check_markers"), nullptr);  // meaningless without a georeference

  f = good_layer();
  f.markers.erase(f.markers.begin(), f.markers.begin() + 2);  // 2 control markers left
  fs = evaluate_layer(f, {});
  ASSERT_NE(find_rule(fs, "few_control_markers"), nullptr);
}

TEST(Rules, UnalignedPhotosAreNamed) {
  LayerFigures f = good_layer();
  f.unaligned = {"IMG_0007.JPG", "IMG_0012.JPG", "IMG_0031.JPG"};
  f.registered = 37;
  auto fs = evaluate_layer(f, {});
  const Finding* u = find_rule(fs, "unaligned_photos");
  ASSERT_NE(u, nullptr);
  EXPECT_EQ(u->message, "3 photos could not be aligned: IMG_0007.JPG, IMG_0012.JPG, IMG_0031.JPG");
  EXPECT_EQ(u->severity, Severity::note);  // 7.5 % is under the 10 % threshold
  for (int i = 0; i < 3; ++i) f.unaligned.push_back("X" + std::to_string(i));
  EXPECT_EQ(find_rule(evaluate_layer(f, {}), "unaligned_photos")->severity, Severity::problem);
}

TEST(Rules, MissingStagesAreSaidNotCrashed) {
  LayerFigures f;
  f.layer = "L9";
  auto fs = evaluate_layer(f, {});
  ASSERT_EQ(fs.size(), 1u);
  EXPECT_EQ(fs[0].rule, "no_photos");
  f.photos = 5;
  fs = evaluate_layer(f, {});
  ASSERT_NE(find_rule(fs, "not_processed"), nullptr);
  EXPECT_EQ(fs.front().rule, "not_processed");  // the problem before the few-photos warning
  EXPECT_NE(find_rule(fs, "not_processed")->advice.find("strata process DIR --layer L9"), std::string::npos);
}

TEST(Rules, MarkerFarFromItsSurveyAndRejectedMarker) {
  LayerFigures f = good_layer();
  f.markers[1].residual_m = {0.02, 0.015, 0};
  f.markers.push_back({"GCP6", "rejected", true, Eigen::Vector3d(0.2, 0, 0), 1, 6});
  const auto fs = evaluate_layer(f, {});
  ASSERT_NE(find_rule(fs, "marker_residual"), nullptr);
  EXPECT_NE(find_rule(fs, "marker_residual")->message.find("GCP2 is 25 mm"), std::string::npos);
  ASSERT_NE(find_rule(fs, "marker_rejected"), nullptr);
}

// A survey rounded to 0.1 m in plan: each axis carries 0.1 / sqrt(12) = 28.9 mm, 3D
// about 41 mm, which is what the layer is judged against instead of the fixed 10 mm.
LayerFigures layer_on_a_rounded_survey(double control_rmse_m) {
  LayerFigures f = good_layer();
  f.survey_words = "a survey rounded to 0.1 m";
  const double rounding = 0.1 / std::sqrt(12.0);
  for (auto& m : f.markers) {
    m.expected_m = expected_marker_error_m(Eigen::Vector3d::Zero(), rounding, 0.0, m.reprojection_px * 0.001);
    m.residual_m = {0.045, -0.03, 0.01};  // 55 mm: over 20 mm, under twice 41 mm
  }
  f.control_rmse_m = control_rmse_m;
  f.check_rmse_m = 0.05;
  return f;
}

TEST(Rules, ExpectedMarkerErrorCombinesStatedRoundingAndPhotos) {
  EXPECT_DOUBLE_EQ(expected_marker_error_m(Eigen::Vector3d::Zero(), 0, 0, 0), 0);
  // The larger of stated and rounding per axis: plan from the rounding, height stated.
  EXPECT_NEAR(expected_marker_error_m({0.01, 0.01, 0.02}, 0.03, 0, 0), std::sqrt(2 * 0.03 * 0.03 + 0.02 * 0.02), 1e-12);
  EXPECT_NEAR(expected_marker_error_m(Eigen::Vector3d::Zero(), 0, 0, 0.003), 0.003, 1e-12);
  EXPECT_NEAR(expected_marker_error_m(Eigen::Vector3d::Zero(), 0.1 / std::sqrt(12.0), 0, 0), 0.0408, 1e-4);
}

TEST(Rules, RoundedSurveyIsJudgedAgainstWhatItCanDeliver) {
  const auto fs = evaluate_layer(layer_on_a_rounded_survey(0.07), {});
  EXPECT_EQ(find_rule(fs, "control_rmse"), nullptr);
  const Finding* c = find_rule(fs, "control_rmse_survey");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->severity, Severity::warning);
  EXPECT_EQ(c->message,
            "control RMSE 70 mm on a survey rounded to 0.1 m (about 41 mm expected): as close as that survey "
            "allows, but over the 10 mm tolerance");
  EXPECT_EQ(find_rule(fs, "marker_residual"), nullptr) << "55 mm is within what a 0.1 m rounding explains";
  for (const auto& x : fs) EXPECT_NE(x.severity, Severity::problem) << x.rule << ": " << x.message;
}

TEST(Rules, RoundedSurveyStillFailsMarkersThatDisagree) {
  LayerFigures f = layer_on_a_rounded_survey(0.15);
  f.markers[2].residual_m = {0.25, 0.1, 0};
  const auto fs = evaluate_layer(f, {});
  const Finding* c = find_rule(fs, "control_rmse");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->severity, Severity::problem);
  EXPECT_EQ(c->message,
            "control RMSE 150 mm exceeds 10 mm, and more than a survey rounded to 0.1 m explains (about 41 mm "
            "expected)");
  const Finding* m = find_rule(fs, "marker_residual");
  ASSERT_NE(m, nullptr);
  EXPECT_NE(m->message.find("GCP3 is 269 mm"), std::string::npos) << m->message;
  EXPECT_NE(m->message.find("2 times what a survey rounded to 0.1 m explains"), std::string::npos) << m->message;
}

TEST(Rules, UnstatedSurveyKeepsTheFixedTolerance) {
  LayerFigures f = good_layer();
  f.control_rmse_m = 0.012;
  for (auto& m : f.markers) m.expected_m = m.reprojection_px * 0.001;  // photos only: 0.5 mm
  const auto fs = evaluate_layer(f, {});
  const Finding* c = find_rule(fs, "control_rmse");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->message, "control RMSE 12 mm exceeds 10 mm");
}

TEST(Rules, ThresholdsAreValidated) {
  QualityThresholds t;
  t.min_control_markers = 2;
  EXPECT_THROW(t.validate(), InputError);
  EXPECT_NO_THROW(QualityThresholds{}.validate());
}

TEST(Rules, Millimetres) {
  EXPECT_EQ(format_mm(0.014), "14 mm");
  EXPECT_EQ(format_mm(0.0025), "2.5 mm");
}

}  // namespace
}  // namespace strata
