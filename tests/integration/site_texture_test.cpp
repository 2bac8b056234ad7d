// `strata export model DIR --texture` without --layer: the site model with every
// aligned layer textured from its photos, on a small synthetic layer processed through
// the CLI (the faults suite's shared project, made once per test run); and a photo
// gone from the project refused naming it, with nothing written.
#include "field_project.hpp"
#include "support/recorded_mesh.hpp"
#include "support/test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <regex>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

class SiteTexture : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    try {
      shared_ = test::shared_project("faults", 1, 12, 5, std::vector<std::string>{});
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the shared project could not be made: " << setup_error_;
  }
  static fs::path shared_;
  static std::string setup_error_;
};
fs::path SiteTexture::shared_;
std::string SiteTexture::setup_error_;

const nlohmann::json* node_named(const nlohmann::json& gltf, const std::string& name) {
  for (const auto& n : gltf.at("nodes")) {
    if (n.value("name", "") == name) return &n;
  }
  return nullptr;
}

TEST_F(SiteTexture, SiteModelTexturesTheAlignedLayer) {
  test::ScratchDir dir("site_texture");
  const fs::path site = shared_ / "template", out = dir / "site.glb";
  const auto r = run_strata({"export", "model", site.string(), "--texture", "--lod", "1", "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("1 layers of which 1 textured"), std::string::npos) << r.err;
  const nlohmann::json g = test::glb_json(out);
  ASSERT_TRUE(g.is_object());
  const nlohmann::json* layer = node_named(g, "layer L1");
  ASSERT_NE(layer, nullptr);
  const nlohmann::json& mesh = g.at("meshes").at(layer->at("mesh").get<int>());
  ASSERT_GE(mesh.at("primitives").size(), 1u);
  for (const auto& prim : mesh.at("primitives")) {
    EXPECT_TRUE(prim.at("attributes").contains("TEXCOORD_0"));
    EXPECT_FALSE(prim.at("attributes").contains("COLOR_0"));  // it would multiply the texture
    const auto& material = g.at("materials").at(prim.at("material").get<int>());
    const int texture = material.at("pbrMetallicRoughness").at("baseColorTexture").at("index");
    const int image = g.at("textures").at(texture).at("source");
    EXPECT_EQ(g.at("images").at(image).at("mimeType"), "image/jpeg");
  }
  // Colour gains between the photos, fitted over the faces several see: the log gives
  // their range and the RMS of the log colour ratios, which the fit lowers; without
  // them (--no-colour-gains) no gains are fitted.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m, std::regex(R"(colour gains ([0-9.]+)-([0-9.]+) fitted on ([0-9]+) overlaps; )"
                                                     R"(RMS of log colour ratios between photos ([0-9.]+) before, ([0-9.]+) after)")))
      << r.err;
  std::printf("%s\n", m[0].str().c_str());
  EXPECT_GT(std::stoul(m[3]), 0u);
  EXPECT_LE(std::stod(m[1]), std::stod(m[2]));
  EXPECT_LT(std::stod(m[5]), std::stod(m[4]));
  const auto plain_colours = run_strata({"export", "model", site.string(), "--texture", "--no-colour-gains", "--lod", "1",
                                         "--out", (dir / "no_gains.glb").string()});
  ASSERT_EQ(plain_colours.exit_code, 0) << plain_colours.err;
  EXPECT_EQ(plain_colours.err.find("colour gains"), std::string::npos) << plain_colours.err;
  // The untextured site model of the same project has no images at all.
  const fs::path plain = dir / "plain.glb";
  ASSERT_EQ(run_strata({"export", "model", site.string(), "--lod", "1", "--out", plain.string()}).exit_code, 0);
  EXPECT_FALSE(test::glb_json(plain).contains("images"));
}

TEST_F(SiteTexture, AMissingPhotoIsNamedAndNothingIsWritten) {
  test::ScratchDir dir("site_texture_missing");
  const fs::path site = dir / "site", out = dir / "site.glb";
  test::copy_scene(shared_ / "template", site);
  std::vector<fs::path> photos;
  for (const auto& e : fs::recursive_directory_iterator(site / "media")) {
    if (e.is_regular_file()) photos.push_back(e.path());
  }
  ASSERT_FALSE(photos.empty());
  std::sort(photos.begin(), photos.end());
  const fs::path gone = photos[photos.size() / 2];
  fs::remove(gone);
  const auto r =
      run_strata({"-q", "export", "model", site.string(), "--texture", "--lod", "1", "--out", out.string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(gone.filename().string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace strata
