// The GeoTIFF writer and reader: georeferencing as gdalinfo would report it (CRS,
// geotransform, nodata, COG layout), and the heights back in the site frame.
#include "crs/crs.hpp"
#include "exporters/raster/geotiff.hpp"
#include "importers/raster/geotiff.hpp"
#include "support/test_support.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cmath>

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000.0, 4174000.0, 1450.0);

TEST(GeoTiff, DtmGeoreferenceAsGdalinfoSeesIt) {
  test::ScratchDir dir("exporters_dtm_geotiff");
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

  const Dtm back = convert_raster<float>(read_height_geotiff(path, kOrigin));
  EXPECT_EQ(back.grid.width, d.grid.width);
  EXPECT_NEAR(back.grid.x_min, d.grid.x_min, 1e-9);
  EXPECT_FALSE(back.valid(3, 4));
  EXPECT_NEAR(back.at(10, 20), d.at(10, 20), 2e-4);
}

}  // namespace
}  // namespace strata
