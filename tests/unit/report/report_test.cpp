// Reports of a small project built in the test: a fake but consistent
// reconstruction (cameras on a ring, points on an analytic surface, markers with
// residuals) stored with store_alignment, DTM and orthophoto GeoTIFFs written with
// the products writers, a thickness raster and a volume row; no heavy pipeline.
#include "core/error.hpp"
#include "crs/crs.hpp"
#include "exporters/raster/geotiff.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/stage_json.hpp"
#include "products/dtm.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "report/report.hpp"
#include "support/shared_scene.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <optional>
#include <random>
#include <regex>

namespace strata {
namespace {

namespace fs = std::filesystem;

const Eigen::Vector3d kOrigin(500000, 4000000, 100);  // metres, EPSG:32636
constexpr double kHalfX = 1.0, kHalfY = 0.75;          // trench half sizes, metres
constexpr double kCheckResidual_m = 0.014;             // GCP5: over the 10 mm check tolerance

double surface(double x, double y, double base) {
  return base + 0.03 * std::sin(2 * x) * std::cos(3 * y) + 0.02 * x;
}

Intrinsics test_intrinsics() { return {1200, 800, 1300, 1300, 599.5, 399.5, 0, 0}; }

Project make_project(const fs::path& dir) {
  CreateOptions co;
  co.crs = "EPSG:32636";
  co.name = "trench-A";
  co.origin = kOrigin;
  Project p = Project::create(dir, co);
  Database& db = p.db();
  Transaction tx(db);
  for (const char* code : {"101", "102", "103", "104"}) insert_unit(db, {0, code, "deposit", ""});
  insert_relation(db, {0, "101", "above", "102"});
  insert_relation(db, {0, "102", "above", "103"});
  insert_relation(db, {0, "102", "above", "104"});
  int i = 0;
  for (const char* l : {"L1", "L2", "L3", "L4"}) {
    insert_layer(db, {0, l, std::string("10") + char('1' + i), fmt::format("2024-06-1{}T09:00:00", i)});
    ++i;
  }
  const int srs = p.site().srs_id;
  const std::pair<const char*, Eigen::Vector3d> markers[] = {
      {"GCP1", {-1.1, -0.85, 0}}, {"GCP2", {1.1, -0.85, 0}}, {"GCP3", {1.1, 0.85, 0}},
      {"GCP4", {-1.1, 0.85, 0}},  {"GCP5", {0.0, 0.9, 0}}};
  for (const auto& [name, pos] : markers) {
    MarkerRecord m;
    m.name = name;
    m.position = pos + kOrigin;
    m.kind = std::string(name) == "GCP5" ? "check" : "control";
    upsert_marker(db, m, srs);
  }
  tx.commit();
  return p;
}

// Photos of a layer: `n` on a ring (none on the east-north-east stretch, so that a
// corner is thinly covered), plus one that will not align.
std::vector<ImageRecord> import_photos(Project& p, const std::string& layer, int n) {
  Database& db = p.db();
  Transaction tx(db);
  const auto l = require_layer(db, layer);
  CameraRecord cam;
  cam.make = "Test";
  cam.model = "Ring";
  cam.width = 1200;
  cam.height = 800;
  const auto camera_id = find_or_insert_camera(db, cam);
  static int sha = 0;
  for (int i = 0; i <= n; ++i) {
    ImageRecord im;
    im.layer_id = l.id;
    im.name = fmt::format("IMG_{:04d}.JPG", i + 1);
    im.sha256 = fmt::format("{:064x}", ++sha);
    im.media_path = "media/" + im.sha256.substr(0, 2) + "/" + im.sha256 + ".jpg";
    im.bytes = 1;
    im.width = 1200;
    im.height = 800;
    im.camera_id = camera_id;
    im.captured_at = fmt::format("2024-06-10T09:{:02d}:{:02d}", (i * 3) / 60, (i * 3) % 60);
    insert_image(db, im);
  }
  tx.commit();
  return list_images(db, l.id);
}

void process_layer(Project& p, const std::string& layer, double base, bool products) {
  Database& db = p.db();
  const auto l = require_layer(db, layer);
  const auto images = import_photos(p, layer, 16);
  const Intrinsics k = test_intrinsics();
  StoredAlignment a;
  a.rec.groups.push_back({k, false});
  a.rec.georeferenced = true;
  a.images = images;
  a.camera_ids = {*images.front().camera_id};
  std::vector<Camera> cams;
  for (std::size_t i = 0; i < images.size(); ++i) {
    RegisteredImage ri;
    ri.name = images[i].name;
    ri.registered = i + 1 < images.size();  // the last photo did not align
    if (ri.registered) {
      // Bearings 80..370 degrees: nobody stood north-east of the trench.
      const double deg = 80 + 290.0 * double(i) / double(images.size() - 2);
      const double t = deg * M_PI / 180;
      const Eigen::Vector3d c(1.7 * std::cos(t), 1.4 * std::sin(t), base + 1.2);
      const Eigen::Vector3d target(0.35 * c.x(), 0.35 * c.y(), base);
      ri.pose = Pose::look_at(c, target);
      cams.push_back({k, ri.pose});
    }
    a.rec.images.push_back(ri);
  }
  std::mt19937 rng(7);
  std::gamma_distribution<double> err(4.0, 0.12);
  for (int i = 0; i < 50; ++i) {
    for (int j = 0; j < 38; ++j) {
      SparsePoint pt;
      const double x = -kHalfX + 2 * kHalfX * i / 49, y = -kHalfY + 2 * kHalfY * j / 37;
      pt.X = {x, y, surface(x, y, base)};
      int cam_index = 0;
      for (std::size_t im = 0; im < a.rec.images.size(); ++im) {
        if (!a.rec.images[im].registered) continue;
        const auto px = cams[std::size_t(cam_index++)].project(pt.X);
        if (px && px->x() >= 0 && px->y() >= 0 && px->x() < k.width && px->y() < k.height) {
          pt.track.push_back({int(im), int(pt.track.size())});
        }
      }
      if (pt.track.size() < 2) continue;
      pt.error_px = err(rng);
      pt.colour = {150, std::uint8_t(110 + (i * 7 + j * 3) % 40), 80};
      a.rec.points.push_back(pt);
    }
  }
  const nlohmann::json rmse_control = {{"e_m", 0.003}, {"n_m", 0.004}, {"z_m", 0.005}, {"xyz_m", 0.0071}, {"markers", 4}};
  const nlohmann::json rmse_check = {{"e_m", 0.006}, {"n_m", 0.008}, {"z_m", 0.009}, {"xyz_m", kCheckResidual_m}, {"markers", 1}};
  std::map<std::string, std::int64_t> marker_ids;
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& m : list_markers(db)) {
    const bool check = m.kind == "check";
    const double s = check ? 1.0 : 0.4;
    nlohmann::json r = {{"marker", m.name}, {"role", m.kind}, {"triangulated", true},
                        {"dE", s * 0.006 * (m.name == "GCP2" ? -1 : 1)}, {"dN", s * 0.008},
                        {"dZ", s * (m.name == "GCP3" ? -0.009 : 0.007)}, {"reprojection_px", 0.4 + 0.1 * m.id},
                        {"images", check ? 2 : 6 + int(m.id)}};
    marker_ids[m.name] = m.id;
    rows.push_back(r);
  }
  // As an earlier version stored it, without the newer keys.
  a.quality = alignment_quality_from_json({{"layer", layer},
               {"images_total", images.size()},
               {"images_registered", images.size() - 1},
               {"unregistered", {images.back().name}},
               {"points", a.rec.points.size()},
               {"mean_track_length", 5.2},
               {"reprojection_rmse_px", 0.62},
               {"gsd_m", 0.0009},
               {"georeferenced", true},
               {"control_rmse", rmse_control},
               {"check_rmse", rmse_check},
               {"markers", rows},
               {"timings", {{"total_s", 41.0}}}});
  a.inputs_key = "test";
  {
    Transaction tx(db);
    store_alignment(db, l, p.site(), a, marker_ids);
    tx.commit();
  }
  if (!products) return;

  // DTM and orthophoto as the products stage writes them.
  const double cell = 0.01;
  Dtm dtm;
  dtm.grid = {-kHalfX, kHalfY, cell, int(2 * kHalfX / cell), int(2 * kHalfY / cell)};
  RgbaRaster ortho;
  ortho.grid = dtm.grid;
  for (int r = 0; r < dtm.grid.height; ++r) {
    for (int c = 0; c < dtm.grid.width; ++c) {
      const double x = dtm.grid.x_centre(c), y = dtm.grid.y_centre(r);
      dtm.z.push_back(float(surface(x, y, base)));
      const double tone = 0.5 + 0.5 * std::sin(9 * x + 4 * std::sin(5 * y));
      for (double v : {150 + 60 * tone, 110 + 50 * tone, 70 + 40 * tone, 255.0}) ortho.rgba.push_back(std::uint8_t(v));
    }
  }
  const RasterGeoreference geo{describe_crs("EPSG:32636").wkt, kOrigin};
  const std::string rel = "products/" + layer;
  fs::create_directories(p.dir() / rel);
  write_dtm_geotiff(p.dir() / rel / "dtm.tif", dtm, geo);
  write_rgba_geotiff(p.dir() / rel / "ortho.tif", ortho, geo);
  Transaction tx(db);
  for (const char* kind : {"dense", "products"}) {
    const nlohmann::json q = std::string(kind) == "dense"
                                 ? nlohmann::json{{"completeness", 0.93}, {"median_distance_sparse_m", 0.0012}}
                                 : nlohmann::json{{"dtm", {{"cell_m", cell}, {"area_m2", 3.0}}},
                                                  {"ortho", {{"coverage", 0.97}}},
                                                  {"footprint", {{"area_m2", 2.95}}}};
    db.prepare("INSERT INTO reconstructions(layer_id, stage, created_at, inputs_key, georeferenced, quality_json) "
               "VALUES (?, ?, '2024-06-10T10:00:00Z', 'test', 1, ?)")
        .bind_all(l.id, kind, q.dump())
        .run();
  }
  for (const char* kind : {"dtm", "ortho"}) {
    ProductRecord r;
    r.layer_id = l.id;
    r.kind = kind;
    r.path = rel + "/" + kind + ".tif";
    record_product(db, p.dir(), r);
  }
  tx.commit();
}

void add_volumes(Project& p) {
  Database& db = p.db();
  const auto u = require_unit(db, "101");
  Dtm t = Dtm::empty(RasterGrid::from_south_west_centre(-kHalfX + 0.01, -kHalfY + 0.01, 0.02, 99, 74));
  for (std::size_t c = 0; c < t.z.size(); ++c) {
    const Eigen::Vector2d q = t.grid.centre(c);
    t.z[c] = float(surface(q.x(), q.y(), 0) - surface(q.x(), q.y(), -0.1));
  }
  fs::create_directories(p.dir() / "products/volume");
  write_float_geotiff(p.dir() / "products/volume/thickness_101.tif", t,
                      {describe_crs("EPSG:32636").wkt, kOrigin}, {.description = "thickness of 101", .unit = "m"},
                      {.cog = false});
  Transaction tx(db);
  ProductRecord r;
  r.unit_id = u.id;
  r.kind = "thickness";
  r.path = "products/volume/thickness_101.tif";
  record_product(db, p.dir(), r);
  db.prepare("INSERT INTO unit_volumes(unit_id, top_layer, bottom_layers, volume_m3, area_m2, mean_thickness_m, "
             "min_thickness_m, max_thickness_m, volume_sigma_m3, method, computed_at) VALUES (?, 'L1', 'L2', 0.3, "
             "3.0, 0.1, 0.1, 0.1, 0.004, 'voxels', '2024-06-12T10:00:00Z')")
      .bind_all(u.id)
      .run();
  tx.commit();
}

// The report must open at the trench edge with no network: no URL anywhere
// (no http(s) in src/href, no namespace URIs either).
void expect_self_contained(const std::string& html) {
  EXPECT_EQ(html.find("http"), std::string::npos) << html.substr(html.find("http") - 80, 200);
  static const std::regex external(R"((src|href)\s*=\s*"(?!data:|#)[^"]*")");
  EXPECT_FALSE(std::regex_search(html, external));
}

// Copies a report for a human to look at (headless Chromium) when asked to.
void keep(const fs::path& file, const std::string& name) {
  if (const char* dir = std::getenv("STRATA_REPORT_KEEP_DIR")) {
    fs::create_directories(dir);
    fs::copy_file(file, fs::path(dir) / name, fs::copy_options::overwrite_existing);
  }
}

// The project is built once for every process of the suite (ctest runs each test in
// its own process; support/shared_scene.hpp); reports are written into the project,
// so each test works on its own copy.
class ReportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    shared_ = test::shared_scene("report_site", "L1 L2 processed, L3 photographed, L4 empty", [](const fs::path& d) {
      Project p = make_project(d / "site");
      process_layer(p, "L1", 0.0, true);
      process_layer(p, "L2", -0.1, true);
      import_photos(p, "L3", 12);  // photographed, not processed
      add_volumes(p);              // L4: nothing at all
    });
  }
  void SetUp() override {
    scratch_.emplace("site");
    test::copy_scene(shared_ / "site", site());
  }
  fs::path site() const { return scratch_->path() / "site"; }
  static fs::path shared_;
  std::optional<test::ScratchDir> scratch_;
};
fs::path ReportTest::shared_;

TEST_F(ReportTest, LayerReportHasEverySectionAndNoExternalUrl) {
  Project p = Project::open(site());
  const fs::path out = write_layer_report_product(p, "L1");
  ASSERT_TRUE(fs::exists(out));
  EXPECT_TRUE(find_product(p.db(), require_layer(p.db(), "L1").id, "report").has_value());
  keep(out, "layer_L1.html");
  const std::string html = test::read_text(out);
  for (const char* heading : {"Warnings and what to do", "Photos", "Camera positions", "Coverage",
                              "Marker residuals", "Reprojection error", "DTM hillshade"}) {
    EXPECT_NE(html.find(fmt::format("<h2>{}</h2>", heading)), std::string::npos) << heading;
  }
  expect_self_contained(html);
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);  // orthophoto, coverage, hillshade
  EXPECT_NE(html.find("marker GCP5 seen in only 2 photos"), std::string::npos);
  EXPECT_NE(html.find("check RMSE 14 mm exceeds 10 mm"), std::string::npos);
  EXPECT_NE(html.find("1 photo could not be aligned: IMG_0017.JPG"), std::string::npos);
  EXPECT_NE(html.find("Not ready to dig"), std::string::npos);
  EXPECT_EQ(html.find("<p class=\"missing\">"), std::string::npos);  // every stage is there
}

TEST_F(ReportTest, LayerReportSummaryMatchesTheRules) {
  Project p = Project::open(site());
  ReportSummary s;
  layer_report_html(p, "L1", {}, &s);
  ASSERT_EQ(s.layers.size(), 1u);
  // The camera ring leaves out the north-east: that corner is the one gap.
  std::vector<std::string> gaps;
  for (const auto& f : s.layers[0].findings) {
    if (f.rule == "coverage_gap") gaps.push_back(f.message);
  }
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_EQ(gaps[0].find("the north-east corner is seen by fewer than 3 photos"), 0u) << gaps[0];
  EXPECT_EQ(s.layers[0].count(Severity::problem), 2);  // the gap and the check RMSE
}

TEST_F(ReportTest, UnprocessedLayersAreSaidInPlainWords) {
  Project p = Project::open(site());
  const std::string l3 = layer_report_html(p, "L3", {});
  expect_self_contained(l3);
  EXPECT_NE(l3.find("the layer has not been aligned"), std::string::npos);
  EXPECT_NE(l3.find("strata process DIR --layer L3"), std::string::npos);
  const std::string l4 = layer_report_html(p, "L4", {});
  EXPECT_NE(l4.find("No photos have been imported for this layer."), std::string::npos);
  EXPECT_THROW(layer_report_html(p, "L9", {}), InputError);
}

TEST_F(ReportTest, SiteReportHasEverySection) {
  Project p = Project::open(site());
  const fs::path out = site() / "site.html";
  const ReportSummary s = write_site_report(p, out, {});
  keep(out, "site.html");
  EXPECT_EQ(s.layers.size(), 4u);
  const std::string html = test::read_text(out);
  for (const char* heading : {"Site", "Layers", "Finds", "Harris matrix", "Volumes", "Thickness maps", "Section"}) {
    EXPECT_NE(html.find(fmt::format("<h2>{}</h2>", heading)), std::string::npos) << heading;
  }
  expect_self_contained(html);
  EXPECT_NE(html.find("<h3>Layer L3 (unit 103)</h3>"), std::string::npos);
  EXPECT_NE(html.find("0.300"), std::string::npos);  // the volume row
}

TEST(ReportEmpty, SiteReportOfAnEmptyProject) {
  test::ScratchDir dir("empty");
  CreateOptions co;
  co.crs = "EPSG:32636";
  Project p = Project::create(dir.path() / "site", co);
  const std::string html = site_report_html(p, {});
  expect_self_contained(html);
  EXPECT_NE(html.find("No layers recorded yet."), std::string::npos);
  EXPECT_NE(html.find("No stratigraphic units recorded yet."), std::string::npos);
  EXPECT_NE(html.find("No volumes yet"), std::string::npos);
  EXPECT_NE(html.find("No finds recorded yet; import them with: strata import finds DIR FILE.csv"), std::string::npos);
}

TEST_F(ReportTest, CommandLine) {
  const fs::path out = site() / "cli" / "report.html";
  auto r = test::run_strata({"report", site().string(), "--layer", "L1", "--out", out.string(), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(out));
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_EQ(j[0]["layer"], "L1");
  EXPECT_GE(j[0]["problems"].get<int>(), 1);
  r = test::run_strata({"report", site().string(), "--layer", "nope", "--out", out.string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("nope"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace strata
