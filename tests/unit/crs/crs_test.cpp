#include "core/error.hpp"
#include "crs/crs.hpp"

#include <GeographicLib/UTMUPS.hpp>
#include <gtest/gtest.h>

namespace strata {
namespace {

// PROJ and GeographicLib both implement Karney's Transverse Mercator series;
// they agree far below survey precision.
constexpr double kAgreementMetres = 1e-3;

TEST(Crs, DescribesWhatSurveyorsWrite) {
  EXPECT_EQ(describe_crs("EPSG:32636").code, 32636);
  EXPECT_EQ(describe_crs("32636").code, 32636);
  EXPECT_EQ(describe_crs("WGS84 UTM 11N").code, 32611);
  EXPECT_EQ(describe_crs("WGS84 UTM 33S").code, 32733);
  const CrsInfo proj = describe_crs("+proj=utm +zone=11 +ellps=WGS84 +datum=WGS84 +units=m +no_defs");
  EXPECT_EQ(proj.code, 32611);
  EXPECT_TRUE(proj.projected);
  EXPECT_TRUE(proj.metres);
  EXPECT_THROW(describe_crs("EPSG:999999"), CrsError);
  EXPECT_THROW(describe_crs("no such thing"), CrsError);
}

TEST(Crs, SiteCrsMustBeProjectedInMetres) {
  EXPECT_NO_THROW(require_site_crs(describe_crs("EPSG:32636")));
  EXPECT_THROW(require_site_crs(describe_crs("EPSG:4326")), CrsError);
  EXPECT_THROW(require_site_crs(describe_crs("EPSG:2263")), CrsError);  // US survey feet
}

TEST(Crs, LonLatToUtmAgreesWithGeographicLib) {
  const double lat = 37.7012345, lon = 35.6543210;  // central Anatolia, UTM zone 36N
  int zone;
  bool north;
  double x, y;
  GeographicLib::UTMUPS::Forward(lat, lon, zone, north, x, y, 36);
  const CrsTransform t("EPSG:4326", "EPSG:32636");
  const Eigen::Vector3d p = t.apply({lon, lat, 1450.0});
  EXPECT_NEAR(p.x(), x, kAgreementMetres);
  EXPECT_NEAR(p.y(), y, kAgreementMetres);
  EXPECT_DOUBLE_EQ(p.z(), 1450.0);
}

}  // namespace
}  // namespace strata
