// Self-calibration against what was known of the camera (pipeline/camera_calibration.hpp).
#include "pipeline/camera_calibration.hpp"

#include <gtest/gtest.h>

namespace strata {
namespace {

CameraGroup group(double f, double k1) {
  CameraGroup g;
  g.intrinsics = {4000, 3000, f, f, 1999.5, 1499.5, k1, 0};
  return g;
}

TEST(CalibrationCheck, AFocalFarFromTheExifPriorIsNamed) {
  CameraGroup exif = group(3000, 0);
  exif.focal_from_exif = true;
  const auto checks = check_self_calibration({exif, exif}, {group(3060, -0.02), group(3400, -0.02)});
  ASSERT_EQ(checks.size(), 2u);
  EXPECT_EQ(checks[0].source, "exif");
  EXPECT_NEAR(checks[0].focal_change, 0.02, 1e-12);
  EXPECT_TRUE(checks[0].finding.empty()) << "2 % is within the 5 % tolerance";
  EXPECT_NEAR(checks[1].focal_change, 0.4 / 3, 1e-12);
  EXPECT_NE(checks[1].finding.find("+13.3 %"), std::string::npos) << checks[1].finding;
}

TEST(CalibrationCheck, DistortionAwayFromAKnownCalibrationIsNamed) {
  CameraGroup known = group(3000, -0.05);
  known.calibration_known = true;
  known.calibration_source = "calibration: camera set";
  // k1 -0.05 -> -0.06 at the corner (r^2 = 0.69 in normalised units): about 20 px.
  const auto checks = check_self_calibration({known}, {group(3000, -0.06)});
  ASSERT_EQ(checks.size(), 1u);
  EXPECT_GT(checks[0].corner_shift_px, 10.0);
  EXPECT_NE(checks[0].finding.find("image corner"), std::string::npos);
  EXPECT_TRUE(check_self_calibration({known}, {group(3000, -0.0502)})[0].finding.empty());
}

TEST(CalibrationCheck, WithoutAPriorThereIsNothingToCompare) {
  const auto checks = check_self_calibration({group(3600, 0)}, {group(2760, 0)});
  ASSERT_EQ(checks.size(), 1u);
  EXPECT_EQ(checks[0].prior_focal_px, 0.0);
  EXPECT_TRUE(checks[0].finding.empty());
}

}  // namespace
}  // namespace strata
