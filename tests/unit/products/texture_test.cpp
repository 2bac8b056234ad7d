// Texture atlas (products.texture) from views rendered of an analytic scene: a
// floor with a smooth colour field and a 15 cm blue box standing on it, seen by two
// cameras with radial distortion. Camera A is closer (it would win every face it
// sees); floor behind the box, hidden from A, must come from camera B.
#include "core/error.hpp"
#include "products/texture_atlas.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cmath>

namespace strata {
namespace {

constexpr double kFloorHalf = 0.3, kFloorStep = 0.025;  // metres
constexpr double kBoxHalf = 0.05, kBoxH = 0.15;         // metres, box centred on the origin
// Texel vs truth: bilinear sampling of the photo twice (photo pixels, then the
// atlas) over a field that varies by about 2 grey levels per photo pixel, plus
// 8-bit rounding of both.
constexpr double kColourTolerance = 6;

std::array<double, 3> floor_colour(double x, double y) {
  return {128 + 100 * std::sin(20 * x), 128 + 100 * std::cos(17 * y), 60 + 40 * std::sin(11 * (x + y))};
}
const std::array<double, 3> kBoxColour = {30, 40, 220};

Camera camera_at(const Eigen::Vector3d& c) {
  Camera cam;
  cam.intrinsics = {320, 240, 300, 300, 159.5, 119.5, -0.05, 0.01};
  cam.pose = Pose::look_at(c, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY());
  return cam;
}

// Ray-traced photo of the scene (nearest of floor and box along each pixel's ray).
OrthoView render(const std::string& name, const Camera& cam) {
  OrthoView v;
  v.name = name;
  v.camera = cam;
  const Intrinsics& K = cam.intrinsics;
  v.rgb.resize(std::size_t(K.width) * K.height * 3);
  const Eigen::Vector3d C = cam.pose.centre();
  const Eigen::Vector3d lo(-kBoxHalf, -kBoxHalf, 0), hi(kBoxHalf, kBoxHalf, kBoxH);
  for (int y = 0; y < K.height; ++y) {
    for (int x = 0; x < K.width; ++x) {
      const Eigen::Vector3d d = cam.ray({double(x), double(y)});
      double t0 = 0, t1 = 1e9;
      for (int k = 0; k < 3; ++k) {
        double a = (lo[k] - C[k]) / d[k], b = (hi[k] - C[k]) / d[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a);
        t1 = std::min(t1, b);
      }
      const double t_floor = -C.z() / d.z();
      std::array<double, 3> c = {0, 0, 0};
      if (t0 <= t1 && t0 < t_floor) {
        c = kBoxColour;
      } else if (t_floor > 0) {
        const Eigen::Vector3d P = C + t_floor * d;
        c = floor_colour(P.x(), P.y());
      }
      for (int k = 0; k < 3; ++k) v.rgb[(std::size_t(y) * K.width + x) * 3 + k] = std::uint8_t(std::lround(c[k]));
    }
  }
  return v;
}

DenseMesh scene_mesh() {
  DenseMesh m;
  const int n = int(std::lround(2 * kFloorHalf / kFloorStep));
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.vertices.emplace_back(-kFloorHalf + i * kFloorStep, -kFloorHalf + j * kFloorStep, 0);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      m.faces.push_back({a, b, c});
      m.faces.push_back({a, c, d});
    }
  }
  // The box: top and four sides, outward normals (counter-clockwise from outside).
  auto quad = [&](Eigen::Vector3d p0, Eigen::Vector3d p1, Eigen::Vector3d p2, Eigen::Vector3d p3) {
    const int b = int(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {p0, p1, p2, p3});
    m.faces.push_back({b, b + 1, b + 2});
    m.faces.push_back({b, b + 2, b + 3});
  };
  const double s = kBoxHalf, h = kBoxH;
  quad({-s, -s, h}, {s, -s, h}, {s, s, h}, {-s, s, h});
  quad({-s, -s, 0}, {s, -s, 0}, {s, -s, h}, {-s, -s, h});
  quad({s, -s, 0}, {s, s, 0}, {s, s, h}, {s, -s, h});
  quad({s, s, 0}, {-s, s, 0}, {-s, s, h}, {s, s, h});
  quad({-s, s, 0}, {-s, -s, 0}, {-s, -s, h}, {-s, s, h});
  return m;
}

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

struct Scene {
  DenseMesh mesh = scene_mesh();
  std::vector<OrthoView> views = {render("A", camera_at({-0.3, 0.0, 0.6})), render("B", camera_at({0.5, 0.05, 1.2}))};
};

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
