// True orthophoto from synthetic rendered views of an analytic scene: a textured
// floor with a painted red spot, and a 15 cm high blue block (a 'wall' that must not
// smear onto the floor behind it). The views differ in exposure.
#include "core/error.hpp"
#include "products/orthophoto.hpp"
#include "support/shared_scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

namespace strata {
namespace {

constexpr double kCell = 0.005;             // metres, DTM / orthophoto cell
constexpr double kSpotX = -0.20, kSpotY = 0.15, kSpotR = 0.02;  // metres, site frame
constexpr double kBlockX = 0.25, kBlockY = -0.05, kBlockHalf = 0.10, kBlockH = 0.15;
// Acceptance (docs/products.md): a known point lands within 2 orthophoto pixels of
// its true position.
constexpr double kPositionTolerancePx = 2.0;
// Exposure gains recovered to within 3 % (8-bit rounding, bilinear sampling).
constexpr double kGainTolerance = 0.03;
// Floor cells beside the block showing the block's blue: a handful at most (DTM
// cells straddling the wall's foot).
constexpr double kMaxSmearFraction = 0.02;
// Noisy-DTM test: +-1 cm of cell-to-cell noise (about what the fused surface
// shows at 5 mm cells outside the trench), and what the orthophoto must still give.
constexpr double kNoiseM = 0.01;
constexpr double kNoisyMinCoverage = 0.97;
constexpr double kNoisyMaxSeams = 0.15;
// Median rectification must remove most of the warp the noise causes: grey error
// against the exact-surface orthophoto at most this share of the noisy one's.
constexpr double kMedianShareOfNoisyError = 0.6;
// Antialiasing test (grey levels of 255, squares 40 and 220): point samples of a
// checkerboard finer than the cell spread over the two greys; cell averages of
// 2.5 x 2.5 periods vary only by the partial period at the cell edges.
constexpr double kAliasedMinSpread = 40;
constexpr double kAveragedMaxSpread = 20;

bool in_block(double x, double y) { return std::abs(x - kBlockX) < kBlockHalf && std::abs(y - kBlockY) < kBlockHalf; }
double height(double x, double y) { return in_block(x, y) ? kBlockH : 0.002 * std::sin(8 * x) * std::cos(6 * y); }

Eigen::Vector3d albedo(const Eigen::Vector3d& p) {
  if (p.z() > 0.02) return {40, 60, 200};  // block top and sides
  if (std::hypot(p.x() - kSpotX, p.y() - kSpotY) < kSpotR) return {200, 30, 30};
  const bool check = (int(std::floor(p.x() / 0.05)) + int(std::floor(p.y() / 0.05))) % 2 == 0;
  const double t = 0.5 + 0.5 * std::sin(37 * p.x() + 23 * p.y());
  return check ? Eigen::Vector3d(150 - 20 * t, 120, 90) : Eigen::Vector3d(100, 85 + 15 * t, 70);
}

// First intersection of the ray with the height field: march 1 mm steps from the
// top of the scene, then bisect.
bool cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, Eigen::Vector3d& hit) {
  if (d.z() >= 0) return false;
  double t = (o.z() - (kBlockH + 0.01)) / -d.z();
  const double t_end = (o.z() + 0.01) / -d.z();
  double prev = t;
  for (; t < t_end; t += 0.001) {
    const Eigen::Vector3d p = o + t * d;
    if (p.z() <= height(p.x(), p.y())) {
      double a = prev, b = t;
      for (int k = 0; k < 20; ++k) {
        const double m = 0.5 * (a + b);
        const Eigen::Vector3d q = o + m * d;
        (q.z() <= height(q.x(), q.y()) ? b : a) = m;
      }
      hit = o + b * d;
      return true;
    }
    prev = t;
  }
  return false;
}

// A 320 x 240 camera at `centre` looking at the origin, no pixels yet.
OrthoView camera_at(const std::string& name, const Eigen::Vector3d& centre) {
  OrthoView v;
  v.name = name;
  Intrinsics& K = v.camera.intrinsics;
  K.width = 320;
  K.height = 240;
  K.fx = K.fy = 300;
  K.cx = 159.5;
  K.cy = 119.5;
  K.k1 = -0.03;
  v.camera.pose = Pose::look_at(centre, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d::UnitY());
  return v;
}

OrthoView render(const std::string& name, const Eigen::Vector3d& centre, double exposure) {
  OrthoView v = camera_at(name, centre);
  const Intrinsics& K = v.camera.intrinsics;
  v.rgb.assign(std::size_t(K.width) * K.height * 3, 0);
  const Eigen::Vector3d C = v.camera.pose.centre();
  for (int y = 0; y < K.height; ++y) {
    for (int x = 0; x < K.width; ++x) {
      Eigen::Vector3d hit;
      Eigen::Vector3d col(20, 20, 20);
      if (cast(C, v.camera.ray(Eigen::Vector2d(x, y)), hit)) col = albedo(hit) * exposure;
      for (int k = 0; k < 3; ++k) {
        v.rgb[(std::size_t(y) * K.width + x) * 3 + k] = std::uint8_t(std::clamp(std::lround(col[k]), 0L, 255L));
      }
    }
  }
  return v;
}

Dtm analytic_dtm() {
  Dtm d;
  d.grid = {-0.45, 0.35, kCell, 180, 140};
  d.z.resize(d.grid.cells());
  for (int r = 0; r < d.grid.height; ++r)
    for (int c = 0; c < d.grid.width; ++c) d.z[d.grid.index(c, r)] = float(height(d.grid.x_centre(c), d.grid.y_centre(r)));
  return d;
}

class OrthoScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const std::vector<std::pair<Eigen::Vector3d, double>> cams = {
        {{0.0, 0.0, 1.0}, 1.00},   {{0.5, 0.1, 0.9}, 1.15},  {{-0.5, -0.1, 0.9}, 0.85},
        {{0.1, 0.5, 0.9}, 1.05},   {{-0.1, -0.5, 0.9}, 0.90}, {{0.6, -0.5, 0.8}, 1.10}};
    // The pixels are rendered once for every process of the suite (ctest runs each
    // test in its own process; support/shared_scene.hpp), the cameras made here.
    const auto name = [](std::size_t i) { return "v" + std::to_string(i); };
    const std::filesystem::path dir = test::shared_scene("ortho_views", "six views 320x240", [&](const auto& d) {
      for (std::size_t i = 0; i < cams.size(); ++i) {
        const OrthoView v = render(name(i), cams[i].first, cams[i].second);
        std::ofstream(d / (name(i) + ".rgb"), std::ios::binary)
            .write(reinterpret_cast<const char*>(v.rgb.data()), std::streamsize(v.rgb.size()));
      }
    });
    views_ = new std::vector<OrthoView>();
    for (std::size_t i = 0; i < cams.size(); ++i) {
      OrthoView v = camera_at(name(i), cams[i].first);
      v.rgb.resize(std::size_t(v.camera.intrinsics.width) * v.camera.intrinsics.height * 3);
      std::ifstream(dir / (name(i) + ".rgb"), std::ios::binary)
          .read(reinterpret_cast<char*>(v.rgb.data()), std::streamsize(v.rgb.size()));
      views_->push_back(std::move(v));
      exposures_.push_back(cams[i].second);
    }
  }
  static void TearDownTestSuite() { delete views_; }
  static std::vector<OrthoView>* views_;
  static std::vector<double> exposures_;
};
std::vector<OrthoView>* OrthoScene::views_ = nullptr;
std::vector<double> OrthoScene::exposures_;

TEST_F(OrthoScene, SpotLandsWithinTwoPixelsAndWallDoesNotSmear) {
  const Dtm dtm = analytic_dtm();
  OrthoSummary s;
  const RgbaRaster img = build_orthophoto(dtm, *views_, OrthoOptions{}, &s);
  EXPECT_GT(s.coverage, 0.95);
  EXPECT_GE(s.views_used, 3);
  const RasterGrid& g = img.grid;
  double sx = 0, sy = 0, n = 0;
  std::size_t floor_near = 0, smeared = 0;
  for (int r = 0; r < g.height; ++r) {
    for (int c = 0; c < g.width; ++c) {
      const std::uint8_t* p = &img.rgba[g.index(c, r) * 4];
      if (p[3] == 0) continue;
      const double x = g.x_centre(c), y = g.y_centre(r);
      if (p[0] > 140 && p[1] < 90 && p[2] < 90) {
        sx += c;
        sy += r;
        ++n;
      }
      // Floor within 2..8 cm of the block: hidden behind it in the oblique views.
      const double dx = std::abs(x - kBlockX) - kBlockHalf, dy = std::abs(y - kBlockY) - kBlockHalf;
      const double dist = std::max(dx, dy);
      if (dist > 0.02 && dist < 0.08) {
        ++floor_near;
        if (p[2] > p[0] + 40) ++smeared;
      }
    }
  }
  ASSERT_GT(n, 20);
  const double true_col = (kSpotX - g.x_min) / g.cell - 0.5, true_row = (g.y_max - kSpotY) / g.cell - 0.5;
  EXPECT_LT(std::hypot(sx / n - true_col, sy / n - true_row), kPositionTolerancePx);
  ASSERT_GT(floor_near, 1000u);
  EXPECT_LT(double(smeared) / double(floor_near), kMaxSmearFraction) << smeared << " of " << floor_near;
  // Block top is blue.
  const int bc = int((kBlockX - g.x_min) / g.cell), br = int((g.y_max - kBlockY) / g.cell);
  const std::uint8_t* top = &img.rgba[g.index(bc, br) * 4];
  EXPECT_GT(top[2], top[0] + 60);
}

TEST_F(OrthoScene, GainsUndoExposureDifferences) {
  const Dtm dtm = analytic_dtm();
  OrthoSummary s;
  build_orthophoto(dtm, *views_, OrthoOptions{}, &s);
  ASSERT_EQ(s.gains.size(), exposures_.size());
  // gain * exposure must be the same for every photo (up to one common factor).
  std::vector<double> prod;
  for (std::size_t v = 0; v < exposures_.size(); ++v) prod.push_back(s.gains[v][1] * exposures_[v]);
  double mean = 0;
  for (double p : prod) mean += p / double(prod.size());
  for (std::size_t v = 0; v < prod.size(); ++v) EXPECT_NEAR(prod[v] / mean, 1.0, kGainTolerance) << "view " << v;
  EXPECT_LT(s.balance_rms_after, 0.5 * s.balance_rms_before);
}

TEST_F(OrthoScene, WithoutDepthTestTheWallWouldSmear) {
  // Sanity of the smear measure: the block seen by one oblique view only, with a
  // tolerance so large that the depth test passes everything, must smear.
  OrthoOptions o;
  o.depth_tolerance_m = 10;
  o.candidates = 1;
  o.radiometric_balance = false;
  const Dtm dtm = analytic_dtm();
  const RgbaRaster img = build_orthophoto(dtm, {(*views_)[5]}, o);
  std::size_t blue_floor = 0;
  const RasterGrid& g = img.grid;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) {
      const std::uint8_t* p = &img.rgba[g.index(c, r) * 4];
      if (p[3] && !in_block(g.x_centre(c), g.y_centre(r)) && p[2] > p[0] + 40) ++blue_floor;
    }
  EXPECT_GT(blue_floor, 200u);
}

// The analytic DTM with +-kNoiseM of cell-to-cell noise (a fixed pseudo-random
// pattern), as a fused surface sampled at 5 mm gives on the floor.
Dtm noisy_dtm() {
  Dtm d = analytic_dtm();
  for (int r = 0; r < d.grid.height; ++r)
    for (int c = 0; c < d.grid.width; ++c) {
      const unsigned h = (unsigned(c) * 73856093u) ^ (unsigned(r) * 19349663u);
      d.z[d.grid.index(c, r)] += float(kNoiseM * (double(h % 1001) / 500.0 - 1.0));
    }
  return d;
}

TEST_F(OrthoScene, CentimetreNoiseInTheDtmLeavesNoHolesAndFewSeams) {
  // Normals from one-cell differences of this DTM tilt by up to 76 degrees: the
  // best view changes from cell to cell (seams everywhere, and the feathering
  // then blends views whose projections disagree); on the field data also views
  // are rejected at random (holes). Normals of the smoothed surface keep the
  // regions compact.
  const Dtm dtm = noisy_dtm();
  OrthoSummary s;
  const RgbaRaster img = build_orthophoto(dtm, *views_, OrthoOptions{}, &s);
  std::printf("noisy DTM, normals smoothed: coverage %.4f, seams %.4f\n", s.coverage, s.seam_fraction);
  EXPECT_GT(s.coverage, kNoisyMinCoverage);
  EXPECT_LT(s.seam_fraction, kNoisyMaxSeams);
  // The painted spot still lands within 2 px.
  const RasterGrid& g = img.grid;
  double sx = 0, sy = 0, n = 0;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) {
      const std::uint8_t* p = &img.rgba[g.index(c, r) * 4];
      if (p[3] && p[0] > 140 && p[1] < 90 && p[2] < 90) {
        sx += c;
        sy += r;
        ++n;
      }
    }
  ASSERT_GT(n, 20);
  const double true_col = (kSpotX - g.x_min) / g.cell - 0.5, true_row = (g.y_max - kSpotY) / g.cell - 0.5;
  EXPECT_LT(std::hypot(sx / n - true_col, sy / n - true_row), kPositionTolerancePx);

  // Sanity of the measure: one-cell normals on the same DTM fragment the regions
  // (rectified on the noisy heights themselves: the median would remove the noise).
  OrthoOptions raw;
  raw.normal_radius_m = 0;
  raw.rectify_median_radius_m = 0;
  OrthoSummary sr;
  build_orthophoto(dtm, *views_, raw, &sr);
  std::printf("noisy DTM, one-cell normals: coverage %.4f, seams %.4f\n", sr.coverage, sr.seam_fraction);
  EXPECT_GT(sr.seam_fraction, kNoisyMaxSeams);
}

// Mean absolute grey difference between two orthophotos over the cells both coloured.
double mean_grey_difference(const RgbaRaster& a, const RgbaRaster& b) {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.grid.cells(); ++i) {
    const std::uint8_t* p = &a.rgba[4 * i];
    const std::uint8_t* q = &b.rgba[4 * i];
    if (!p[3] || !q[3]) continue;
    sum += std::abs((p[0] + p[1] + p[2]) - (q[0] + q[1] + q[2])) / 3.0;
    ++n;
  }
  EXPECT_GT(n, a.grid.cells() / 2);
  return sum / double(n);
}

TEST_F(OrthoScene, MedianRectificationUndoesTheWarpOfANoisyDtm) {
  // Oblique views move each cell by its height error x tan(incidence): with
  // +-1 cm of noise the checkerboard's straight edges come out ragged. Rectified
  // on the DTM's local median, the orthophoto is close to the one rectified on the
  // exact surface.
  OrthoOptions exact_options;
  exact_options.rectify_median_radius_m = 0;
  const RgbaRaster exact = build_orthophoto(analytic_dtm(), *views_, exact_options);
  const Dtm noisy = noisy_dtm();
  const RgbaRaster ragged = build_orthophoto(noisy, *views_, exact_options);
  const RgbaRaster median = build_orthophoto(noisy, *views_, OrthoOptions{});
  const double e_ragged = mean_grey_difference(ragged, exact), e_median = mean_grey_difference(median, exact);
  std::printf("grey difference to the exact-surface orthophoto: noisy heights %.2f, median %.2f\n", e_ragged,
              e_median);
  EXPECT_LT(e_median, kMedianShareOfNoisyError * e_ragged);
}

// A flat floor with a 2 mm checkerboard, photographed from straight above at
// 0.5 mm per pixel: a 5 mm cell covers 10 x 10 photo pixels and 2.5 x 2.5 periods,
// so its true mean colour is the same everywhere. One bilinear sample per cell
// picks single squares (a speckled, aliased orthophoto); the averaged colour is
// nearly uniform.
TEST(OrthoAntialias, CellsAverageThePixelsTheyCover) {
  OrthoView v;
  v.name = "fine";
  Intrinsics& K = v.camera.intrinsics;
  K.width = K.height = 400;
  K.fx = K.fy = 1000;
  K.cx = K.cy = 199.5;
  v.camera.pose = Pose::look_at({0.0, 0.0, 0.5}, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY());
  v.rgb.resize(std::size_t(K.width) * K.height * 3);
  const Eigen::Vector3d C = v.camera.pose.centre();
  for (int y = 0; y < K.height; ++y)
    for (int x = 0; x < K.width; ++x) {
      const Eigen::Vector3d d = v.camera.ray(Eigen::Vector2d(x, y));
      const Eigen::Vector3d p = C - C.z() / d.z() * d;  // on the floor z = 0
      const bool white = (int(std::floor(p.x() / 0.002)) + int(std::floor(p.y() / 0.002))) % 2 == 0;
      for (int k = 0; k < 3; ++k) v.rgb[(std::size_t(y) * K.width + x) * 3 + k] = white ? 220 : 40;
    }
  Dtm flat;
  flat.grid = {-0.06, 0.06, kCell, 24, 24};
  flat.z.assign(flat.grid.cells(), 0.f);
  auto grey_spread = [&](bool antialias) {
    OrthoOptions o;
    o.antialias = antialias;
    o.radiometric_balance = false;
    const RgbaRaster img = build_orthophoto(flat, {v}, o);
    double sum = 0, sum2 = 0, n = 0;
    for (std::size_t i = 0; i < img.grid.cells(); ++i) {
      if (!img.rgba[4 * i + 3]) continue;
      const double g = img.rgba[4 * i + 1];
      sum += g;
      sum2 += g * g;
      ++n;
    }
    EXPECT_GT(n, 0.9 * double(img.grid.cells()));
    return std::sqrt(std::max(0.0, sum2 / n - (sum / n) * (sum / n)));
  };
  const double aliased = grey_spread(false), averaged = grey_spread(true);
  // The photo's pixel on the floor straight below the camera: depth / f = 0.5 mm.
  OrthoSummary s;
  build_orthophoto(flat, {v}, OrthoOptions{}, &s);
  ASSERT_EQ(s.source_pixel_m.size(), flat.grid.cells());
  EXPECT_NEAR(s.source_pixel_m[flat.grid.index(12, 12)], 0.0005, 0.00001);
  std::printf("grey standard deviation over a 2 mm checkerboard: point samples %.1f, averaged %.1f\n", aliased,
              averaged);
  EXPECT_GT(aliased, kAliasedMinSpread);
  EXPECT_LT(averaged, kAveragedMaxSpread);
}

TEST(OrthoOptions, RejectsInvalidFields) {
  OrthoOptions o;
  o.candidates = 0;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.max_view_angle_deg = 95;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.normal_radius_m = -0.01;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.rectify_median_radius_m = -0.01;
  EXPECT_THROW(o.validate(), InputError);
}

}  // namespace
}  // namespace strata
