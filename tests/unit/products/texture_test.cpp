// Texture atlas (products.texture) from views rendered of an analytic scene: a
// floor with a smooth colour field and a 15 cm blue box standing on it, seen by two
// cameras (texture_scene.hpp).
#include "core/error.hpp"
#include "products/texture_atlas.hpp"
#include "texture_scene.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cmath>

namespace strata {
namespace {

using namespace texture_scene;

// The atlas colour at surface point P on the floor: its face, barycentric UV,
// bilinear in the atlas.
std::optional<std::array<double, 3>> texel_at(const TexturedMesh& t, const Eigen::Vector3d& P, int* view) {
  for (std::size_t f = 0; f < t.mesh.faces.size(); ++f) {
    const auto& v = t.mesh.faces[f];
    const Eigen::Vector3d a = t.mesh.vertices[v[0]], b = t.mesh.vertices[v[1]], c = t.mesh.vertices[v[2]];
    if (std::abs(a.z()) > 1e-9 || std::abs(b.z()) > 1e-9 || std::abs(c.z()) > 1e-9) continue;
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    const double wa = ((b.x() - P.x()) * (c.y() - P.y()) - (b.y() - P.y()) * (c.x() - P.x())) / area;
    const double wb = ((c.x() - P.x()) * (a.y() - P.y()) - (c.y() - P.y()) * (a.x() - P.x())) / area;
    const double wc = 1 - wa - wb;
    if (wa < 0 || wb < 0 || wc < 0) continue;
    const Eigen::Vector2f uv = float(wa) * t.uv[v[0]] + float(wb) * t.uv[v[1]] + float(wc) * t.uv[v[2]];
    const TextureImage& im = t.atlases[std::size_t(t.face_atlas[f])];
    const double x = uv.x() * im.width - 0.5, y = uv.y() * im.height - 0.5;
    const int xi = int(std::floor(x)), yi = int(std::floor(y));
    const double ax = x - xi, ay = y - yi;
    std::array<double, 3> out{};
    for (int k = 0; k < 3; ++k) {
      auto at = [&](int xx, int yy) { return double(im.rgb[(std::size_t(yy) * im.width + xx) * 3 + k]); };
      out[k] = (1 - ay) * ((1 - ax) * at(xi, yi) + ax * at(xi + 1, yi)) + ay * ((1 - ax) * at(xi, yi + 1) + ax * at(xi + 1, yi + 1));
    }
    *view = t.face_view[f];
    return out;
  }
  return std::nullopt;
}

TextureOptions small_atlas() {
  TextureOptions o;
  o.atlas_size_px = 512;
  return o;
}

TEST(TextureAtlas, TexelsCarryThePhotoColourOfTheirSurfacePoint) {
  const Scene s;
  TextureSummary sum;
  const TexturedMesh t = build_texture_atlas(s.mesh, s.views, small_atlas(), &sum);
  EXPECT_EQ(sum.views_used, 2);
  EXPECT_GT(sum.textured_faces, sum.faces * 8 / 10);
  EXPECT_EQ(t.uv.size(), t.mesh.vertices.size());
  int checked = 0;
  for (double x = -0.25; x <= 0.25; x += 0.0371) {
    for (double y = -0.25; y <= 0.25; y += 0.0413) {
      if (std::abs(x) < kBoxHalf + 0.1 && std::abs(y) < kBoxHalf + 0.1) continue;  // box and its shadows
      int view = -1;
      const auto c = texel_at(t, {x, y, 0}, &view);
      ASSERT_TRUE(c);
      if (view < 0) continue;
      const auto truth = floor_colour(x, y);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR((*c)[k], truth[k], kColourTolerance) << x << " " << y << " ch " << k;
      ++checked;
    }
  }
  EXPECT_GT(checked, 50);
}

TEST(TextureAtlas, FloorHiddenBehindTheBoxFromTheCloserCameraComesFromTheOther) {
  const Scene s;
  const TexturedMesh t = build_texture_atlas(s.mesh, s.views, small_atlas());
  int view = -1;
  // A point in front of the closer camera A: A wins.
  auto c = texel_at(t, {-0.15, 0.0, 0}, &view);
  ASSERT_TRUE(c);
  EXPECT_EQ(view, 0);
  // Behind the box seen from A (its ray passes through the box): B, with the floor's colour, not the box's blue.
  c = texel_at(t, {0.09, 0.0, 0}, &view);
  ASSERT_TRUE(c);
  EXPECT_EQ(view, 1);
  const auto truth = floor_colour(0.09, 0.0);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR((*c)[k], truth[k], kColourTolerance);
}

TEST(TextureAtlas, SmallAtlasShrinksTheTexelScaleAndEncodes) {
  const Scene s;
  TextureOptions o = small_atlas();
  o.atlas_size_px = 128;
  o.max_atlases = 1;
  TextureSummary sum;
  const TexturedMesh t = build_texture_atlas(s.mesh, s.views, o, &sum);
  EXPECT_EQ(t.atlases.size(), 1u);
  EXPECT_LT(sum.texel_scale, 1.0);
  for (int q : {0, 90}) {
    const std::string bytes = encode_texture_image(t.atlases[0], q);
    const cv::Mat back = cv::imdecode(std::vector<std::uint8_t>(bytes.begin(), bytes.end()), cv::IMREAD_COLOR);
    EXPECT_EQ(back.cols, 128);
    EXPECT_EQ(back.rows, 128);
  }
  o.gutter_px = 0;
  EXPECT_THROW(build_texture_atlas(s.mesh, s.views, o), InputError);
}

}  // namespace
}  // namespace strata
