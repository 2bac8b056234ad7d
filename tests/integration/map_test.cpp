// The field station's map through its API (docs/api.md, "The map"): what GET /api/map
// lists for a processed layer, tiles cut from its orthophoto and DTM on Leaflet's
// L.CRS.Simple grid in the site frame, their refusals, and sections drawn along a line
// as `strata export section` draws them.
#include "integration/served.hpp"

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <fstream>
#include <set>

namespace strata {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::run_strata;
using test::Served;

constexpr int kTilePx = 256;
// A tile of real data shows this many distinct grey levels at least: a flat or
// constant hillshade would show one or two.
constexpr int kMinHillshadeGreyLevels = 8;

std::string error_field(const httplib::Result& r) { return json::parse(r->body).at("error").value("field", ""); }
std::string error_message(const httplib::Result& r) { return json::parse(r->body).at("error").at("message"); }

cv::Mat decoded(const std::string& png) {
  const std::vector<std::uint8_t> bytes(png.begin(), png.end());
  return cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
}

int opaque_pixels(const cv::Mat& bgra) {
  std::vector<cv::Mat> ch;
  cv::split(bgra, ch);
  return cv::countNonZero(ch[3]);
}

// The tile (x, y) at zoom z holding the site-frame point (e, n): L.CRS.Simple's
// pixel (e * 2^z, -n * 2^z) divided by the tile size.
std::pair<long, long> tile_of(double e, double n, int z) {
  const double scale = std::ldexp(1.0, z);
  return {long(std::floor(e * scale / kTilePx)), long(std::floor(-n * scale / kTilePx))};
}

class Map : public ::testing::Test {
 protected:
  static inline const bool kIgnoreSigpipe = (std::signal(SIGPIPE, SIG_IGN), true);
  // One layer processed to products (L1), and the same synthetic site with its two
  // layers both processed, so that a section has two surfaces to cut; each made once
  // for every process of the suite (support/shared_scene.hpp).
  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir("map");
    try {
      one_ = test::shared_project("map_l1", 1, 12, 5, std::vector<std::string>{});
      two_ = test::shared_scene("map_two_layers", "layers 2 photos 14 seed 5 process L1 L2", [](const fs::path& dir) {
        test::synth(dir / "data", 1, 14, 5);
        test::make_project(dir / "template", dir / "data", 2);
        for (const char* layer : {"L1", "L2"}) {
          const auto r = run_strata({"-q", "process", (dir / "template").string(), "--layer", layer});
          if (r.exit_code != 0) throw std::runtime_error(std::string("process ") + layer + ": " + r.err);
        }
      });
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the shared projects could not be made: " << setup_error_;
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }
  static fs::path copy(const fs::path& shared, const std::string& name) {
    const fs::path f = scratch_->path() / name;
    fs::remove_all(f);
    fs::create_directories(f);
    test::copy_scene(shared / "template", f / "site");
    return f;
  }
  static test::ScratchDir* scratch_;
  static fs::path one_, two_;
  static std::string setup_error_;
};
test::ScratchDir* Map::scratch_ = nullptr;
fs::path Map::one_, Map::two_;
std::string Map::setup_error_;

TEST_F(Map, ListsTheProcessedLayerWithBoundsThatHoldItsMarkers) {
  const fs::path f = copy(one_, "listed");
  Served s(f, f / "site");
  const json map = s.get("/api/map");
  EXPECT_EQ(map.at("crs"), "EPSG:32636");
  ASSERT_EQ(map.at("layers").size(), 1u) << map.dump();
  const json& l1 = map.at("layers")[0];
  EXPECT_EQ(l1.at("name"), "L1");
  EXPECT_EQ(l1.at("unit"), "101");
  for (const char* kind : {"ortho", "dtm"}) {
    const json& b = l1.at(kind);
    ASSERT_TRUE(b.is_object()) << kind;
    EXPECT_LT(b.at("e_min").get<double>(), b.at("e_max").get<double>()) << kind;
    EXPECT_LT(b.at("n_min").get<double>(), b.at("n_max").get<double>()) << kind;
  }
  // The markers surveyed around the trench's edge lie on the layer's rasters or just
  // beyond their edge (the synthetic trench's markers stand up to 0.6 m outside what
  // the photos reconstruct): the bounds are in the markers' place, in site CRS metres.
  constexpr double kMarkerRing_m = 1.0;
  ASSERT_FALSE(map.at("markers").empty());
  for (const char* kind : {"ortho", "dtm"}) {
    const json& b = l1.at(kind);
    for (const auto& m : map.at("markers")) {
      const double e = m.at("e"), n = m.at("n");
      EXPECT_TRUE(e > b.at("e_min").get<double>() - kMarkerRing_m && e < b.at("e_max").get<double>() + kMarkerRing_m &&
                  n > b.at("n_min").get<double>() - kMarkerRing_m && n < b.at("n_max").get<double>() + kMarkerRing_m)
          << m.dump() << " far outside the " << kind << " " << b.dump();
    }
  }
  // Contours and the footprint as GeoJSON in site CRS coordinates, within the DTM.
  const json& contours = map.at("contours").at("features");
  ASSERT_FALSE(contours.empty());
  const json& first = contours[0].at("geometry").at("coordinates")[0];
  EXPECT_GT(first[0].get<double>(), l1.at("dtm").at("e_min").get<double>());
  EXPECT_LT(first[1].get<double>(), l1.at("dtm").at("n_max").get<double>());
  ASSERT_EQ(map.at("footprints").at("features").size(), 1u);
  EXPECT_EQ(map.at("footprints").at("features")[0].at("geometry").at("type"), "MultiPolygon");
  EXPECT_FALSE(map.at("truncated").get<bool>());
}

TEST_F(Map, TilesShowTheLayerWhereItHasDataAndNothingElsewhere) {
  const fs::path f = copy(one_, "tiles");
  Served s(f, f / "site");
  const json map = s.get("/api/map");
  const json& b = map.at("layers")[0].at("ortho");
  const double oe = map.at("origin")[0], on = map.at("origin")[1];
  // The zoom at which a tile pixel is about one orthophoto pixel, and the tile at its centre.
  const int z = int(std::lround(std::log2(1 / b.at("pixel_m").get<double>())));
  const auto [x, y] = tile_of((b.at("e_min").get<double>() + b.at("e_max").get<double>()) / 2 - oe,
                              (b.at("n_min").get<double>() + b.at("n_max").get<double>()) / 2 - on, z);
  const std::string path = fmt::format("/api/layers/L1/tiles/ortho/{}/{}/{}", z, x, y);
  const auto r = s.client().Get(path.c_str());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(r->get_header_value("Cache-Control"), "no-store");  // no ?v=: not kept
  const cv::Mat tile = decoded(r->body);
  ASSERT_FALSE(tile.empty());
  EXPECT_EQ(tile.cols, kTilePx);
  EXPECT_EQ(tile.rows, kTilePx);
  ASSERT_EQ(tile.channels(), 4);
  EXPECT_GT(opaque_pixels(tile), kTilePx * kTilePx / 2) << "the tile at the orthophoto's centre is mostly data";

  const auto versioned = s.client().Get((path + "?v=" + b.at("version").get<std::string>()).c_str());
  ASSERT_TRUE(versioned);
  EXPECT_EQ(versioned->get_header_value("Cache-Control"), "private, max-age=86400");

  const auto far = s.client().Get(fmt::format("/api/layers/L1/tiles/ortho/{}/{}/{}", z, x + 1000, y).c_str());
  ASSERT_TRUE(far);
  ASSERT_EQ(far->status, 200);
  const cv::Mat empty = decoded(far->body);
  ASSERT_EQ(empty.channels(), 4);
  EXPECT_EQ(opaque_pixels(empty), 0) << "a tile far from the data is transparent";

  const auto hs = s.client().Get(fmt::format("/api/layers/L1/tiles/hillshade/{}/{}/{}", z, x, y).c_str());
  ASSERT_TRUE(hs);
  ASSERT_EQ(hs->status, 200) << hs->body;
  const cv::Mat shade = decoded(hs->body);
  ASSERT_EQ(shade.channels(), 4);
  ASSERT_GT(opaque_pixels(shade), 0);
  std::set<int> greys;
  for (int row = 0; row < shade.rows; ++row) {
    for (int col = 0; col < shade.cols; ++col) {
      const auto p = shade.at<cv::Vec4b>(row, col);
      if (p[3] > 0) greys.insert(p[0]);
    }
  }
  EXPECT_GE(int(greys.size()), kMinHillshadeGreyLevels) << "the hillshade varies with the surface";
}

TEST_F(Map, BadTilesAreRefusedNamingTheField) {
  const fs::path f = copy(one_, "bad_tiles");
  Served s(f, f / "site");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"/api/layers/L1/tiles/dem/5/0/0", "kind"},
      {"/api/layers/L1/tiles/ortho/99/0/0", "z"},
      {"/api/layers/L1/tiles/ortho/5/a/0", "x"},
      {"/api/layers/L1/tiles/ortho/5/0/1.5", "y"},
  };
  for (const auto& [path, field] : cases) {
    const auto r = s.client().Get(path.c_str());
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, 400) << path << ": " << r->body;
    EXPECT_EQ(error_field(r), field) << path;
  }
  const auto missing = s.client().Get("/api/layers/L9/tiles/ortho/5/0/0");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
  EXPECT_EQ(error_field(missing), "layer");
}

TEST_F(Map, ASectionNeedsTwoSurfacesAndAGoodLine) {
  const fs::path f = copy(one_, "section_one");
  Served s(f, f / "site");
  const json map = s.get("/api/map");
  const double oe = map.at("origin")[0], on = map.at("origin")[1];
  const auto r = s.post("/api/sections", {{"e1", oe}, {"n1", on}, {"e2", oe + 1}, {"n2", on + 1}});
  ASSERT_GE(r->status, 400);
  ASSERT_LT(r->status, 500) << r->body;
  // The volume code's own refusal: "volume: 1 layer(s) have a surface; at least two are needed ...".
  EXPECT_NE(error_message(r).find("at least two"), std::string::npos) << error_message(r);

  const std::vector<std::pair<json, std::string>> bad = {
      {{{"e1", "x"}, {"n1", on}, {"e2", oe + 1}, {"n2", on}}, "e1"},
      {{{"e1", oe}, {"n1", on}, {"e2", oe + 1}}, "n2"},
      {{{"e1", oe}, {"n1", on}, {"e2", oe}, {"n2", on}}, "e2"},
      {{{"e1", oe}, {"n1", on}, {"e2", oe + 5000}, {"n2", on}}, "e2"},
  };
  for (const auto& [body, field] : bad) {
    const auto b = s.post("/api/sections", body);
    EXPECT_EQ(b->status, 400) << body.dump() << ": " << b->body;
    EXPECT_EQ(error_field(b), field) << body.dump();
  }
  // Without the CSRF token, as every POST.
  const auto no_token = s.client().Post("/api/sections", json{{"e1", oe}}.dump(), "application/json");
  ASSERT_TRUE(no_token);
  EXPECT_EQ(no_token->status, 403);
}

TEST_F(Map, ASectionIsTheDrawingTheCommandLineMakes) {
  const fs::path f = copy(two_, "section_two");
  Served s(f, f / "site");
  const json map = s.get("/api/map");
  ASSERT_EQ(map.at("layers").size(), 2u);
  const json& b = map.at("layers")[0].at("dtm");
  const double e_min = b.at("e_min"), e_max = b.at("e_max"), n_mid = (b.at("n_min").get<double>() + b.at("n_max").get<double>()) / 2;
  const double e1 = e_min + 0.2 * (e_max - e_min), e2 = e_max - 0.2 * (e_max - e_min);
  const auto r = s.post("/api/sections", {{"e1", e1}, {"n1", n_mid}, {"e2", e2}, {"n2", n_mid}});
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "image/svg+xml");
  EXPECT_NE(r->body.find("<svg"), std::string::npos);
  EXPECT_NE(r->body.find("101"), std::string::npos) << "the unit dug between the layers is drawn";
  const fs::path out = f / "section.svg";
  const auto cli = run_strata({"-q", "export", "section", (f / "site").string(), "--line",
                               fmt::format("{:.17g},{:.17g},{:.17g},{:.17g}", e1, n_mid, e2, n_mid), "--out",
                               out.string()});
  ASSERT_EQ(cli.exit_code, 0) << cli.err;
  EXPECT_EQ(r->body, test::read_text(out)) << "the same drawing as strata export section";
}

}  // namespace
}  // namespace strata
