// Contours and footprint from analytic DTMs; their rows and the raster tables in
// a real project.gpkg, read back through GDAL/OGR as QGIS would.
#include "crs/crs.hpp"
#include "exporters/raster/geotiff.hpp"
#include "exporters/raster/gpkg_raster.hpp"
#include "products/site_plan.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "support/test_support.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <cmath>
#include <set>

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000.0, 4174000.0, 1450.0);
constexpr double kCell = 0.01;  // metres
// Contours of a plane follow it within a fraction of a cell (linear interpolation
// between cell centres is exact on a plane).
constexpr double kContourTolerance = 1e-6;  // metres
// Footprint of a disc from cells simplified by half a cell: area within 2 %.
constexpr double kAreaTolerance = 0.02;

Dtm plane_dtm() {  // z = 0.1 x over [0, 1] x [0, 0.5], site frame
  Dtm d;
  d.grid = {0.0, 0.5, kCell, 100, 50};
  d.z.resize(d.grid.cells());
  for (int r = 0; r < d.grid.height; ++r)
    for (int c = 0; c < d.grid.width; ++c) d.z[d.grid.index(c, r)] = float(0.1 * d.grid.x_centre(c));
  return d;
}

Dtm disc_dtm(double radius) {
  Dtm d;
  d.grid = {-0.5, 0.5, kCell, 100, 100};
  d.z.assign(d.grid.cells(), std::nanf(""));
  for (int r = 0; r < d.grid.height; ++r)
    for (int c = 0; c < d.grid.width; ++c)
      if (std::hypot(d.grid.x_centre(c), d.grid.y_centre(r)) < radius) d.z[d.grid.index(c, r)] = 0.f;
  return d;
}

TEST(SitePlan, ContoursOfAPlane) {
  ContourOptions o;
  o.interval_m = 0.02;
  const auto lines = dtm_contours(plane_dtm(), kOrigin, o);
  std::set<long> levels;
  for (const auto& l : lines) {
    levels.insert(std::lround(l.elevation / 0.02));
    for (const auto& p : l.points) {
      const double x = p.x() - kOrigin.x();
      EXPECT_NEAR(0.1 * x + kOrigin.z(), l.elevation, kContourTolerance);
    }
  }
  // Heights 1450.0005 .. 1450.0995: levels 1450.02, .04, .06, .08.
  EXPECT_EQ(levels.size(), 4u);
}

TEST(SitePlan, FootprintOfADisc) {
  const double radius = 0.3;
  const Footprint fp = dtm_footprint(disc_dtm(radius), kOrigin);
  ASSERT_EQ(fp.polygons.size(), 1u);
  EXPECT_NEAR(fp.area_m2 / (M_PI * radius * radius), 1.0, kAreaTolerance);
  EXPECT_NEAR(fp.min.x() - kOrigin.x(), -radius, 2 * kCell);
  EXPECT_NEAR(fp.max.y() - kOrigin.y(), radius, 2 * kCell);
}

class SitePlanProject : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::make_unique<test::ScratchDir>("products_site_plan");
    CreateOptions c;
    c.crs = "EPSG:32636";
    c.origin = kOrigin;
    Project::create(dir_->path() / "site", c);
    project_ = std::make_unique<Project>(Project::open(dir_->path() / "site"));
    UnitRecord u;
    u.code = "101";
    insert_unit(project_->db(), u);
    LayerRecord l;
    l.name = "L1";
    l.unit = "101";
    insert_layer(project_->db(), l);
  }
  std::unique_ptr<test::ScratchDir> dir_;
  std::unique_ptr<Project> project_;
};

TEST_F(SitePlanProject, VectorsAndRasterTablesOpenInGdal) {
  auto& db = project_->db();
  const int srs = project_->site().srs_id;
  const Dtm dtm = plane_dtm();
  {
    Transaction tx(db);
    store_site_plan(db, srs, "L1", 0.02, dtm_contours(dtm, kOrigin, {0.02, 0}), dtm_footprint(dtm, kOrigin));
    register_site_plan_views(db, srs);
    tx.commit();
  }
  // Twice: rows are replaced, not added.
  {
    Transaction tx(db);
    store_site_plan(db, srs, "L1", 0.02, dtm_contours(dtm, kOrigin, {0.02, 0}), dtm_footprint(dtm, kOrigin));
    tx.commit();
  }
  const auto tif = dir_->path() / "dtm.tif";
  write_dtm_geotiff(tif, dtm, {describe_crs("EPSG:32636").wkt, kOrigin});
  const auto gpkg = project_->database_path();
  for (int run = 0; run < 2; ++run) {
    write_gpkg_raster(gpkg, tif, raster_table_name("dtm", "L1"), GpkgRasterKind::gridded_coverage, "test DTM");
  }

  GDALAllRegister();
  GDALDataset* v = GDALDataset::FromHandle(GDALOpenEx(gpkg.string().c_str(), GDAL_OF_VECTOR, nullptr, nullptr, nullptr));
  ASSERT_NE(v, nullptr);
  OGRLayer* contours = v->GetLayerByName("contours");
  ASSERT_NE(contours, nullptr);
  EXPECT_GT(contours->GetFeatureCount(), 0);
  EXPECT_LE(contours->GetFeatureCount(), 8);  // 4 levels, one line each (run twice: replaced)
  ASSERT_NE(contours->GetSpatialRef(), nullptr);
  EXPECT_STREQ(contours->GetSpatialRef()->GetAuthorityCode(nullptr), "32636");
  OGRLayer* fp = v->GetLayerByName("footprints");
  ASSERT_NE(fp, nullptr);
  EXPECT_EQ(fp->GetFeatureCount(), 1);
  fp->ResetReading();
  OGRFeature* f = fp->GetNextFeature();
  ASSERT_NE(f, nullptr);
  EXPECT_NEAR(f->GetFieldAsDouble("area_m2"), 0.5, 0.01);
  OGRFeature::DestroyFeature(f);
  EXPECT_NE(v->GetLayerByName("marker_residuals_view"), nullptr);
  GDALClose(GDALDataset::ToHandle(v));

  const std::string sub = "GPKG:" + gpkg.string() + ":dtm_L1";
  GDALDataset* r = GDALDataset::FromHandle(GDALOpen(sub.c_str(), GA_ReadOnly));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->GetRasterXSize(), dtm.grid.width);
  EXPECT_EQ(r->GetRasterBand(1)->GetRasterDataType(), GDT_Float32);
  double gt[6];
  r->GetGeoTransform(gt);
  EXPECT_NEAR(gt[0], kOrigin.x(), 1e-6);
  EXPECT_NEAR(gt[3], kOrigin.y() + 0.5, 1e-6);
  float z = 0;
  ASSERT_EQ(r->GetRasterBand(1)->RasterIO(GF_Read, 50, 10, 1, 1, &z, 1, 1, GDT_Float32, 0, 0, nullptr), CE_None);
  EXPECT_NEAR(z, 1450.0 + 0.1 * dtm.grid.x_centre(50), 2e-4);
  GDALClose(GDALDataset::ToHandle(r));

  // The project still opens (GDAL's tables do not upset the migrations).
  project_.reset();
  EXPECT_NO_THROW(Project::open(dir_->path() / "site"));
}

}  // namespace
}  // namespace strata
