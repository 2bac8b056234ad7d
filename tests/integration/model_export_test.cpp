// `strata export model` and `strata export viewer` on a project whose layer has a recorded dense mesh (written
// here, as the dense stage writes it: double site CRS coordinates): the refusals, and
// the .glb's frame checked against the mesh's known coordinates. The container
// itself is checked in tests/unit/exporters/gltf_test.cpp.
#include "exporters/mesh/mesh_writers.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "support/obj_file.hpp"
#include "support/recorded_mesh.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <regex>
#include <sstream>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::glb_json;
using test::record_dense_mesh;
using test::run_strata;

const Eigen::Vector3d kSiteOrigin(733900.0, 4173900.0, 1450.0);  // E, N, Z metres, as given to init
constexpr double kSubMillimetre = 1e-4;  // metres: what the local origin must preserve

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

// Two triangles, 2.5 x 1.5 m, with tenth-of-millimetre digits (site frame).
DenseMesh quad() {
  DenseMesh m;
  m.vertices = {{100.1234, 100.5678, 0.0009}, {102.6234, 100.5678, 0.0102},
                {102.6234, 102.0678, -0.2031}, {100.1234, 102.0678, -0.1007}};
  m.colours.assign(4, Rgb8(180, 140, 90));
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

fs::path project_with_layer(const test::ScratchDir& dir) {
  const std::string site = (dir / "site").string();
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"init", site, "--crs", "EPSG:32636", "--origin", "733900,4173900,1450"},
           {"unit", "add", site, "101"},
           {"layer", "add", site, "L1", "--unit", "101"}}) {
    const auto r = run_strata(args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  return site;
}

// Two triangles per square of a (cells + 1) x (cells + 1) vertex grid laid row by row.
void add_grid_faces(DenseMesh& m, int cells) {
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const int a = j * (cells + 1) + i;
      m.faces.push_back({a, a + 1, a + cells + 2});
      m.faces.push_back({a, a + cells + 2, a + cells + 1});
    }
  }
}

// A coloured grid of cells x cells squares, 1 cm each, two triangles per square (site
// frame, near the quad): red rises to the east, so colours show where they came from.
DenseMesh coloured_grid(int cells) {
  DenseMesh m;
  for (int j = 0; j <= cells; ++j) {
    for (int i = 0; i <= cells; ++i) {
      m.vertices.emplace_back(100.0 + 0.01 * i, 100.0 + 0.01 * j, 0.001 * i);
      m.colours.emplace_back(std::uint8_t(255 * i / cells), 128, 64);
    }
  }
  add_grid_faces(m, cells);
  return m;
}

// The largest v index any face names.
int max_vertex_index(const test::ObjFile& o) {
  int k = 0;
  for (const auto& face : o.f) {
    for (const auto& corner : face) k = std::max(k, corner[0]);
  }
  return k;
}

// The recorded quad of a fresh project exported as `file` (.glb or .obj) in `dir`.
fs::path exported_quad(const test::ScratchDir& dir, const std::string& file) {
  const fs::path site = project_with_layer(dir);
  record_dense_mesh(site, "L1", quad());
  const auto r = run_strata({"export", "model", site.string(), "--layer", "L1", "--out", (dir / file).string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return dir / file;
}

std::size_t glb_faces(const nlohmann::json& j) {
  std::size_t indices = 0;
  for (const auto& prim : j["meshes"][0]["primitives"]) indices += std::size_t(j["accessors"][int(prim["indices"])]["count"]);
  return indices / 3;
}

TEST(CliExportModel, RefusesWithoutDenseMeshOrAModelExtension) {
  test::ScratchDir dir("model_refused");
  const std::string site = project_with_layer(dir).string();
  auto r = run_strata({"export", "model", site, "--layer", "L1", "--out", (dir / "l1.glb").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("no dense mesh"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--until dense"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "l1.glb"));
  r = run_strata({"export", "model", site, "--layer", "L1", "--out", (dir / "l1.ply").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(".glb"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(".obj"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "l1.ply"));
}

TEST(CliExportModel, ObjCarriesTheSiteFrameThroughItsStatedOrigin) {
  test::ScratchDir dir("model_obj");
  const DenseMesh m = quad();
  const test::ObjFile o = test::read_obj(exported_quad(dir, "l1.obj"));
  // The glTF export's local origin (GlbCarriesTheSiteFrame): whole metres.
  EXPECT_EQ(o.origin, Eigen::Vector3d(734001, 4174001, 1450));
  ASSERT_EQ(o.v.size(), m.vertices.size());
  ASSERT_EQ(o.rgb.size(), m.vertices.size());
  EXPECT_EQ(o.f.size(), m.faces.size());
  EXPECT_LE(max_vertex_index(o), int(m.vertices.size()));
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Eigen::Vector3d back = o.origin + o.v[i].cast<float>().cast<double>();  // as a float32 reader has it
    EXPECT_LT((back - (m.vertices[i] + kSiteOrigin)).cwiseAbs().maxCoeff(), kSubMillimetre) << i;
    EXPECT_NEAR(o.rgb[i].x(), 180 / 255.0, 1e-4);
  }
  EXPECT_FALSE(fs::exists(dir / "l1.mtl"));  // untextured: no material library
}

// A 40 x 40 grid: 3200 faces. --lod 1 and 2 a quarter and a sixteenth of them with
// their colours, --lod 3 (50 faces) and --lod -1 refused naming the value, as is the
// site model as OBJ and an .obj in a folder that cannot exist; none leaves a file.
TEST(CliExportModel, LevelsOfDetailKeepAQuarterOfTheFacesEachAndTheirColours) {
  test::ScratchDir dir("model_lod");
  const fs::path site = project_with_layer(dir);
  const DenseMesh m = coloured_grid(40);
  record_dense_mesh(site, "L1", m);
  // The collapses stop on an edge count, so a level ends at or a little below its target.
  constexpr double kMinShareOfTarget = 0.8;
  for (int lod = 1; lod <= 2; ++lod) {
    const std::size_t target = m.faces.size() >> (2 * lod);
    const std::string name = "lod" + std::to_string(lod);
    const fs::path obj = dir / (name + ".obj"), glb = dir / (name + ".glb");
    auto r = run_strata({"export", "model", site.string(), "--layer", "L1", "--lod", std::to_string(lod), "--out",
                         obj.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("level of detail " + std::to_string(lod)), std::string::npos) << r.err;
    const test::ObjFile o = test::read_obj(obj);
    EXPECT_LE(o.f.size(), target) << lod;
    EXPECT_GE(double(o.f.size()), kMinShareOfTarget * double(target)) << lod;
    EXPECT_LE(max_vertex_index(o), int(o.v.size()));
    ASSERT_EQ(o.rgb.size(), o.v.size()) << lod;
    // The red ramp survives: a vertex's red is near the ramp's value where it lies.
    constexpr double kRampTolerance = 0.15;  // of full scale: a coarse vertex averages its patch
    for (std::size_t i = 0; i < o.v.size(); ++i) {
      const double east = o.origin.x() + o.v[i].x() - (kSiteOrigin.x() + 100.0);  // metres from the west edge
      EXPECT_NEAR(o.rgb[i].x(), east / 0.4, kRampTolerance) << lod << " " << i;
      EXPECT_NEAR(o.rgb[i].y(), 128 / 255.0, 1e-3) << lod << " " << i;
    }
    r = run_strata({"export", "model", site.string(), "--layer", "L1", "--lod", std::to_string(lod), "--out",
                    glb.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(glb_faces(glb_json(glb)), o.f.size()) << lod;
  }
  // The refusals write into an empty folder of their own, which must stay empty.
  const fs::path out = dir / "refused";
  fs::create_directories(out);
  for (const std::string lod : {"3", "-1"}) {
    const auto r = run_strata({"export", "model", site.string(), "--layer", "L1", "--lod", lod, "--out",
                               (out / "bad.obj").string()});
    EXPECT_EQ(r.exit_code, 1) << lod;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("--lod " + lod), std::string::npos) << r.err;
  }
  auto r = run_strata({"export", "model", site.string(), "--lod", "3", "--out", (out / "site.glb").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--lod 3: layer L1 has 3200 faces"), std::string::npos) << r.err;
  r = run_strata({"export", "model", site.string(), "--out", (out / "site.obj").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--layer"), std::string::npos) << r.err;
  test::write_text(out / "plain_file", "a file, not a folder");
  r = run_strata({"export", "model", site.string(), "--layer", "L1", "--out", (out / "plain_file" / "l1.obj").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("l1.obj"), std::string::npos) << r.err;
  fs::remove(out / "plain_file");
  EXPECT_TRUE(fs::is_empty(out)) << test::tree_fingerprint(out);
}

TEST(CliExportModel, GlbCarriesTheSiteFrame) {
  test::ScratchDir dir("model_glb");
  const DenseMesh m = quad();
  const nlohmann::json j = glb_json(exported_quad(dir, "l1.glb"));
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["asset"]["extras"]["crs"], "EPSG:32636");
  // Box centre 734001.3734, 4174001.3178, 1449.90355 (CRS) -> whole metres.
  EXPECT_EQ(j["asset"]["extras"]["origin"], nlohmann::json({734001.0, 4174001.0, 1450.0}));
  EXPECT_EQ(j["nodes"][0]["name"], "L1");
  const auto& t = j["nodes"][0]["translation"];
  const auto& pos = j["accessors"][int(j["meshes"][0]["primitives"][0]["attributes"]["POSITION"])];
  EXPECT_EQ(pos["count"], m.vertices.size());
  // The box back in site CRS coordinates: E = t.x + x, N = -(t.z + z), Z = t.y + y.
  const double e_min = double(t[0]) + double(pos["min"][0]), e_max = double(t[0]) + double(pos["max"][0]);
  const double n_min = -(double(t[2]) + double(pos["max"][2])), n_max = -(double(t[2]) + double(pos["min"][2]));
  const double z_min = double(t[1]) + double(pos["min"][1]), z_max = double(t[1]) + double(pos["max"][1]);
  EXPECT_NEAR(e_min, 734000.1234, kSubMillimetre);
  EXPECT_NEAR(e_max, 734002.6234, kSubMillimetre);
  EXPECT_NEAR(n_min, 4174000.5678, kSubMillimetre);
  EXPECT_NEAR(n_max, 4174002.0678, kSubMillimetre);
  EXPECT_NEAR(z_min, 1449.7969, kSubMillimetre);
  EXPECT_NEAR(z_max, 1450.0102, kSubMillimetre);
}

// The site model without unit solids or cameras (no layer surfaces, no alignment
// here: the unit test covers the scene writer, the full example the whole path):
// processed layers in layer order, markers at their surveyed place, and the refusal
// of a project with no processed layer naming the command to run.
TEST(CliExportModel, TextureNeedsAlignedPhotos) {
  test::ScratchDir dir("model_texture");
  const fs::path site = project_with_layer(dir);
  record_dense_mesh(site, "L1", quad());
  // The site model textures the layers with aligned photos; this one has none: it
  // keeps its vertex colours, with a warning naming it.
  auto r = run_strata({"export", "model", site.string(), "--texture", "--out", (dir / "site.glb").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("layer L1 has no aligned photos"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("1 layers of which 0 textured"), std::string::npos) << r.err;
  r = run_strata({"export", "model", site.string(), "--layer", "L1", "--texture", "--out", (dir / "l1.glb").string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("strata process"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "l1.glb"));
  // The photo check renders the texture: without it there is nothing to check.
  r = run_strata({"export", "model", site.string(), "--layer", "L1", "--check-photos", "2", "--out",
                  (dir / "l1.glb").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("--check-photos needs --texture"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "l1.glb"));
}

TEST(CliExportModel, SiteModelHasLayersAndMarkersAndRefusesAnUnprocessedProject) {
  test::ScratchDir dir("model_site");
  const fs::path site = project_with_layer(dir);
  auto r = run_strata({"export", "model", site.string(), "--out", (dir / "site.glb").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("strata process"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "site.glb"));

  r = run_strata({"layer", "add", site.string(), "L2", "--unit", "101"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  record_dense_mesh(site, "L1", quad());
  const Eigen::Vector3d gcp = kSiteOrigin + Eigen::Vector3d(101.5, 101.0, -0.05);
  {
    Project p = Project::open(site);
    MarkerRecord m;
    m.name = "GCP1";
    m.position = gcp;
    upsert_marker(p.db(), m, p.site().srs_id);
  }
  r = run_strata({"export", "model", site.string(), "--out", (dir / "site.glb").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("L2 has no dense mesh"), std::string::npos) << r.err;
  const nlohmann::json j = glb_json(dir / "site.glb");
  ASSERT_TRUE(j.is_object());
  ASSERT_EQ(j["nodes"].size(), 2u);
  EXPECT_EQ(j["nodes"][0]["name"], "layer L1");
  EXPECT_EQ(j["nodes"][1]["name"], "marker GCP1");
  const auto& t = j["nodes"][1]["translation"];
  EXPECT_NEAR(double(t[0]), gcp.x(), kSubMillimetre);
  EXPECT_NEAR(-double(t[2]), gcp.y(), kSubMillimetre);
  EXPECT_NEAR(double(t[1]), gcp.z(), kSubMillimetre);
  EXPECT_EQ(j["nodes"][1]["extras"]["kind"], "control");
}

// The viewer's embedded model: the base64 text of <script id="model"> (or another id:
// "model-detail") decoded; "" when the page has no such element.
std::string embedded_model(const std::string& html, const std::string& id = "model") {
  const auto b = html.find("<script id=\"" + id + "\"");
  if (b == std::string::npos) return {};
  const auto body = html.find('>', b) + 1;
  const auto e = html.find("</script>", b);
  std::string out;
  unsigned bits = 0;
  int n = 0;
  for (std::size_t i = body; i < e; ++i) {
    const char c = html[i];
    int v = -1;
    if (c >= 'A' && c <= 'Z') v = c - 'A';
    else if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
    else if (c >= '0' && c <= '9') v = c - '0' + 52;
    else if (c == '+') v = 62;
    else if (c == '/') v = 63;
    if (v < 0) continue;  // newlines and '=' padding
    bits = bits << 6 | unsigned(v);
    if ((n += 6) >= 8) out += char((bits >> (n -= 8)) & 0xFF);
  }
  return out;
}

// Layer L1 processed and one marker surveyed: two scene nodes.
void record_mesh_and_marker(const fs::path& site) {
  record_dense_mesh(site, "L1", quad());
  Project p = Project::open(site);
  MarkerRecord m;
  m.name = "GCP1";
  m.position = kSiteOrigin + Eigen::Vector3d(101.5, 101.0, -0.05);
  upsert_marker(p.db(), m, p.site().srs_id);
}

TEST(CliExportViewer, OneSelfContainedPageWithTheModelEmbedded) {
  test::ScratchDir dir("viewer_page");
  const std::string site = project_with_layer(dir).string();
  const std::string html_path = (dir / "site.html").string();
  auto r = run_strata({"export", "viewer", site, "--out", html_path});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("strata process"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(html_path));

  record_mesh_and_marker(site);
  r = run_strata({"export", "viewer", site, "--out", html_path});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string html = test::read_text(html_path);
  EXPECT_NE(html.find("THREE.GLTFLoader"), std::string::npos);
  EXPECT_NE(html.find("THREE.OrbitControls"), std::string::npos);
  EXPECT_NE(html.find("WebGLRenderer"), std::string::npos);  // three.min.js itself
  // Self-contained: nothing fetched from the network.
  EXPECT_FALSE(std::regex_search(html, std::regex(R"((src|href)\s*=\s*["']?\s*(https?:)?//)", std::regex::icase)));
  EXPECT_EQ(html.find("<link"), std::string::npos);
  const std::string glb = embedded_model(html);
  ASSERT_GE(glb.size(), 20u);
  std::uint32_t magic = 0, length = 0;
  std::memcpy(&magic, glb.data(), 4);
  std::memcpy(&length, glb.data() + 8, 4);
  EXPECT_EQ(magic, 0x46546C67u);  // "glTF"
  EXPECT_EQ(length, glb.size());
  test::write_text(dir / "embedded.glb", glb);
  const nlohmann::json j = glb_json(dir / "embedded.glb");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["nodes"].size(), 2u);

  // --layer: that layer (and the markers); an unknown layer is refused.
  r = run_strata({"export", "viewer", site, "--layer", "L1", "--out", (dir / "l1.html").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  test::write_text(dir / "l1.glb", embedded_model(test::read_text(dir / "l1.html")));
  EXPECT_EQ(glb_json(dir / "l1.glb")["nodes"][0]["name"], "layer L1");
  r = run_strata({"export", "viewer", site, "--layer", "L9", "--out", (dir / "l9.html").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(dir / "l9.html"));
}

TEST(CliExportViewer, MissingLibjsThreeIsOneErrorNamingThePackage) {
  test::ScratchDir dir("viewer_no_three");
  const fs::path site = project_with_layer(dir);
  record_mesh_and_marker(site);
  ::setenv("STRATA_LIBJS_THREE_DIR", (dir / "no-three").c_str(), 1);
  const auto r = run_strata({"export", "viewer", site.string(), "--out", (dir / "site.html").string()});
  ::unsetenv("STRATA_LIBJS_THREE_DIR");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("apt-get install libjs-three"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "site.html"));
}

// The page run in headless Chromium (software WebGL): its script writes "loaded N
// nodes" once the model is in the scene, so a JavaScript error fails the test.
TEST(CliExportViewer, PageLoadsTheModelInHeadlessChromium) {
  const fs::path chromium = "/usr/bin/chromium";
  if (!fs::exists(chromium)) GTEST_SKIP() << "no /usr/bin/chromium (apt-get install chromium)";
  test::ScratchDir dir("viewer_chromium");
  const std::string site = project_with_layer(dir).string();
  record_mesh_and_marker(site);
  const fs::path html_path = dir / "site.html", dom = dir / "dom.html";
  const auto r = run_strata({"export", "viewer", site, "--out", html_path.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string cmd = "timeout 120 " + chromium.string() +
                          " --headless --no-sandbox --disable-gpu --use-gl=swiftshader --enable-unsafe-swiftshader"
                          " --virtual-time-budget=10000 --dump-dom 'file://" + html_path.string() + "' > '" +
                          dom.string() + "' 2> '" + (dir / "chromium.err").string() + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << test::read_text(dir / "chromium.err");
  const std::string page = test::read_text(dom);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(page, m, std::regex(R"(<div id="status"[^>]*>([^<]*)</div>)"))) << page.substr(0, 2000);
  EXPECT_EQ(m[1].str(), "loaded 2 nodes");
  EXPECT_NE(m[0].str().find("data-webgl=\"yes\""), std::string::npos) << m[0].str();

  // The measuring tool: two clicks near the view's centre (where the quad is) must give
  // site CRS points on the quad and the distances between them.
  const std::string probe = R"(<script>setTimeout(function () {
    var v = document.getElementById('view'), r = v.getBoundingClientRect();
    document.getElementById('measure').checked = true;
    [[0, 0], [30, 10]].forEach(function (d) {
      var o = { clientX: r.width / 2 + d[0], clientY: r.height / 2 + d[1], bubbles: true };
      v.dispatchEvent(new PointerEvent('pointerdown', o));
      v.dispatchEvent(new PointerEvent('pointerup', o));
    });
    var out = document.createElement('div');
    out.id = 'probe';
    out.textContent = document.getElementById('readout').textContent.replace(/\n/g, ' | ');
    document.body.appendChild(out);
  }, 2000);</script>)";
  std::string html = test::read_text(html_path);
  html.insert(html.rfind("</body>"), probe);
  test::write_text(dir / "probe.html", html);
  const std::string probe_cmd = "timeout 120 " + chromium.string() +
                                " --headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader --window-size=800,600"
                                " --virtual-time-budget=10000 --dump-dom 'file://" + (dir / "probe.html").string() +
                                "' > '" + dom.string() + "' 2> /dev/null";
  ASSERT_EQ(std::system(probe_cmd.c_str()), 0);
  const std::string measured = test::read_text(dom);
  ASSERT_TRUE(std::regex_search(measured, m, std::regex(R"(P1  E ([0-9.]+)  N ([0-9.]+)  Z ([0-9.]+) \| P2 .*\| 3D ([0-9.]+) m   horizontal ([0-9.]+) m)")))
      << measured.substr(measured.find("probe") == std::string::npos ? 0 : measured.find("probe"), 500);
  EXPECT_GT(std::stod(m[1]), 734000.1234);  // inside the quad (docs: E 734000.1234-734002.6234)
  EXPECT_LT(std::stod(m[1]), 734002.6234);
  EXPECT_GT(std::stod(m[2]), 4174000.5678);
  EXPECT_LT(std::stod(m[2]), 4174002.0678);
  EXPECT_NEAR(std::stod(m[3]), 1449.9, 0.15);  // the quad's Z spans 1449.7969-1450.0102
  EXPECT_GT(std::stod(m[4]), 0.0);
  EXPECT_LE(std::stod(m[5]), std::stod(m[4]));
}

// --max-faces: a layer mesh above it is simplified before it is embedded.
TEST(CliExportViewer, MaxFacesSimplifiesLargeLayerMeshes) {
  test::ScratchDir dir("viewer_max_faces");
  const fs::path site = project_with_layer(dir);
  DenseMesh grid;  // 20 x 20 vertices, 1 m apart, a gentle slope: 722 faces
  constexpr int kSide = 20;
  for (int i = 0; i < kSide; ++i) {
    for (int j = 0; j < kSide; ++j) grid.vertices.emplace_back(100.0 + i, 100.0 + j, 0.01 * i);
  }
  for (int i = 0; i + 1 < kSide; ++i) {
    for (int j = 0; j + 1 < kSide; ++j) {
      const int a = i * kSide + j, b = a + kSide;
      grid.faces.push_back({a, b, b + 1});
      grid.faces.push_back({a, b + 1, a + 1});
    }
  }
  record_dense_mesh(site, "L1", grid);
  const auto r = run_strata({"export", "viewer", site.string(), "--out", (dir / "site.html").string(),
                             "--max-faces", "100"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("722 faces simplified to at most 100"), std::string::npos) << r.err;
  test::write_text(dir / "embedded.glb", embedded_model(test::read_text(dir / "site.html")));
  const nlohmann::json j = glb_json(dir / "embedded.glb");
  ASSERT_TRUE(j.is_object());
  const int indices = j["meshes"][0]["primitives"][0]["indices"];
  EXPECT_LE(int(j["accessors"][indices]["count"]), 3 * 100);
  EXPECT_GT(int(j["accessors"][indices]["count"]), 0);
}

// --- The page in headless Chromium: what it draws, the marker pick, the levels of detail.

const fs::path kChromium = "/usr/bin/chromium";
// Software WebGL (SwiftShader), as PageLoadsTheModelInHeadlessChromium found it works on
// Debian 12's Chromium; one device pixel per CSS pixel, so screenshots are window-sized.
const std::string kChromiumFlags =
    "--headless --no-sandbox --disable-gpu --use-gl=swiftshader --enable-unsafe-swiftshader --hide-scrollbars "
    "--force-device-scale-factor=1 --virtual-time-budget=10000";

// Runs Chromium on `url` with `args` (--dump-dom, --screenshot=...); its stdout into `out`.
bool run_chromium(const std::string& args, const std::string& url, const fs::path& out) {
  const std::string cmd = "timeout 180 " + kChromium.string() + " " + kChromiumFlags + " " + args + " '" + url + "' > '" +
                          out.string() + "' 2> '" + out.string() + ".err'";
  return std::system(cmd.c_str()) == 0;
}

// A flat square layer: side x side metres from (x0, y0) at height z (site frame), one
// colour, cells x cells squares of two triangles.
DenseMesh flat_square(double x0, double y0, double z, double side, int cells, Rgb8 colour) {
  DenseMesh m;
  for (int j = 0; j <= cells; ++j) {
    for (int i = 0; i <= cells; ++i) {
      m.vertices.emplace_back(x0 + side * i / cells, y0 + side * j / cells, z);
      m.colours.push_back(colour);
      m.normals.emplace_back(0, 0, 1);
    }
  }
  add_grid_faces(m, cells);
  return m;
}

// Two layers side by side, 1 m squares at Z 1449.95: L1 green to the west, L2 blue to
// the east; marker GCP1 lies on L1's surface.
const Rgb8 kGreen(60, 170, 60), kBlue(40, 90, 200);
constexpr double kLayerZ = -0.05;  // metres, site frame
const Eigen::Vector3d kMarkerOnL1 = kSiteOrigin + Eigen::Vector3d(100.37, 100.61, kLayerZ);

fs::path two_layer_site(const test::ScratchDir& dir) {
  const fs::path site = project_with_layer(dir);
  const auto r = run_strata({"layer", "add", site.string(), "L2", "--unit", "101"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  record_dense_mesh(site, "L1", flat_square(100.0, 100.0, kLayerZ, 1.0, 10, kGreen));
  record_dense_mesh(site, "L2", flat_square(101.5, 100.0, kLayerZ, 1.0, 10, kBlue));
  Project p = Project::open(site);
  MarkerRecord m;
  m.name = "GCP1";
  m.position = kMarkerOnL1;
  upsert_marker(p.db(), m, p.site().srs_id);
  return site;
}

// An 8-bit sRGB colour as the page draws it: glTF holds it linear (the sRGB curve), the
// renderer encodes its output with gamma 2.2 (three.js r111's gammaOutput).
cv::Vec3b on_screen(const Rgb8& c) {
  auto channel = [](int v) {
    const double s = v / 255.0, linear = s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4);
    return std::uint8_t(std::lround(255 * std::pow(linear, 1 / 2.2)));
  };
  return {channel(c[2]), channel(c[1]), channel(c[0])};  // BGR, as OpenCV reads it
}
const cv::Vec3b kBackground(0xe8, 0xe3, 0xdd);  // the scene's background 0xdde3e8, BGR
// Grey levels: the colour is stored as float, drawn unlit, encoded and rounded to 8 bits
// once; antialiased edge pixels (blends) fall outside and are not counted.
constexpr int kScreenColourTolerance = 3;

cv::Mat pixels_of(const cv::Mat& bgr, const cv::Vec3b& colour) {
  cv::Mat mask(bgr.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(y, x);
      bool near = true;
      for (int k = 0; k < 3; ++k) near = near && std::abs(int(p[k]) - int(colour[k])) <= kScreenColourTolerance;
      mask.at<std::uint8_t>(y, x) = near ? 255 : 0;
    }
  }
  return mask;
}

// Screenshots of the page at 1000 x 700: both layers drawn in their colours over the
// background; with ?hide=layer%20L2 the pixels that showed L2 show the background and
// L1 is unchanged.
TEST(CliExportViewer, ScreenshotShowsEachLayerInItsColourAndNotOneSwitchedOff) {
  if (!fs::exists(kChromium)) GTEST_SKIP() << "no /usr/bin/chromium (apt-get install chromium)";
  test::ScratchDir dir("viewer_screenshot");
  const fs::path site = two_layer_site(dir), html = dir / "site.html";
  const auto r = run_strata({"export", "viewer", site.string(), "--out", html.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const fs::path all_png = dir / "all.png", hidden_png = dir / "hidden.png";
  ASSERT_TRUE(run_chromium("--window-size=1000,700 --screenshot=" + all_png.string(), "file://" + html.string(),
                           dir / "all.out")) << test::read_text(dir / "all.out.err");
  ASSERT_TRUE(run_chromium("--window-size=1000,700 --screenshot=" + hidden_png.string(),
                           "file://" + html.string() + "?hide=layer%20L2", dir / "hidden.out"))
      << test::read_text(dir / "hidden.out.err");
  const cv::Mat all = cv::imread(all_png.string(), cv::IMREAD_COLOR), hidden = cv::imread(hidden_png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(all.empty());
  ASSERT_FALSE(hidden.empty());
  ASSERT_EQ(all.cols, 1000);
  ASSERT_EQ(all.rows, 700);
  const double image = double(all.total());
  const cv::Mat green = pixels_of(all, on_screen(kGreen)), blue = pixels_of(all, on_screen(kBlue));
  const int green_px = cv::countNonZero(green), blue_px = cv::countNonZero(blue);
  const int background_px = cv::countNonZero(pixels_of(all, kBackground));
  std::printf("screenshot: green (L1) %d px, blue (L2) %d px, background %d px of %.0f\n", green_px, blue_px,
              background_px, image);
  // Each 1 m square seen from the default view covers a few percent of the window.
  constexpr double kMinLayerShare = 0.01;
  EXPECT_GT(green_px, kMinLayerShare * image);
  EXPECT_GT(blue_px, kMinLayerShare * image);
  EXPECT_GT(background_px, 0.5 * image);  // the rest is background (less the panel and the readout)
  // The bottom-right corner holds no part of the model nor of the page's boxes.
  const cv::Rect corner(all.cols - 60, all.rows - 60, 60, 60);
  EXPECT_EQ(cv::countNonZero(pixels_of(all(corner), kBackground)), corner.area());
  // L1 is west of L2: its pixels lie left of L2's on the screen (the view looks north-west-ish down).
  const cv::Moments mg = cv::moments(green, true), mb = cv::moments(blue, true);
  EXPECT_LT(mg.m10 / mg.m00, mb.m10 / mb.m00);

  // L2 switched off by the URL: none of its colour, its pixels now the background.
  const cv::Mat blue_after = pixels_of(hidden, on_screen(kBlue)), background_after = pixels_of(hidden, kBackground);
  EXPECT_EQ(cv::countNonZero(blue_after), 0);
  cv::Mat was_blue_now_background;
  cv::bitwise_and(blue, background_after, was_blue_now_background);
  EXPECT_GT(cv::countNonZero(was_blue_now_background), 0.98 * blue_px);
  // L1 drawn as before, pixel for pixel but for the few the marker's label crosses.
  const int green_after = cv::countNonZero(pixels_of(hidden, on_screen(kGreen)));
  EXPECT_NEAR(green_after, green_px, 0.01 * green_px);

  // ?shade=1 lights the layers: the same squares, no longer in their recorded colours.
  const fs::path shaded_png = dir / "shaded.png";
  ASSERT_TRUE(run_chromium("--window-size=1000,700 --screenshot=" + shaded_png.string(),
                           "file://" + html.string() + "?shade=1", dir / "shaded.out"))
      << test::read_text(dir / "shaded.out.err");
  const cv::Mat shaded = cv::imread(shaded_png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(shaded.empty());
  const int shaded_layers = cv::countNonZero(pixels_of(shaded, on_screen(kGreen))) +
                            cv::countNonZero(pixels_of(shaded, on_screen(kBlue)));
  EXPECT_LT(shaded_layers, 0.1 * (green_px + blue_px));
  EXPECT_NEAR(cv::countNonZero(pixels_of(shaded, kBackground)), background_px, 0.01 * background_px);
}

// The measuring tool on marker GCP1: a click at the marker's place on the screen (the
// page's test hook gives it) reports its surveyed E, N, Z; with the markers hidden a click
// at the same place meets the surface under it, within 5 mm of the survey.
TEST(CliExportViewer, ClickOnAMarkerReportsItsSurveyWithinFiveMillimetres) {
  if (!fs::exists(kChromium)) GTEST_SKIP() << "no /usr/bin/chromium (apt-get install chromium)";
  test::ScratchDir dir("viewer_marker_click");
  const fs::path site = two_layer_site(dir), html = dir / "site.html";
  const auto r = run_strata({"export", "viewer", site.string(), "--out", html.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string probe = R"(<script>setTimeout(function () {
    var v = document.getElementById('view'), hook = window.strataViewer, out = document.createElement('div');
    function click(p) {
      var o = { clientX: p.x, clientY: p.y, bubbles: true };
      v.dispatchEvent(new PointerEvent('pointerdown', o));
      v.dispatchEvent(new PointerEvent('pointerup', o));
    }
    document.getElementById('measure').checked = true;
    var p = hook.screenPositionOf('marker GCP1');
    click(p);
    var markers = document.getElementById('show-markers');
    markers.checked = false;
    markers.dispatchEvent(new Event('change'));
    click(p);
    out.id = 'probe';
    out.textContent = 'at ' + p.x + ' ' + p.y + ' | ' + document.getElementById('readout').textContent.replace(/\n/g, ' | ');
    document.body.appendChild(out);
  }, 2000);</script>)";
  std::string page = test::read_text(html);
  page.insert(page.rfind("</body>"), probe);
  test::write_text(dir / "probe.html", page);
  ASSERT_TRUE(run_chromium("--window-size=1000,700 --dump-dom", "file://" + (dir / "probe.html").string(), dir / "dom.html"))
      << test::read_text(dir / "dom.html.err");
  const std::string dom = test::read_text(dir / "dom.html");
  std::smatch m;
  const std::regex readout(
      R"(<div id="probe">at ([0-9.]+) ([0-9.]+) \| P1  E ([0-9.]+)  N ([0-9.]+)  Z ([0-9.]+)  marker GCP1 \(surveyed\) \| )"
      R"(P2  E ([0-9.]+)  N ([0-9.]+)  Z ([0-9.]+) \| 3D ([0-9.]+) m)");
  ASSERT_TRUE(std::regex_search(dom, m, readout)) << dom.substr(std::min(dom.size(), dom.find("probe")), 600);
  std::printf("marker GCP1 at client pixel (%s, %s); %s\n", m[1].str().c_str(), m[2].str().c_str(), m[0].str().c_str());
  constexpr double kClickTolerance = 0.005;  // metres: the acceptance of the viewer's measuring tool
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(std::stod(m[3 + k]), kMarkerOnL1[k], kClickTolerance) << "marker, axis " << k;
    EXPECT_NEAR(std::stod(m[6 + k]), kMarkerOnL1[k], kClickTolerance) << "surface, axis " << k;
  }
  EXPECT_LT(std::stod(m[9]), kClickTolerance);  // the two points' distance
  // The surface point is the surface's, not the marker's snapped again: Z is the layer's.
  EXPECT_NEAR(std::stod(m[8]), kSiteOrigin.z() + kLayerZ, 1e-3);
}

// A layer of 3200 faces with --coarse-lod 2: the page holds it at about 200 faces (shown
// at once) and at 3200 (after), and the browser shows the coarse level, then the full one.
TEST(CliExportViewer, LargeLayerIsShownCoarseFirstThenAtItsFullLevel) {
  test::ScratchDir dir("viewer_levels");
  const fs::path site = project_with_layer(dir), html = dir / "site.html";
  const DenseMesh grid = coloured_grid(40);
  record_dense_mesh(site, "L1", grid);
  auto r = run_strata({"export", "viewer", site.string(), "--coarse-lod", "2", "--out", html.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("(coarse level 2), then all 3200"), std::string::npos) << r.err;
  const std::string page = test::read_text(html);
  EXPECT_NE(page.find("data-detail=\"yes\""), std::string::npos);
  test::write_text(dir / "first.glb", embedded_model(page, "model"));
  test::write_text(dir / "detail.glb", embedded_model(page, "model-detail"));
  const nlohmann::json first = glb_json(dir / "first.glb"), detail = glb_json(dir / "detail.glb");
  ASSERT_TRUE(first.is_object());
  ASSERT_TRUE(detail.is_object());
  const std::size_t coarse_faces = glb_faces(first), target = grid.faces.size() / 16;
  constexpr double kMinShareOfTarget = 0.8;  // as the levels of detail of export model
  EXPECT_LE(coarse_faces, target);
  EXPECT_GE(double(coarse_faces), kMinShareOfTarget * double(target));
  EXPECT_EQ(glb_faces(detail), grid.faces.size());
  EXPECT_EQ(detail["nodes"][0]["name"], "layer L1");
  // The detail comes after the page's script, so the browser can draw before parsing it.
  EXPECT_GT(page.find("<script id=\"model-detail\""), page.find("window.strataViewer"));

  // --coarse-lod 0: the full level alone.
  r = run_strata({"export", "viewer", site.string(), "--coarse-lod", "0", "--out", (dir / "full.html").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string full_page = test::read_text(dir / "full.html");
  EXPECT_EQ(full_page.find("<script id=\"model-detail\""), std::string::npos);
  test::write_text(dir / "full.glb", embedded_model(full_page));
  EXPECT_EQ(glb_faces(glb_json(dir / "full.glb")), grid.faces.size());

  if (!fs::exists(kChromium)) GTEST_SKIP() << "no /usr/bin/chromium (apt-get install chromium)";
  // Waits on the status box's data-level, not on a timer: a polling timer lets
  // headless Chromium's virtual time run out before the full level has been parsed.
  const std::string probe = R"(<script>(function () {
    function record() {
      if (window.strataViewer.level() !== 'full' || document.getElementById('probe')) return;
      var out = document.createElement('div');
      out.id = 'probe';
      out.textContent = JSON.stringify(window.strataViewer.levels);
      document.body.appendChild(out);
    }
    new MutationObserver(record).observe(document.getElementById('status'), { attributes: true, childList: true });
    record();
  })();</script>)";
  std::string probed = page;
  probed.insert(probed.rfind("</body>"), probe);
  test::write_text(dir / "probe.html", probed);
  // Headless Chromium's virtual time sometimes runs out before the full level is parsed
  // under load (about one run in five with the suite beside it: the page's
  // requestAnimationFrame steps and virtual time race). A dump without the probe is
  // taken again, up to kDumpTries times; what the dump must show is asserted below as
  // before. The race itself is an open problem (docs/model.md, Viewer).
  constexpr int kDumpTries = 5;
  std::string dom;
  for (int attempt = 0; attempt < kDumpTries; ++attempt) {
    ASSERT_TRUE(run_chromium("--window-size=800,600 --dump-dom", "file://" + (dir / "probe.html").string(),
                             dir / "dom.html"))
        << test::read_text(dir / "dom.html.err");
    dom = test::read_text(dir / "dom.html");
    if (dom.find("<div id=\"probe\">") != std::string::npos) break;
  }
  std::smatch m;
  ASSERT_TRUE(std::regex_search(dom, m, std::regex(R"(<div id="probe">([^<]*)</div>)"))) << dom.substr(0, 2000);
  const nlohmann::json levels = nlohmann::json::parse(m[1].str());
  ASSERT_EQ(levels.size(), 2u) << levels.dump();
  EXPECT_EQ(levels[0]["level"], "coarse");
  EXPECT_EQ(std::size_t(levels[0]["layerFaces"]), coarse_faces);
  EXPECT_EQ(levels[1]["level"], "full");
  EXPECT_EQ(std::size_t(levels[1]["layerFaces"]), grid.faces.size());
  ASSERT_TRUE(std::regex_search(dom, m, std::regex(R"(<div id="status"[^>]*>([^<]*)</div>)")));
  EXPECT_EQ(m[1].str(), "loaded 1 nodes");
  EXPECT_NE(m[0].str().find("data-level=\"full\""), std::string::npos) << m[0].str();
}

}  // namespace
}  // namespace strata
