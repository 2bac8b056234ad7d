// GRASS GIS reads strata's DTM export: 'strata export grass' files (the library
// call behind it) imported headless with import.sh, then r.univar compared with
// strata's own statistics. Skipped when GRASS is not installed.
#include "crs/crs.hpp"
#include "products/dtm.hpp"
#include "exporters/grass/grass_export.hpp"
#include "exporters/raster/geotiff.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000.0, 4174000.0, 1450.0);
// r.univar reads the same Float32 cells; its sums are double: agreement to well
// below the Float32 step at 1,450 m (1.2e-4 m).
constexpr double kStatTolerance = 1e-4;  // metres

std::string run(const std::string& cmd, int* status) {
  std::string out;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return out;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), int(buf.size()), p)) out += buf.data();
  *status = pclose(p);
  return out;
}

TEST(Grass, RUnivarMatchesStrataStatistics) {
  int status = 0;
  run("command -v grass > /dev/null 2>&1", &status);
  if (status != 0) GTEST_SKIP() << "GRASS GIS ('grass') is not on PATH; install grass-core to run this test";

  test::ScratchDir dir("grass_export");
  CreateOptions c;
  c.crs = "EPSG:32636";
  c.origin = kOrigin;
  Project::create(dir / "site", c);
  Project p = Project::open(dir / "site");
  UnitRecord u;
  u.code = "101";
  insert_unit(p.db(), u);
  LayerRecord l;
  l.name = "L1";
  l.unit = "101";
  l.id = insert_layer(p.db(), l);

  // A DTM with relief and a hole: a bowl 0.8 x 0.6 m at 5 mm, no data in one corner.
  Dtm dtm;
  dtm.grid = {11.0, 21.0, 0.005, 160, 120};
  dtm.z.resize(dtm.grid.cells());
  for (int r = 0; r < dtm.grid.height; ++r) {
    for (int col = 0; col < dtm.grid.width; ++col) {
      const double x = dtm.grid.x_centre(col) - 11.4, y = dtm.grid.y_centre(r) - 20.7;
      dtm.z[dtm.grid.index(col, r)] = (col < 20 && r < 15) ? std::nanf("") : float(0.3 + 0.5 * (x * x + y * y));
    }
  }
  std::filesystem::create_directories(p.dir() / "products" / "L1");
  write_dtm_geotiff(p.dir() / "products" / "L1" / "dtm.tif", dtm, {describe_crs("EPSG:32636").wkt, kOrigin});
  ProductRecord rec;
  rec.layer_id = l.id;
  rec.kind = "dtm";
  rec.path = "products/L1/dtm.tif";
  record_product(p.db(), p.dir(), rec);

  const GrassExportSummary s = export_grass(p, dir / "grass");
  ASSERT_TRUE(std::filesystem::exists(s.script));
  const std::string cmd = "cd " + (dir / "grass").string() +
                          " && grass --tmp-location EPSG:32636 --exec sh -c "
                          "'sh ./import.sh > /dev/null 2>&1 && r.univar -g map=L1_dtm' 2>/dev/null";
  const std::string out = run(cmd, &status);
  ASSERT_EQ(status, 0) << out;
  std::map<std::string, double> v;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq != std::string::npos) v[line.substr(0, eq)] = std::atof(line.substr(eq + 1).c_str());
  }
  const DtmStatistics st = dtm_statistics(dtm, kOrigin.z());
  ASSERT_TRUE(v.count("mean")) << out;
  EXPECT_EQ(std::size_t(v["n"]), st.valid_cells);
  EXPECT_NEAR(v["mean"], st.mean, kStatTolerance);
  EXPECT_NEAR(v["min"], st.min, kStatTolerance);
  EXPECT_NEAR(v["max"], st.max, kStatTolerance);
  std::printf("GRASS r.univar: n=%.0f mean=%.6f min=%.6f max=%.6f; strata: n=%zu mean=%.6f min=%.6f max=%.6f\n",
              v["n"], v["mean"], v["min"], v["max"], st.valid_cells, st.mean, st.min, st.max);
}

}  // namespace
}  // namespace strata
