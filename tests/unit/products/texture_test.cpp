// Texture atlas (products.texture) from views rendered of an analytic scene: a
// floor with a smooth colour field and a 15 cm blue box standing on it, seen by two
// cameras (texture_scene.hpp).
#include "core/error.hpp"
#include "products/model_check.hpp"
#include "products/texture_atlas.hpp"
#include "texture_scene.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdio>
#include <map>

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


// The atlas colour at texture coordinate uv (glTF: (0, 0) the atlas's top-left corner), bilinear.
std::array<double, 3> atlas_colour(const TextureImage& im, const Eigen::Vector2f& uv) {
  const double x = uv.x() * im.width - 0.5, y = uv.y() * im.height - 0.5;
  const int xi = std::clamp(int(std::floor(x)), 0, im.width - 2), yi = std::clamp(int(std::floor(y)), 0, im.height - 2);
  const double ax = x - xi, ay = y - yi;
  std::array<double, 3> out{};
  for (int k = 0; k < 3; ++k) {
    auto at = [&](int xx, int yy) { return double(im.rgb[(std::size_t(yy) * im.width + xx) * 3 + k]); };
    out[std::size_t(k)] =
        (1 - ay) * ((1 - ax) * at(xi, yi) + ax * at(xi + 1, yi)) + ay * ((1 - ax) * at(xi, yi + 1) + ax * at(xi + 1, yi + 1));
  }
  return out;
}

// The seam step: over every edge between two faces textured from different photos, the
// atlas colour at the edge's midpoint read through each face's own chart, |difference|
// averaged over the channels, then over the edges (grey levels). Both charts show the
// same surface point, so what differs is the photos' exposure (and the resampling).
struct SeamSteps {
  double mean = 0;
  std::size_t edges = 0;
};
SeamSteps seam_steps(const TexturedMesh& t) {
  // Vertices are duplicated per chart: edges are matched by their corners' positions.
  using Key = std::array<long, 6>;
  auto key_of = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    auto q = [](double v) { return std::lround(v * 1e6); };  // micrometres
    Key ka = {q(a.x()), q(a.y()), q(a.z()), q(b.x()), q(b.y()), q(b.z())};
    const Key kb = {q(b.x()), q(b.y()), q(b.z()), q(a.x()), q(a.y()), q(a.z())};
    return std::min(ka, kb);
  };
  struct Side {
    int face;
    Eigen::Vector2f uv_mid;
  };
  std::map<Key, std::vector<Side>> edges;
  for (std::size_t f = 0; f < t.mesh.faces.size(); ++f) {
    if (t.face_view[f] < 0) continue;
    const auto& v = t.mesh.faces[f];
    for (int k = 0; k < 3; ++k) {
      const int a = v[std::size_t(k)], b = v[std::size_t((k + 1) % 3)];
      edges[key_of(t.mesh.vertices[std::size_t(a)], t.mesh.vertices[std::size_t(b)])].push_back(
          {int(f), 0.5f * (t.uv[std::size_t(a)] + t.uv[std::size_t(b)])});
    }
  }
  SeamSteps s;
  double sum = 0;
  for (const auto& [key, sides] : edges) {
    if (sides.size() != 2 || t.face_view[std::size_t(sides[0].face)] == t.face_view[std::size_t(sides[1].face)]) continue;
    const auto c0 = atlas_colour(t.atlases[std::size_t(t.face_atlas[std::size_t(sides[0].face)])], sides[0].uv_mid);
    const auto c1 = atlas_colour(t.atlases[std::size_t(t.face_atlas[std::size_t(sides[1].face)])], sides[1].uv_mid);
    sum += (std::abs(c0[0] - c1[0]) + std::abs(c0[1] - c1[1]) + std::abs(c0[2] - c1[2])) / 3;
    ++s.edges;
  }
  s.mean = s.edges ? sum / double(s.edges) : 0;
  return s;
}

// Photo B 20 % brighter than photo A (A's pixels divided by 1.2, so that nothing clips):
// without gains every seam between A's and B's charts is a step of about a sixth of the
// floor's brightness; the gains fitted over the faces both see level it.
TEST(TextureAtlas, ColourGainsLevelTheSeamsBetweenPhotosOfDifferentExposure) {
  constexpr double kExposureRatio = 1.2;  // B / A
  Scene s;
  for (std::uint8_t& c : s.views[0].rgb) c = std::uint8_t(std::lround(c / kExposureRatio));
  TextureOptions o = small_atlas();
  o.colour_balance = false;
  TextureSummary plain_sum, balanced_sum;
  const SeamSteps plain = seam_steps(build_texture_atlas(s.mesh, s.views, o, &plain_sum));
  o.colour_balance = true;
  const TexturedMesh levelled = build_texture_atlas(s.mesh, s.views, o, &balanced_sum);
  const SeamSteps balanced = seam_steps(levelled);
  ASSERT_EQ(plain.edges, balanced.edges);  // the gains change colours, not the view choice
  // Seams exist where B takes over behind the box: enough edges to measure on.
  constexpr std::size_t kMinSeamEdges = 20;
  EXPECT_GE(plain.edges, kMinSeamEdges);
  // Without gains: the floor's mean of about 110 grey levels x (1 - 1 / 1.2).
  constexpr double kMinStepWithoutGains = 12;  // grey levels
  EXPECT_GT(plain.mean, kMinStepWithoutGains);
  // With them the step falls to the resampling's own (two bilinear resamplings of a
  // field of about 2 grey levels per pixel, 8-bit rounding).
  constexpr double kMaxStepWithGains = 3;  // grey levels
  EXPECT_LT(balanced.mean, kMaxStepWithGains);
  EXPECT_LT(balanced.mean, 0.25 * plain.mean);
  // The fitted gains: B / A = 1 / 1.2 in every channel; the regulariser keeps their
  // geometric mean at 1, so each moves half the way (in logs).
  ASSERT_EQ(balanced_sum.gains.size(), 2u);
  constexpr double kGainTolerance = 0.02;  // the faces' mean colours are 8-bit and resampled
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(balanced_sum.gains[1][std::size_t(k)] / balanced_sum.gains[0][std::size_t(k)], 1 / kExposureRatio,
                kGainTolerance) << k;
    EXPECT_NEAR(balanced_sum.gains[0][std::size_t(k)] * balanced_sum.gains[1][std::size_t(k)], 1.0, kGainTolerance) << k;
  }
  EXPECT_GT(balanced_sum.balance_rms_before, std::log(kExposureRatio) * 0.8);
  EXPECT_LT(balanced_sum.balance_rms_after, 0.25 * balanced_sum.balance_rms_before);
  for (const auto& g : plain_sum.gains) EXPECT_EQ(g, (std::array<double, 3>{1, 1, 1}));
  // The check against the photos compares each photo times its gains: on the faces
  // textured from photo A itself it still sees the resampling alone (the model check's
  // own test: median <= 1, p90 <= 3), not A's 9.5 % gain (about 10 grey levels).
  ASSERT_EQ(levelled.view_gains, balanced_sum.gains);
  const ColourDifference own = check_textured_model(levelled, s.views, {0}, ModelCheckOptions{}).own;
  EXPECT_GT(own.pixels, 1000u);
  EXPECT_LE(own.median_mean, 1.0);
  EXPECT_LE(own.p90_mean, 3.0);
  std::printf("seam step without gains %.2f, with gains %.2f grey levels over %zu edges; gains A %.4f %.4f %.4f, "
              "B %.4f %.4f %.4f; RMS log ratio %.4f -> %.4f on %zu overlaps\n", plain.mean, balanced.mean,
              plain.edges, balanced_sum.gains[0][0], balanced_sum.gains[0][1], balanced_sum.gains[0][2],
              balanced_sum.gains[1][0], balanced_sum.gains[1][1], balanced_sum.gains[1][2],
              balanced_sum.balance_rms_before, balanced_sum.balance_rms_after, balanced_sum.balance_overlaps);
}

}  // namespace
}  // namespace strata
