// QGIS project: layer groups in stratigraphic order, relative sources that resolve,
// .qgz a valid zip holding the .qgs.
#include "core/error.hpp"
#include "exporters/qgis/qgis_project.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

namespace strata {
namespace {

QgisProjectInput sample(const std::filesystem::path& root) {
  QgisProjectInput in;
  in.title = "trench A";
  in.gpkg = root / "project.gpkg";
  in.crs_authid = "EPSG:32636";
  in.crs_wkt = "PROJCS[\"WGS 84 / UTM zone 36N\"]";
  in.min = {734011, 4174017};
  in.max = {734016, 4174021};
  for (const char* l : {"L1", "L2"}) {
    QgisLayerGroup g;
    g.layer = l;
    g.unit = std::string("10") + l[1];
    g.dtm = root / "products" / l / "dtm.tif";
    g.ortho = root / "products" / l / "ortho.tif";
    g.contours = g.footprint = true;
    in.layers.push_back(g);
  }
  return in;
}

TEST(Qgis, GroupsInStratigraphicOrderWithRelativeSources) {
  const std::string xml = qgis_project_xml(sample("/data/site"), "/data/site");
  const auto l2 = xml.find("layer-tree-group name=\"L2 (unit 102)\"");
  const auto l1 = xml.find("layer-tree-group name=\"L1 (unit 101)\"");
  ASSERT_NE(l2, std::string::npos);
  ASSERT_NE(l1, std::string::npos);
  EXPECT_LT(l2, l1);  // latest capture on top
  EXPECT_NE(xml.find("<datasource>./products/L1/dtm.tif</datasource>"), std::string::npos);
  EXPECT_NE(xml.find("./project.gpkg|layername=contours|subset=&quot;layer&quot; = &#39;L1&#39;"), std::string::npos);
  EXPECT_NE(xml.find("rasterrenderer type=\"hillshade\""), std::string::npos);
  EXPECT_NE(xml.find("<labeling type=\"simple\">"), std::string::npos);
  EXPECT_NE(xml.find("<Absolute type=\"bool\">false</Absolute>"), std::string::npos);
  // A project file in a subfolder points one level up.
  const std::string sub = qgis_project_xml(sample("/data/site"), "/data/site/gis");
  EXPECT_NE(sub.find("<datasource>../products/L2/ortho.tif</datasource>"), std::string::npos);
}

TEST(Qgis, QgzIsAZipHoldingTheQgs) {
  test::ScratchDir dir("products_qgis");
  const auto qgz = dir / "site.qgz";
  write_qgis_project(sample(dir.path()), qgz);
  ASSERT_TRUE(std::filesystem::exists(qgz));
  if (std::system("python3 -c 'pass' > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3 not available to read the zip";
  const std::string cmd =
      "python3 -c \"import sys, zipfile; z = zipfile.ZipFile(sys.argv[1]); "
      "assert z.testzip() is None; assert z.namelist() == ['site.qgs']; "
      "assert b'<qgis' in z.read('site.qgs')\" " + qgz.string();
  EXPECT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_THROW(write_qgis_project(sample(dir.path()), dir / "site.txt"), InputError);
}

}  // namespace
}  // namespace strata
