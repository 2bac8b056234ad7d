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

// The finds layer as QGIS reads it: the .qgs parsed by Python's ElementTree (the
// escaping of the expressions undone as any XML reader does), then `checks` (Python
// statements on `renderer`, `style` = the label's text-style) run. Returns the
// script's exit status.
int check_finds_layer(const std::filesystem::path& qgs, const std::string& checks) {
  const std::filesystem::path script = qgs.parent_path() / (qgs.stem().string() + "_check.py");
  test::write_text(script, R"(import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
layer = root.find(".//maplayer[id='strata_finds']")
assert layer is not None, 'no finds layer'
assert layer.findtext('datasource') == './project.gpkg|layername=finds', layer.findtext('datasource')
assert layer.get('geometry') == 'Point' and layer.get('labelsEnabled') == '1'
node = root.find(".//layer-tree-group[@name='Site']/layer-tree-layer[@id='strata_finds']")
assert node is not None and node.get('checked') == 'Qt::Checked', 'the finds are not in the Site group, switched on'
renderer = layer.find('renderer-v2')
style = layer.find('labeling/settings/text-style')
)" + checks);
  const std::string cmd = "python3 " + script.string() + " " + qgs.string();
  return std::system(cmd.c_str());
}

TEST(Qgis, FindsLabelledByNumberAndConflictsApart) {
  if (std::system("python3 -c 'pass' > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3 not available to read the XML";
  test::ScratchDir dir("qgis_finds");
  QgisProjectInput in = sample(dir.path());

  // No finds recorded: no layer.
  EXPECT_EQ(qgis_project_xml(in, dir.path()).find("strata_finds"), std::string::npos);

  // No voxel model: every find alike, labelled by its number.
  in.finds = true;
  write_qgis_project(in, dir / "record.qgs");
  EXPECT_EQ(check_finds_layer(dir / "record.qgs", R"(
assert renderer.get('type') == 'singleSymbol', renderer.get('type')
assert renderer.find('symbols/symbol/layer').get('class') == 'SimpleMarker'
assert style.get('fieldName') == 'find_id' and style.get('isExpression') == '0'
)"),
            0);

  // Checked against the voxel model, two conflicts (an id with a quote in it, a point
  // in no unit's solid): a red rule for them before ELSE; the labels name the unit.
  in.find_conflicts = std::vector<QgisFindConflict>{{"F13", "101"}, {"O'Neil 2", ""}};
  write_qgis_project(in, dir / "checked.qgs");
  EXPECT_EQ(check_finds_layer(dir / "checked.qgs", R"(
assert renderer.get('type') == 'RuleRenderer', renderer.get('type')
rules = renderer.findall('rules/rule')
filters = [r.get('filter') for r in rules]
assert filters == ['"find_id" IN (\'F13\', \'O\'\'Neil 2\')', 'ELSE'], filters
assert rules[0].get('label') == 'conflict with the unit solids (2)', rules[0].get('label')
symbols = renderer.findall('symbols/symbol')
assert [r.get('symbol') for r in rules] == [s.get('name') for s in symbols] == ['0', '1']
colours = [s.find("layer/prop[@k='color']").get('v') for s in symbols]
assert colours[0] == '225,20,20,255' and colours[1] != colours[0], colours
assert style.get('isExpression') == '1'
label = style.get('fieldName')
assert label == ('CASE WHEN "find_id" = \'F13\' THEN "find_id" || \': recorded \' || "unit" || \', lies in 101\''
                 ' WHEN "find_id" = \'O\'\'Neil 2\' THEN "find_id" || \': recorded \' || "unit" || '
                 '\', in no unit\'\'s solid\' ELSE "find_id" END'), label
)"),
            0);

  // Checked, none in conflict: one rule (ELSE) for all, labelled by number.
  in.find_conflicts = std::vector<QgisFindConflict>{};
  write_qgis_project(in, dir / "clean.qgs");
  EXPECT_EQ(check_finds_layer(dir / "clean.qgs", R"(
rules = renderer.findall('rules/rule')
assert [r.get('filter') for r in rules] == ['ELSE'], [r.get('filter') for r in rules]
assert rules[0].get('label') == 'agree with the unit solids'
assert style.get('fieldName') == 'find_id' and style.get('isExpression') == '0'
)"),
            0);
}

}  // namespace
}  // namespace strata
