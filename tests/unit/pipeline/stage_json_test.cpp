// The stage results as JSON: every field written is read back, records of earlier
// versions (missing keys) read as defaults, and the keys are the ones users and
// scripts read from `process --json`.
#include "pipeline/stage_json.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace strata {
namespace {

AlignmentQuality sample_alignment() {
  AlignmentQuality q;
  q.layer = "L1";
  q.images_total = 40;
  q.sparse.registered_images = 39;
  q.sparse.points = 12345;
  q.sparse.reprojection_rmse_px = 0.61;
  q.sparse.gsd_m = 0.0009;
  q.unregistered = {"IMG_0040.JPG"};
  CameraFigures c;
  c.camera_id = 7;
  c.intrinsics.model = CameraModel::brown;
  c.intrinsics.width = 2400;
  c.intrinsics.fx = 2100.5;
  c.intrinsics.p1 = 1e-4;
  c.lens.source = "focal_35mm";
  c.lens.focal_35mm = 24.0;
  q.cameras = {c};
  FocalSearchSummary fs;
  fs.groups = {0};
  fs.attempts = {{1.2, {2880}, 0, std::numeric_limits<double>::infinity(), {}, "no initial pair", false},
                 {0.8, {1920}, 39, 0.55, {1950}, "", true}};
  q.focal_search = fs;
  q.georeferenced = true;
  q.control_rmse = {0.003, 0.004, 0.005, 0.005, 0.0071, 4, 4};
  q.check_rmse = {0.006, 0.008, 0.009, 0.01, 0.0135, 1, 1};
  MarkerResidual m;
  m.name = "GCP3";
  m.role = MarkerRole::check;
  m.triangulated = true;
  m.dE = 0.002;
  m.distance_misfit_m = std::numeric_limits<double>::quiet_NaN();
  m.loo = true;
  m.loo_dZ = -0.004;
  m.observations = {{3, "IMG_0003.JPG", 0.4, 0.9, 0.5, false}};
  q.markers = {m};
  q.blunders = {{"GCP5", "", 0.21, "m", "rejected"}, {"GCP2", "IMG_0009.JPG", 14.0, "px", "dropped"}};
  q.georeference_message = "fine";
  q.timings.total_s = 41;
  return q;
}

TEST(StageJson, AlignmentRoundTrips) {
  const AlignmentQuality q = sample_alignment();
  const nlohmann::json j = to_json(q);
  const AlignmentQuality back = alignment_quality_from_json(nlohmann::json::parse(j.dump()));
  EXPECT_EQ(to_json(back).dump(), j.dump());
  EXPECT_EQ(back.markers.at(0).role, MarkerRole::check);
  EXPECT_TRUE(std::isnan(back.markers[0].distance_misfit_m));
  EXPECT_TRUE(back.markers[0].loo);
  EXPECT_DOUBLE_EQ(back.markers[0].loo_dZ, -0.004);
  EXPECT_EQ(back.cameras.at(0).intrinsics.model, CameraModel::brown);
  EXPECT_EQ(*back.cameras[0].camera_id, 7);
  EXPECT_TRUE(back.blunders.at(0).image.empty());
  EXPECT_EQ(back.quoted_rmse(), &back.check_rmse);
}

TEST(StageJson, AlignmentKeysAsUsersReadThem) {
  const nlohmann::json j = to_json(sample_alignment());
  EXPECT_EQ(j["images_registered"], 39);
  EXPECT_DOUBLE_EQ(j["check_rmse"]["xyz_m"].get<double>(), 0.0135);
  EXPECT_EQ(j["markers"][0]["marker"], "GCP3");
  EXPECT_EQ(j["markers"][0]["role"], "check");
  EXPECT_DOUBLE_EQ(j["markers"][0]["leave_one_out"]["dZ"].get<double>(), -0.004);
  EXPECT_EQ(j["markers"][0]["observations"][0]["image"], "IMG_0003.JPG");
  EXPECT_TRUE(j["blunders"][0]["image"].is_null()) << "a whole marker: no photo";
  EXPECT_EQ(j["cameras"][0]["model_source"], "focal_35mm");
  EXPECT_TRUE(j["cameras"][0].contains("p1")) << "Brown: the tangential terms";
  EXPECT_FALSE(j["cameras"][0].contains("k4")) << "k4 is the fisheye model's";
  EXPECT_TRUE(j["focal_search"]["attempts"][0]["failure"].is_string());
  EXPECT_TRUE(j["focal_search"]["attempts"][1]["failure"].is_null());
  EXPECT_EQ(nlohmann::json::parse(j.dump())["focal_search"]["attempts"][0]["rmse_px"], nullptr)
      << "infinity is not JSON";
  EXPECT_FALSE(j["timings"].contains("targets_s")) << "no coded targets were looked for";
}

TEST(StageJson, EarlierRecordsReadAsDefaults) {
  const AlignmentQuality q = alignment_quality_from_json(
      {{"layer", "L2"}, {"georeferenced", true}, {"check_rmse", {{"xyz_m", 0.02}, {"markers", 2}}}});
  EXPECT_EQ(q.layer, "L2");
  EXPECT_TRUE(q.cameras.empty());
  EXPECT_FALSE(q.focal_search.has_value());
  EXPECT_EQ(q.check_rmse.markers, 2u);
  EXPECT_EQ(q.control_rmse.markers, 0u);
  EXPECT_EQ(alignment_quality_from_json(nlohmann::json::array()).layer, "") << "not an object: defaults";
}

TEST(StageJson, ProductsRoundTrip) {
  ProductsQuality q;
  q.layer = "L1";
  q.dtm.path = "products/L1/dtm.tif";
  q.dtm.cell_m = 0.005;
  q.dtm.sigma = DtmSigmaFigures{"products/L1/dtm_sigma.tif", 0.0012, 0.004};
  OrthoMarkerCheckFigures check;
  check.tolerance_px = 2;
  OrthoMarkerFigures seen;
  seen.marker = "GCP1";
  seen.status = OrthoMarkerStatus::detected;
  seen.offset_px = 0.7;
  OrthoMarkerFigures unseen;
  unseen.marker = "GCP2";
  unseen.status = OrthoMarkerStatus::coarse;
  unseen.source_pixel_mm = 3.5;
  check.markers = {seen, unseen};
  q.ortho_markers = check;
  const nlohmann::json j = to_json(q);
  EXPECT_TRUE(j["ortho"].is_null()) << "no photos, no orthophoto";
  EXPECT_EQ(j["ortho_markers"]["markers"][1]["status"], "coarse");
  EXPECT_FALSE(j["ortho_markers"]["markers"][1].contains("offset_px")) << "offsets only when detected";
  EXPECT_FALSE(j["steps"].contains("gpkg_rasters"));
  const ProductsQuality back = products_quality_from_json(nlohmann::json::parse(j.dump()));
  EXPECT_EQ(to_json(back).dump(), j.dump());
  ASSERT_TRUE(back.dtm.sigma.has_value());
  EXPECT_DOUBLE_EQ(back.dtm.sigma->p95_m, 0.004);
  EXPECT_FALSE(back.ortho.has_value());
  EXPECT_EQ(back.ortho_markers->markers.at(0).status, OrthoMarkerStatus::detected);
}

}  // namespace
}  // namespace strata
