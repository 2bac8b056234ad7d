// Check of a textured model against its photos (products.model_check) on the
// ray-traced scene of the texture tests (texture_scene.hpp): the model rendered from
// photo A's camera agrees with photo A; a wrong texture does not.
#include "core/error.hpp"
#include "products/model_check.hpp"
#include "products/texture_atlas.hpp"
#include "texture_scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace strata {
namespace {

using namespace texture_scene;

// Render vs photo. At texel scale 1 a chart is a cut-out of its photo: a texel is
// the photo sampled (bilinear) within a pixel of a pixel centre, and the render
// samples the atlas again (bilinear) where that pixel's surface point falls, so a
// rendered pixel is the photo displaced by at most half a pixel in each
// interpolation: about 1 grey level over the floor's field (up to about 2 grey
// levels per pixel), plus 8-bit rounding of atlas and render (0.5 each). So a
// median of 1 grey level; the 90th percentile 3, to leave the faces textured from
// the farther photo B (its coarser pixels resampled into A) and the box's silhouette
// (straight z-buffer edges against the ray-traced edge, well under 10 % of the
// pixels) their share. Measured: median 0, p90 1 per channel.
constexpr double kMedianTolerance = 1;
constexpr double kP90Tolerance = 3;
// A texture shifted by this many texels misplaces colours by as many photo pixels:
// up to about 2 grey levels per pixel of the field, so several times the tolerances
// (measured: median 7.3, p90 14 grey levels).
constexpr int kRollTexels = 6;

TexturedMesh scene_texture(const Scene& s) {
  TextureOptions o;
  o.atlas_size_px = 512;
  return build_texture_atlas(s.mesh, s.views, o);
}

double worst(const std::array<double, 3>& v) { return *std::max_element(v.begin(), v.end()); }

TEST(ModelCheck, RenderFromAPhotosPoseAgreesWithThePhoto) {
  const Scene s;
  const TexturedMesh t = scene_texture(s);
  ModelCheckOptions o;
  o.images = true;
  const ModelCheckSummary sum = check_textured_model(t, s.views, {0}, o);
  ASSERT_EQ(sum.photos.size(), 1u);
  const PhotoCheck& a = sum.photos[0];
  EXPECT_EQ(a.view, "A");
  // The floor fills most of A's 320 x 240 frame.
  EXPECT_GT(a.all.pixels, 320u * 240 / 3);
  EXPECT_LE(worst(a.all.median), kMedianTolerance);
  EXPECT_LE(worst(a.all.p90), kP90Tolerance);
  EXPECT_LE(a.all.median_mean, kMedianTolerance);
  EXPECT_EQ(a.rendered.width, 320);
  EXPECT_EQ(a.rendered.height, 240);
  EXPECT_EQ(a.difference.rgb.size(), a.rendered.rgb.size());
  EXPECT_EQ(sum.all.pixels, a.all.pixels);  // one photo: pooled = its own
  // Most of what A sees is textured from A (the closer camera wins), and that part
  // is the resampling alone.
  EXPECT_GT(a.own.pixels, a.all.pixels / 2);
  EXPECT_LE(a.own.pixels, a.all.pixels);
  EXPECT_LE(a.own.median_mean, kMedianTolerance);
  // Without a region, inside = all.
  EXPECT_EQ(a.inside.pixels, a.all.pixels);
  EXPECT_EQ(a.inside.p90_mean, a.all.p90_mean);
  // From photo B as well (the faces A textures are resampled into B's view).
  const PhotoCheck b = check_textured_model(t, s.views, {1}, ModelCheckOptions{}).photos[0];
  EXPECT_GT(b.all.pixels, 1000u);
  EXPECT_LE(b.all.median_mean, kMedianTolerance);
}

TEST(ModelCheck, AWrongTextureOrPoseGivesClearlyLargerDifferences) {
  const Scene s;
  const TexturedMesh good = scene_texture(s);
  const ColourDifference right = check_textured_model(good, s.views, {0}, ModelCheckOptions{}).all;
  // The atlases rolled by a few texels: every chart reads its neighbour's colours.
  TexturedMesh rolled = good;
  for (TextureImage& im : rolled.atlases) {
    std::rotate(im.rgb.begin(), im.rgb.begin() + std::ptrdiff_t(kRollTexels * 3), im.rgb.end());
  }
  const ColourDifference shifted = check_textured_model(rolled, s.views, {0}, ModelCheckOptions{}).all;
  EXPECT_GT(shifted.median_mean, 4 * kMedianTolerance);
  EXPECT_GT(shifted.p90_mean, 2 * kP90Tolerance);
  EXPECT_GT(shifted.median_mean, 3 * right.median_mean);
  // Photo A compared with a render from B's pose: not the photo's view.
  std::vector<OrthoView> wrong_pose = s.views;
  wrong_pose[0].camera = s.views[1].camera;
  const ColourDifference moved = check_textured_model(good, wrong_pose, {0}, ModelCheckOptions{}).all;
  EXPECT_GT(moved.median_mean, 10 * kMedianTolerance);  // measured 62
}

TEST(ModelCheck, RegionScaleAndOptions) {
  const Scene s;
  const TexturedMesh t = scene_texture(s);
  ModelCheckOptions o;
  // The floor's centre quarter (box included).
  o.region = {{-0.15, -0.15}, {0.15, -0.15}, {0.15, 0.15}, {-0.15, 0.15}};
  const PhotoCheck full = check_textured_model(t, s.views, {0}, o).photos[0];
  EXPECT_GT(full.inside.pixels, 0u);
  EXPECT_LT(full.inside.pixels, full.all.pixels);
  o.scale = 0.5;
  o.images = true;
  const PhotoCheck half = check_textured_model(t, s.views, {0}, o).photos[0];
  EXPECT_EQ(half.rendered.width, 160);
  EXPECT_EQ(half.rendered.height, 120);
  // A quarter of the pixels, give or take the border and the silhouettes.
  EXPECT_NEAR(double(half.all.pixels), full.all.pixels / 4.0, full.all.pixels * 0.02);
  EXPECT_LE(half.all.median_mean, kMedianTolerance);
  // Two photos pooled: the pixels of both.
  const ModelCheckSummary two = check_textured_model(t, s.views, {0, 1}, ModelCheckOptions{});
  EXPECT_EQ(two.all.pixels, two.photos[0].all.pixels + two.photos[1].all.pixels);
  for (double bad : {0.0, 1.5}) {
    ModelCheckOptions b;
    b.scale = bad;
    EXPECT_THROW(check_textured_model(t, s.views, {0}, b), InputError);
  }
  ModelCheckOptions b;
  b.region = {{0, 0}, {1, 0}};
  EXPECT_THROW(check_textured_model(t, s.views, {0}, b), InputError);
  EXPECT_THROW(check_textured_model(t, s.views, {2}, ModelCheckOptions{}), InputError);
}

}  // namespace
}  // namespace strata
