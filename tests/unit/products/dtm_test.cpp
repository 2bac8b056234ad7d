// DTM from a level set of a known analytic surface; GeoTIFF georeferencing as
// gdalinfo would report it (CRS, geotransform, nodata, COG layout).
#include "crs/crs.hpp"
#include "support/level_set_fixture.hpp"
#include "products/dtm.hpp"
#include "products/raster_io.hpp"
#include "support/test_support.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000.0, 4174000.0, 1450.0);
constexpr double kVoxel = 0.005;        // metres, level-set voxel
constexpr double kCell = 0.01;          // metres, DTM cell
// Trilinear zero crossing of a 5 mm level set of a gently curved surface: a
// fraction of a millimetre; 1 mm leaves room for the z - h distance approximation.
constexpr double kMedianTolerance = 0.001;  // metres
constexpr double kMaxTolerance = 0.003;     // metres

double analytic(double x, double y) { return 0.08 * std::sin(2.0 * x) * std::cos(1.5 * y) + 0.02 * x; }

TEST(Dtm, FromLevelSetOfAnalyticSurface) {
  test::ScratchDir dir("products_dtm_levelset");
  const auto vdb = dir / "surface.vdb";
  test::write_height_field_level_set(vdb, analytic, -0.6, -0.4, 0.6, 0.4, kVoxel, 4 * kVoxel, kOrigin);
  DtmOptions o;
  o.cell_m = kCell;
  const Dtm dtm = build_dtm(vdb, o);
  // Grid edges on whole cells of the site frame.
  EXPECT_NEAR(std::remainder(dtm.grid.x_min, kCell), 0.0, 1e-9);
  EXPECT_NEAR(std::remainder(dtm.grid.y_max, kCell), 0.0, 1e-9);
  EXPECT_LE(dtm.grid.x_min, -0.6 + 1e-9);
  EXPECT_GE(dtm.grid.x_max(), 0.6 - 1e-9);
  std::vector<double> err;
  for (int r = 0; r < dtm.grid.height; ++r) {
    for (int c = 0; c < dtm.grid.width; ++c) {
      if (!dtm.valid(c, r)) continue;
      err.push_back(std::abs(dtm.at(c, r) - analytic(dtm.grid.x_centre(c), dtm.grid.y_centre(r))));
    }
  }
  ASSERT_GT(err.size(), std::size_t(0.8 * 120 * 80));  // nearly all cells of the 1.2 x 0.8 m box
  std::sort(err.begin(), err.end());
  EXPECT_LT(err[err.size() / 2], kMedianTolerance);
  EXPECT_LT(err.back(), kMaxTolerance);
  // North-up: the first row is the northern edge (y_max), heights follow y.
  const int c = dtm.grid.width / 2;
  EXPECT_NEAR(dtm.at(c, 5), analytic(dtm.grid.x_centre(c), dtm.grid.y_centre(5)), kMaxTolerance);
}

TEST(Dtm, Statistics) {
  Dtm d;
  d.grid = {0, 1, 0.5, 2, 2};
  d.z = {1.f, 2.f, std::nanf(""), 3.f};
  const DtmStatistics s = dtm_statistics(d, 100.0);
  EXPECT_EQ(s.valid_cells, 3u);
  EXPECT_DOUBLE_EQ(s.min, 101.0);
  EXPECT_DOUBLE_EQ(s.max, 103.0);
  EXPECT_DOUBLE_EQ(s.mean, 102.0);
  EXPECT_DOUBLE_EQ(s.area_m2, 0.75);
}

TEST(Dtm, GeoTiffGeoreferenceAsGdalinfoSeesIt) {
  test::ScratchDir dir("products_dtm_geotiff");
  Dtm d;
  d.grid = {-0.50, 0.30, 0.005, 200, 120};  // x_min, y_max, cell, width, height
  d.z.assign(d.grid.cells(), 0.f);
  for (int r = 0; r < d.grid.height; ++r)
    for (int c = 0; c < d.grid.width; ++c) d.z[d.grid.index(c, r)] = float(0.001 * c - 0.002 * r);
  d.z[d.grid.index(3, 4)] = std::nanf("");
  const auto path = dir / "dtm.tif";
  write_dtm_geotiff(path, d, {describe_crs("EPSG:32636").wkt, kOrigin});

  GDALAllRegister();
  GDALDataset* ds = GDALDataset::FromHandle(GDALOpen(path.string().c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  OGRSpatialReference srs(ds->GetProjectionRef());
  srs.AutoIdentifyEPSG();
  ASSERT_NE(srs.GetAuthorityCode(nullptr), nullptr);
  EXPECT_STREQ(srs.GetAuthorityCode(nullptr), "32636");
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  EXPECT_DOUBLE_EQ(gt[0], 734000.0 - 0.50);
  EXPECT_DOUBLE_EQ(gt[3], 4174000.0 + 0.30);
  EXPECT_DOUBLE_EQ(gt[1], 0.005);
  EXPECT_DOUBLE_EQ(gt[5], -0.005);
  EXPECT_EQ(gt[2], 0.0);
  EXPECT_EQ(gt[4], 0.0);
  GDALRasterBand* b = ds->GetRasterBand(1);
  EXPECT_EQ(b->GetRasterDataType(), GDT_Float32);
  int has = 0;
  EXPECT_EQ(b->GetNoDataValue(&has), kDtmNoData);
  EXPECT_TRUE(has);
  const char* layout = ds->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE");
  ASSERT_NE(layout, nullptr);
  EXPECT_STREQ(layout, "COG");
  float v = 0;
  ASSERT_EQ(b->RasterIO(GF_Read, 3, 4, 1, 1, &v, 1, 1, GDT_Float32, 0, 0, nullptr), CE_None);
  EXPECT_EQ(v, float(kDtmNoData));
  ASSERT_EQ(b->RasterIO(GF_Read, 10, 20, 1, 1, &v, 1, 1, GDT_Float32, 0, 0, nullptr), CE_None);
  EXPECT_NEAR(v, 1450.0 + 0.010 - 0.040, 2e-4);  // Float32 resolution at 1,450 m: 1.2e-4 m
  GDALClose(GDALDataset::ToHandle(ds));

  const Dtm back = read_dtm_geotiff(path, kOrigin);
  EXPECT_EQ(back.grid.width, d.grid.width);
  EXPECT_NEAR(back.grid.x_min, d.grid.x_min, 1e-9);
  EXPECT_FALSE(back.valid(3, 4));
  EXPECT_NEAR(back.at(10, 20), d.at(10, 20), 2e-4);
}

}  // namespace
}  // namespace strata
