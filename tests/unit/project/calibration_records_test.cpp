// camera_calibrations (schema 6): round trip at full precision, one per camera,
// validation naming the field, camera references by id or photo name.
#include "core/error.hpp"
#include "project/calibration_records.hpp"
#include "project/project.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

namespace strata {
namespace {

std::string refusal(const Intrinsics& k) {
  try {
    validate_calibration(k, "camera 1");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

Intrinsics brown_lens() {
  Intrinsics k;
  k.width = 640;
  k.height = 428;
  k.model = CameraModel::brown;
  k.fx = 576.123456789012345;
  k.fy = 575.5;
  k.cx = 312.0900972077;
  k.cy = 214.5645972653;
  k.k1 = -0.0643336925816;
  k.k2 = 0.0168255203379;
  k.k3 = -0.0012;
  k.p1 = 3.1e-4;
  k.p2 = -1.7e-4;
  return k;
}

class CalibrationRecords : public ::testing::Test {
 protected:
  void SetUp() override {
    scratch_ = std::make_unique<test::ScratchDir>("calrec");
    project_ = std::make_unique<Project>(Project::create(scratch_->path() / "site", {"EPSG:32636", "", std::nullopt}));
    Transaction tx(db());
    insert_unit(db(), {0, "101", "deposit", ""});
    const auto layer = insert_layer(db(), {0, "L1", "101", std::nullopt});
    CameraRecord cam;
    cam.make = "Make";
    cam.model = "Model";
    cam.width = 640;
    cam.height = 428;
    camera_ = find_or_insert_camera(db(), cam);
    ImageRecord im;
    im.layer_id = layer;
    im.name = "IMG_0001.JPG";
    im.sha256 = "00";
    im.media_path = "media/00/00.jpg";
    im.width = 640;
    im.height = 428;
    im.camera_id = camera_;
    insert_image(db(), im);
    tx.commit();
  }
  Database& db() { return project_->db(); }

  std::unique_ptr<test::ScratchDir> scratch_;
  std::unique_ptr<Project> project_;
  std::int64_t camera_ = 0;
};

TEST_F(CalibrationRecords, RoundTripIsExactAndOnePerCamera) {
  EXPECT_FALSE(find_calibration(db(), camera_).has_value());
  upsert_calibration(db(), {camera_, brown_lens(), true, "camera set", ""});
  auto c = find_calibration(db(), camera_);
  ASSERT_TRUE(c.has_value());
  const Intrinsics a = brown_lens(), &b = c->intrinsics;
  EXPECT_EQ(b.model, a.model);
  EXPECT_EQ(b.width, a.width);
  EXPECT_EQ(b.height, a.height);
  // REAL columns hold doubles: bit for bit, as a fixed calibration needs.
  for (auto [x, y] : {std::pair{a.fx, b.fx}, {a.fy, b.fy}, {a.cx, b.cx}, {a.cy, b.cy}, {a.k1, b.k1},
                      {a.k2, b.k2}, {a.k3, b.k3}, {a.k4, b.k4}, {a.p1, b.p1}, {a.p2, b.p2}}) {
    EXPECT_EQ(x, y);
  }
  EXPECT_TRUE(c->fixed);
  EXPECT_EQ(c->source, "camera set");
  EXPECT_EQ(c->set_at.size(), 20u);  // 2026-12-01T21:40:00Z

  Intrinsics other = brown_lens();
  other.fx = 600;
  upsert_calibration(db(), {camera_, other, false, "layer L1", ""});
  EXPECT_EQ(list_calibrations(db()).size(), 1u);
  EXPECT_EQ(find_calibration(db(), camera_)->intrinsics.fx, 600);
  EXPECT_TRUE(delete_calibration(db(), camera_));
  EXPECT_FALSE(delete_calibration(db(), camera_));
  EXPECT_TRUE(list_calibrations(db()).empty());
}

TEST_F(CalibrationRecords, ValidationNamesTheField) {
  EXPECT_EQ(refusal(brown_lens()), "(accepted)");
  Intrinsics k = brown_lens();
  k.fx = 0;
  EXPECT_EQ(refusal(k), "camera 1: focal length fx = 0 px must be positive");
  k = brown_lens();
  k.cx = 640;
  EXPECT_EQ(refusal(k), "camera 1: principal point cx = 640 px is outside the 640 px wide image");
  k = brown_lens();
  k.cy = -0.5;  // the outer edge of the first pixel row is still inside
  EXPECT_EQ(refusal(k), "(accepted)");
  k = brown_lens();
  k.k4 = 0.01;
  EXPECT_NE(refusal(k).find("camera 1: k4 = 0.01 but the brown model has no k4"), std::string::npos);
  k = brown_lens();
  k.model = CameraModel::radial;
  EXPECT_NE(refusal(k).find("k3 = -0.0012 but the radial model has no k3"), std::string::npos);
  k.model = CameraModel::fisheye;
  EXPECT_NE(refusal(k).find("p1 = 0.00031 but the fisheye model has no p1"), std::string::npos);
  k = brown_lens();
  k.k2 = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(refusal(k), "camera 1: k2 = nan is not a finite number");
}

TEST_F(CalibrationRecords, CameraByIdOrPhotoName) {
  EXPECT_EQ(resolve_camera(db(), std::to_string(camera_)).id, camera_);
  EXPECT_EQ(resolve_camera(db(), "IMG_0001.JPG").id, camera_);
  EXPECT_THROW(resolve_camera(db(), "99"), InputError);
  EXPECT_THROW(resolve_camera(db(), "IMG_0002.JPG"), InputError);
  EXPECT_EQ(list_cameras(db()).size(), 1u);
}

}  // namespace
}  // namespace strata
