// The orthophoto marker check (docs/products.md): ArUco targets rendered into a small
// synthetic orthophoto at known places are found, their centres turned into map
// coordinates, and compared with the surveyed positions; a target whose survey is
// off by a few pixels is reported as off, markers off the grid, under unseen cells
// or simply absent are listed as such.
#include "core/error.hpp"
#include "products/ortho_markers.hpp"

#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <random>

namespace strata {
namespace {

constexpr double kCell = 0.005;        // metres: orthophoto cell
constexpr int kWidth = 240, kHeight = 180;  // cells
constexpr double kXMin = 10.0, kYMax = 20.0;  // metres, site frame
constexpr int kCodeCellPx = 5;         // 6 code cells (4x4 + border) = 30 px = 15 cm, as in the field
// A target rendered exactly (bilinear placement, 8-bit) is found to within a
// quarter pixel by corner refinement on the upsampled orthophoto.
constexpr double kCentreTolerancePx = 0.25;
// Detected minus surveyed position of the 'shifted' marker (its survey is wrong).
constexpr double kOffsetEastPx = 3.0, kOffsetNorthPx = -2.0;
// Share of a target's cells left unseen in the speckle test, and the centre
// tolerance there (filled cells approximate the lost ones).
constexpr double kSpeckleShare = 0.12;
constexpr double kSpeckleCentreTolerancePx = 0.25;
// A target found in a tile is placed where the whole-image search places it, up to
// the bicubic enlargement's edge effects of the crop: well under a tenth of a pixel.
constexpr double kTileAgreementPx = 0.05;

// Site-frame E, N of orthophoto pixel (u, v), pixel-centre convention.
Eigen::Vector2d map_of(double u, double v) { return {kXMin + (u + 0.5) * kCell, kYMax - (v + 0.5) * kCell}; }

class OrthoMarkers : public ::testing::Test {
 protected:
  void SetUp() override {
    ortho_.grid.x_min = kXMin;
    ortho_.grid.y_max = kYMax;
    ortho_.grid.cell = kCell;
    ortho_.grid.width = kWidth;
    ortho_.grid.height = kHeight;
    // Soil-like noise, and a block of cells no photo saw (alpha 0) at the right.
    grey_ = cv::Mat(kHeight, kWidth, CV_8UC1);
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0, 12);
    for (int r = 0; r < kHeight; ++r)
      for (int c = 0; c < kWidth; ++c)
        grey_.at<std::uint8_t>(r, c) = cv::saturate_cast<std::uint8_t>(110 + 20 * std::sin(0.15 * c + 0.1 * r) + noise(rng));
  }

  // Renders target `id` (white margin of one code cell) with its centre at pixel (u, v).
  void render(int id, double u, double v) {
    const int side = 6 * kCodeCellPx, patch = side + 2 * kCodeCellPx;
    cv::Mat code;
    cv::aruco::drawMarker(cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50), id, side, code, 1);
    cv::Mat white(patch, patch, CV_8UC1, cv::Scalar(255));
    code.copyTo(white(cv::Rect(kCodeCellPx, kCodeCellPx, side, side)));
    const double centre = 0.5 * (patch - 1);  // of the patch, pixel-centre convention
    const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, u - centre, 0, 1, v - centre);
    cv::Mat warped, mask;
    cv::warpAffine(white, warped, shift, grey_.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::warpAffine(cv::Mat(patch, patch, CV_8UC1, cv::Scalar(255)), mask, shift, grey_.size(), cv::INTER_LINEAR,
                   cv::BORDER_CONSTANT, cv::Scalar(0));
    for (int r = 0; r < kHeight; ++r)
      for (int c = 0; c < kWidth; ++c) {
        const double a = mask.at<std::uint8_t>(r, c) / 255.0;
        // `warped` is already weighted by the coverage (black outside the patch).
        grey_.at<std::uint8_t>(r, c) =
            cv::saturate_cast<std::uint8_t>((1 - a) * grey_.at<std::uint8_t>(r, c) + warped.at<std::uint8_t>(r, c));
      }
  }

  // The RGBA orthophoto: brownish colour from the grey, alpha 0 for columns >= unseen_from.
  RgbaRaster finish(int unseen_from) {
    ortho_.rgba.assign(4 * ortho_.grid.cells(), 0);
    for (int r = 0; r < kHeight; ++r)
      for (int c = 0; c < kWidth; ++c) {
        const int g = grey_.at<std::uint8_t>(r, c);
        std::uint8_t* p = &ortho_.rgba[4 * ortho_.grid.index(c, r)];
        if (c >= unseen_from) continue;
        p[0] = cv::saturate_cast<std::uint8_t>(g * 1.05);
        p[1] = std::uint8_t(g);
        p[2] = cv::saturate_cast<std::uint8_t>(g * 0.85);
        p[3] = 255;
      }
    return ortho_;
  }

  RgbaRaster ortho_;
  cv::Mat grey_;
};

const OrthoMarkerOffset& find(const OrthoMarkerCheck& c, const std::string& name) {
  for (const auto& m : c.markers)
    if (m.name == name) return m;
  throw std::runtime_error("no marker " + name);
}

TEST_F(OrthoMarkers, FindsTargetsAndFlagsTheShiftedOne) {
  // GCP1 exactly where surveyed (sub-pixel place); GCP2 rendered 3 px east and
  // 2 px south of its survey; target 9 names no surveyed marker.
  const double u1 = 50.3, v1 = 60.7, u2 = 140.6, v2 = 110.2;
  render(1, u1, v1);
  render(2, u2, v2);
  render(9, 95.0, 40.0);
  const RgbaRaster ortho = finish(200);

  std::vector<SurveyedMarker> survey;
  auto add = [&](const std::string& name, const Eigen::Vector2d& en, const std::string& kind) {
    survey.push_back({name, Eigen::Vector3d(en.x(), en.y(), 0.3), kind});
  };
  add("GCP1", map_of(u1, v1), "control");
  add("GCP2", map_of(u2 - kOffsetEastPx, v2 + kOffsetNorthPx), "check");  // rows grow southwards
  add("GCP3", map_of(-40, 20), "control");    // west of the grid
  add("GCP4", map_of(220, 90), "control");    // in the unseen block
  add("GCP5", map_of(60, 150), "control");    // coloured, but no target there
  add("GCP6", map_of(196, 60), "control");    // coloured centre, unseen block 4 cells east

  const OrthoMarkerCheck check = check_ortho_markers(ortho, survey, OrthoMarkerCheckOptions{});
  ASSERT_EQ(check.markers.size(), 6u);
  for (const auto& m : check.markers) {
    std::printf("%s %s: dE %.2f px, dN %.2f px, offset %.2f px\n", m.name.c_str(), to_string(m.status),
                m.de_m / kCell, m.dn_m / kCell, m.offset_px);
  }
  const auto& m1 = find(check, "GCP1");
  ASSERT_EQ(m1.status, OrthoMarkerStatus::detected);
  EXPECT_EQ(m1.detections, 1);
  EXPECT_LT(m1.offset_px, kCentreTolerancePx);
  EXPECT_NEAR(m1.detected.x(), map_of(u1, v1).x(), kCentreTolerancePx * kCell);

  const auto& m2 = find(check, "GCP2");
  ASSERT_EQ(m2.status, OrthoMarkerStatus::detected);
  EXPECT_NEAR(m2.de_m / kCell, kOffsetEastPx, kCentreTolerancePx);
  EXPECT_NEAR(m2.dn_m / kCell, kOffsetNorthPx, kCentreTolerancePx);
  EXPECT_NEAR(m2.offset_px, std::hypot(kOffsetEastPx, kOffsetNorthPx), kCentreTolerancePx);
  EXPECT_NEAR(m2.offset_m, m2.offset_px * kCell, 1e-12);

  EXPECT_EQ(find(check, "GCP3").status, OrthoMarkerStatus::outside);
  EXPECT_EQ(find(check, "GCP4").status, OrthoMarkerStatus::not_seen);
  EXPECT_EQ(find(check, "GCP5").status, OrthoMarkerStatus::not_detected);
  EXPECT_EQ(find(check, "GCP6").status, OrthoMarkerStatus::partly_seen);
  EXPECT_EQ(check.unknown_ids, std::vector<int>{9});

  EXPECT_EQ(check.detected, 2);
  EXPECT_EQ(check.over_tolerance, 1);  // GCP2 is more than 2 px off
  EXPECT_DOUBLE_EQ(check.max_px, m2.offset_px);
  EXPECT_NEAR(check.rmse_px, std::sqrt(0.5 * (m1.offset_px * m1.offset_px + m2.offset_px * m2.offset_px)), 1e-9);
  EXPECT_NEAR(check.rmse_m, check.rmse_px * kCell, 1e-12);
}

TEST_F(OrthoMarkers, AMissedMarkerWherePhotosAreCoarserThanTheCellIsCoarse) {
  // No target anywhere; the west half was coloured from photos with 2-cell pixels
  // (seen from afar at a grazing angle), the east half from 0.5-cell pixels.
  const RgbaRaster ortho = finish(kWidth);
  std::vector<float> pixel(ortho.grid.cells());
  for (int r = 0; r < ortho.grid.height; ++r)
    for (int c = 0; c < ortho.grid.width; ++c)
      pixel[ortho.grid.index(c, r)] = float((c < ortho.grid.width / 2 ? 2.0 : 0.5) * kCell);
  const double west = 0.25 * kWidth, east = 0.75 * kWidth, middle = 0.5 * kHeight;
  const std::vector<SurveyedMarker> survey{
      {"GCP1", Eigen::Vector3d(map_of(west, middle).x(), map_of(west, middle).y(), 0), "control"},
      {"GCP2", Eigen::Vector3d(map_of(east, middle).x(), map_of(east, middle).y(), 0), "control"}};
  const OrthoMarkerCheck with = check_ortho_markers(ortho, survey, OrthoMarkerCheckOptions{}, &pixel);
  EXPECT_EQ(with.markers[0].status, OrthoMarkerStatus::coarse);
  EXPECT_NEAR(with.markers[0].source_pixel_m, 2 * kCell, 1e-9);
  EXPECT_EQ(with.markers[1].status, OrthoMarkerStatus::not_detected);
  EXPECT_NEAR(with.markers[1].source_pixel_m, 0.5 * kCell, 1e-9);
  // Without the pixel sizes a miss is never excused.
  const OrthoMarkerCheck without = check_ortho_markers(ortho, survey, OrthoMarkerCheckOptions{});
  EXPECT_EQ(without.markers[0].status, OrthoMarkerStatus::not_detected);
  EXPECT_TRUE(std::isnan(without.markers[0].source_pixel_m));
}

TEST_F(OrthoMarkers, TilesFindTargetsAcrossTheirEdgesOnce) {
  // Tiles of 64 cells with a 20 cm (40-cell) margin: GCP1 straddles the edge at
  // column 64, GCP2 the corner at (128, 128), GCP3 lies inside one tile. Each must be
  // found once, where the whole-image search finds it.
  const std::vector<std::pair<int, Eigen::Vector2d>> targets = {
      {1, {63.6, 40.2}}, {2, {127.8, 128.3}}, {3, {190.4, 60.7}}};
  std::vector<SurveyedMarker> survey;
  for (const auto& [id, uv] : targets) {
    render(id, uv.x(), uv.y());
    const Eigen::Vector2d en = map_of(uv.x(), uv.y());
    survey.push_back({"GCP" + std::to_string(id), Eigen::Vector3d(en.x(), en.y(), 0), "control"});
  }
  const RgbaRaster ortho = finish(kWidth);
  const OrthoMarkerCheck whole = check_ortho_markers(ortho, survey, OrthoMarkerCheckOptions{});
  OrthoMarkerCheckOptions tiled_options;
  tiled_options.tile_cells = 64;
  tiled_options.tile_margin_m = 0.2;
  const OrthoMarkerCheck tiled = check_ortho_markers(ortho, survey, tiled_options);
  for (std::size_t k = 0; k < targets.size(); ++k) {
    ASSERT_EQ(whole.markers[k].status, OrthoMarkerStatus::detected) << whole.markers[k].name;
    ASSERT_EQ(tiled.markers[k].status, OrthoMarkerStatus::detected) << tiled.markers[k].name;
    EXPECT_EQ(tiled.markers[k].detections, 1) << tiled.markers[k].name;
    EXPECT_EQ(tiled.markers[k].scales, whole.markers[k].scales) << tiled.markers[k].name;
    EXPECT_LT(tiled.markers[k].offset_px, kCentreTolerancePx) << tiled.markers[k].name;
    EXPECT_NEAR(tiled.markers[k].detected.x(), whole.markers[k].detected.x(), kTileAgreementPx * kCell);
    EXPECT_NEAR(tiled.markers[k].detected.y(), whole.markers[k].detected.y(), kTileAgreementPx * kCell);
  }
}

TEST_F(OrthoMarkers, ANamingRuleMapsIdsToMarkers) {
  render(4, 80.4, 90.1);
  const RgbaRaster ortho = finish(kWidth);
  OrthoMarkerCheckOptions o;
  o.naming.rule = "T{id:02}";
  const std::vector<SurveyedMarker> survey{{"T04", Eigen::Vector3d(map_of(80.4, 90.1).x(), map_of(80.4, 90.1).y(), 0), "check"},
                                           {"GCP4", Eigen::Vector3d(map_of(80.4, 90.1).x(), map_of(80.4, 90.1).y(), 0), "control"}};
  const OrthoMarkerCheck check = check_ortho_markers(ortho, survey, o);
  EXPECT_EQ(check.markers[0].status, OrthoMarkerStatus::detected);
  EXPECT_LT(check.markers[0].offset_px, kCentreTolerancePx);
  EXPECT_EQ(check.markers[1].status, OrthoMarkerStatus::not_detected);
}

TEST_F(OrthoMarkers, SpeckleHolesOnATargetDoNotHideIt) {
  // A target whose cells are 12 % unseen (single alpha-0 cells, as where a noisy
  // surface hides a cell from every photo): the holes are filled from their
  // neighbours for detection, and it is found in its true place. (On this clean
  // rendered target flat grey holes are tolerated too; on the field ortho of L1
  // the filling moved GCP8 from 1.11 to 0.49 px of its survey.)
  const double u = 100.4, v = 80.6;
  render(3, u, v);
  RgbaRaster ortho = finish(kWidth);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uni(0, 1);
  int holes = 0;
  for (int r = int(v) - 22; r <= int(v) + 22; ++r)
    for (int c = int(u) - 22; c <= int(u) + 22; ++c)
      if (uni(rng) < kSpeckleShare) {
        ortho.rgba[4 * ortho.grid.index(c, r) + 3] = 0;
        ++holes;
      }
  ASSERT_GT(holes, 60);
  const std::vector<SurveyedMarker> survey{{"GCP3", Eigen::Vector3d(map_of(u, v).x(), map_of(u, v).y(), 0), "control"}};
  const OrthoMarkerCheck filled = check_ortho_markers(ortho, survey, OrthoMarkerCheckOptions{});
  ASSERT_EQ(filled.markers[0].status, OrthoMarkerStatus::detected);
  EXPECT_LT(filled.markers[0].offset_px, kSpeckleCentreTolerancePx);

}

TEST(OrthoMarkerOptions, RejectsBadValues) {
  OrthoMarkerCheckOptions o;
  o.tolerance_px = 0;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.upsample = {};
  EXPECT_THROW(o.validate(), InputError);
  o.upsample = {2, 9};
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.coverage_radius_m = -0.1;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.fill_holes_max_cells = -1;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.max_source_pixel_cells = 0;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.tile_cells = 10;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.tile_margin_m = 0;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.targets.dictionary = "DICT_9X9";
  EXPECT_THROW(o.validate(), InputError);
  EXPECT_NO_THROW(OrthoMarkerCheckOptions{}.validate());
}

}  // namespace
}  // namespace strata
