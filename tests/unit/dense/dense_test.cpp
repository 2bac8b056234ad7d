// The dense stage on a small analytic scene with known truth (style.md "synthetic
// truth in tests"): a gently curved ground with a raised block, a solid procedural
// texture, 8 views rendered by ray casting through the strata camera model (with
// radial distortion). Depth maps + fusion must recover the heights.
#include "core/error.hpp"
#include "dense/dense.hpp"
#include "dense/internal.hpp"
#include "importers/mesh/ply_mesh.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

namespace strata {
namespace {

// ---- tolerances (the dense acceptance, docs/dense.md, scaled to this small scene) ----
constexpr double kMedianHeightTolerance = 0.003;  // metres: the median |dz| target
constexpr double kP95HeightTolerance = 0.015;     // metres: the 95th percentile target
constexpr double kMinCompleteness = 0.95;         // fraction of the well-covered area
constexpr double kWallExclusion = 0.006;          // metres: cells this close to the block's
                                                  // vertical walls have no single true height
constexpr double kSparseDistanceTolerance = 0.003;  // metres, median |surface - sparse point|

// ---- the analytic scene -------------------------------------------------------------
constexpr double kImageNoise = 3.0;                      // grey levels (of 255), sensor noise
constexpr double kBlockTop = 0.08;                       // metres
constexpr double kBlockX0 = -0.10, kBlockX1 = 0.15;      // metres
constexpr double kBlockY0 = -0.10, kBlockY1 = 0.12;

double ground(double x, double y) { return 0.02 * std::sin(1.5 * x) * std::cos(1.2 * y) + 0.01 * x; }
bool in_block(double x, double y) { return x >= kBlockX0 && x <= kBlockX1 && y >= kBlockY0 && y <= kBlockY1; }
double height(double x, double y) { return in_block(x, y) ? kBlockTop : ground(x, y); }

// A second scene: a rectangular pit with vertical sides cut into the ground, the
// hardest case of an excavation for dense matching (floor next to a side is seen
// only from above and from across the pit).
constexpr double kPitDepth = 0.05;                   // metres below the ground
constexpr double kPitX0 = -0.12, kPitX1 = 0.10;      // metres
constexpr double kPitY0 = -0.09, kPitY1 = 0.08;
bool in_pit(double x, double y) { return x >= kPitX0 && x <= kPitX1 && y >= kPitY0 && y <= kPitY1; }
double pit_height(double x, double y) { return in_pit(x, y) ? ground(x, y) - kPitDepth : ground(x, y); }

using Surface = double (*)(double, double);

// Smooth value noise on a 3D lattice (cell in metres), in [0, 1].
double value_noise(const Eigen::Vector3d& p, double cell, std::uint32_t seed) {
  auto lattice = [seed](long i, long j, long k) {
    std::uint32_t h = static_cast<std::uint32_t>(i * 73856093L ^ j * 19349663L ^ k * 83492791L) ^ seed;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return (h & 0xFFFF) / 65535.0;
  };
  const Eigen::Vector3d q = p / cell;
  const long i = static_cast<long>(std::floor(q.x())), j = static_cast<long>(std::floor(q.y())),
             k = static_cast<long>(std::floor(q.z()));
  auto smooth = [](double t) { return t * t * (3 - 2 * t); };
  const double fx = smooth(q.x() - i), fy = smooth(q.y() - j), fz = smooth(q.z() - k);
  double v = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    v += lattice(i + dx, j + dy, k + dz) * (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
  }
  return v;
}

// Solid texture: soil-like mottling at 4-16 mm, so walls are textured too.
Eigen::Vector3d albedo(const Eigen::Vector3d& X) {
  const double a = 0.5 * value_noise(X, 0.016, 1u) + 0.3 * value_noise(X, 0.008, 2u) +
                   0.2 * value_noise(X, 0.004, 3u);
  const double b = value_noise(X, 0.03, 4u);
  return {0.25 + 0.6 * a, 0.2 + 0.5 * a + 0.1 * b, 0.15 + 0.35 * a + 0.2 * b};
}

// First intersection of a ray with the height field (march + bisection).
std::optional<Eigen::Vector3d> cast(const Eigen::Vector3d& C, const Eigen::Vector3d& dir, Surface h) {
  auto above = [h](const Eigen::Vector3d& X) { return X.z() > h(X.x(), X.y()); };
  if (dir.z() >= 0) return std::nullopt;
  double t = (C.z() - 0.1) / -dir.z();  // start above the highest point
  const double t_end = (C.z() + 0.1) / -dir.z();
  constexpr double kStep = 0.001;       // metres along the ray
  double t_prev = t;
  while (t < t_end) {
    if (!above(C + t * dir)) {
      double lo = t_prev, hi = t;
      for (int k = 0; k < 30; ++k) {
        const double mid = 0.5 * (lo + hi);
        (above(C + mid * dir) ? lo : hi) = mid;
      }
      return C + hi * dir;
    }
    t_prev = t;
    t += kStep;
  }
  return std::nullopt;
}

struct Scene {
  Reconstruction rec;
  std::vector<std::filesystem::path> photos;
};

using Albedo = Eigen::Vector3d (*)(const Eigen::Vector3d&);

Scene make_scene(const std::filesystem::path& dir, Surface h = height, Albedo colour = albedo) {
  Scene s;
  Intrinsics in;
  in.width = 384;
  in.height = 288;
  in.fx = 330;
  in.fy = 331;
  in.cx = 193.2;
  in.cy = 142.1;
  in.k1 = -0.04;
  in.k2 = 0.01;
  s.rec.groups.push_back({in, false});
  constexpr int kViews = 8;
  for (int v = 0; v < kViews; ++v) {
    const double a = 2 * std::numbers::pi * v / kViews;
    const Eigen::Vector3d centre(0.33 * std::cos(a), 0.28 * std::sin(a), 0.9 + 0.03 * std::sin(3 * a));
    const Eigen::Vector3d target(0.05 * std::cos(a + 1), 0.04 * std::sin(a + 1), 0.0);
    const Pose pose = Pose::look_at(centre, target, Eigen::Vector3d::UnitY());
    s.rec.images.push_back({fmt::format("view{}", v), 0, true, pose});
    const Camera cam{in, pose};
    cv::Mat img(in.height, in.width, CV_8UC3);
    for (int y = 0; y < in.height; ++y) {
      for (int x = 0; x < in.width; ++x) {
        const auto hit = cast(pose.centre(), cam.ray({x, y}), h);
        Eigen::Vector3d c = hit ? colour(*hit) : Eigen::Vector3d(0.5, 0.5, 0.5);
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(255 * c.z()),
                                            cv::saturate_cast<uchar>(255 * c.y()),
                                            cv::saturate_cast<uchar>(255 * c.x()));
      }
    }
    // Sensor noise, sigma kImageNoise grey levels (deterministic seed per view).
    cv::Mat noise(img.size(), CV_16SC3);
    cv::theRNG().state = 1234 + v;
    cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(kImageNoise));
    cv::Mat noisy;
    img.convertTo(noisy, CV_16SC3);
    noisy += noise;
    noisy.convertTo(img, CV_8UC3);
    s.photos.push_back(dir / fmt::format("view{}.png", v));
    cv::imwrite(s.photos.back().string(), img);
  }
  // Sparse points on a 2 cm grid, tracked in every view that sees them unoccluded.
  for (double x = -0.5; x <= 0.5; x += 0.02) {
    for (double y = -0.4; y <= 0.4; y += 0.02) {
      SparsePoint p;
      p.X = {x, y, h(x, y)};
      for (int v = 0; v < kViews; ++v) {
        const Camera cam{in, s.rec.images[v].pose};
        const auto px = cam.project(p.X);
        if (!px || px->x() < 0 || px->y() < 0 || px->x() > in.width - 1 || px->y() > in.height - 1) continue;
        const auto hit = cast(cam.pose.centre(), (p.X - cam.pose.centre()).normalized(), h);
        if (!hit || (*hit - p.X).norm() > 0.002) continue;
        p.track.push_back({v, -1});
      }
      if (p.track.size() >= 2) s.rec.points.push_back(p);
    }
  }
  s.rec.georeferenced = true;
  return s;
}

// Stones are paler than the soil around them (the texture alone does not mark the edge).
Eigen::Vector3d stone_on_soil(const Eigen::Vector3d& X) {
  const Eigen::Vector3d soil = albedo(X);
  if (X.z() > 0.5 * kBlockTop) return Eigen::Vector3d(0.35, 0.35, 0.35) + 0.8 * soil;
  return 0.6 * soil;
}

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * (v.size() - 1))];
}

// A geometry-only scene (no rendering needed): `views` cameras of 100 x 100 pixels
// in a row along x, `step` apart, 1 m over the plane z = 0, looking straight down.
Reconstruction camera_row(int views, double step) {
  Reconstruction rec;
  Intrinsics in;
  in.width = 100;
  in.height = 100;
  in.fx = in.fy = 100;
  in.cx = in.cy = 49.5;
  rec.groups.push_back({in, false});
  for (int v = 0; v < views; ++v) {
    rec.images.push_back({fmt::format("v{}", v), 0, true,
                          Pose::look_at({step * v, 0, 1}, {step * v, 0, 0}, Eigen::Vector3d::UnitY())});
  }
  return rec;
}

TEST(Dense, ViewSelectionPrefersOverlappingNeighbours) {
  Reconstruction rec = camera_row(4, 0.2);
  for (int k = 0; k < 50; ++k) {
    SparsePoint p;
    p.X = {0.01 * k - 0.25 + 0.1, 0.01 * (k % 7), 0.0};
    p.track = {{0, -1}, {1, -1}};  // views 0 and 1 share points; 2 and 3 see nothing shared
    rec.points.push_back(p);
  }
  ViewSelectionOptions opt;
  const auto nb = dense::select_views(rec, opt, 0.25);
  ASSERT_EQ(nb.size(), 4u);
  ASSERT_EQ(nb[0].sources.size(), 1u);
  EXPECT_EQ(nb[0].sources[0], 1);
  EXPECT_TRUE(nb[2].sources.empty());
  EXPECT_GT(nb[0].depth_min, 0.5);
  EXPECT_LT(nb[0].depth_min, 1.0);
  EXPECT_GT(nb[0].depth_max, 1.0);
}

// Twelve photos in a row over one patch, each point matched by only two neighbours
// (short tracks): every photo holds every point in its view, so a cover of 3 needs 3
// reference views, not 12; each reference's depth map is checked against references
// only.
TEST(Dense, ReferenceViewsCoverEveryPointWithFewerDepthMaps) {
  constexpr int kViews = 12;
  Reconstruction rec = camera_row(kViews, 0.03);
  const Intrinsics& in = rec.groups[0].intrinsics;
  for (int k = 0; k < 200; ++k) {
    SparsePoint p;
    p.X = {0.15 + 0.002 * k - 0.2, 0.01 * (k % 9) - 0.04, 0.0};
    const int a = k % (kViews - 1);
    p.track = {{a, -1}, {a + 1, -1}};
    rec.points.push_back(p);
  }
  auto references = [](const std::vector<dense::ViewNeighbours>& nb) {
    std::vector<int> r;
    for (int i = 0; i < int(nb.size()); ++i)
      if (nb[i].reference) r.push_back(i);
    return r;
  };
  ViewSelectionOptions every;
  every.reference_cover = 0;
  const auto all = dense::select_views(rec, every, 0.25);
  EXPECT_EQ(references(all).size(), std::size_t(kViews));

  ViewSelectionOptions three;
  three.reference_cover = 3;
  const auto nb = dense::select_views(rec, three, 0.25);
  const std::vector<int> refs = references(nb);
  EXPECT_EQ(refs.size(), 3u);
  for (std::size_t k = 0; k < rec.points.size(); ++k) {
    int holding = 0;
    for (int i : refs) {
      const Eigen::Vector3d Xc = rec.images[i].pose.to_camera(rec.points[k].X);
      const Eigen::Vector2d px = in.to_pixel(Xc.head<2>() / Xc.z());
      holding += Xc.z() > 0 && px.x() >= 0 && px.y() >= 0 && px.x() < in.width && px.y() < in.height ? 1 : 0;
    }
    EXPECT_GE(holding, 3) << "point " << k;
  }
  for (int i = 0; i < kViews; ++i) {
    EXPECT_EQ(nb[i].sources, all[i].sources) << "sources do not depend on the references";
    if (!nb[i].reference) {
      EXPECT_TRUE(nb[i].checks.empty());
      continue;
    }
    EXPECT_FALSE(nb[i].checks.empty()) << "reference " << i << " has no depth map to be checked against";
    for (int c : nb[i].checks) EXPECT_TRUE(nb[c].reference) << c << " checks " << i << " without a depth map";
  }
}

TEST(Dense, RecoversAnalyticSurface) {
  test::ScratchDir dir("dense_scene");
  const Scene scene = make_scene(dir.path());
  ASSERT_GT(scene.rec.points.size(), 500u);

  DenseOptions opt;
  opt.patch_match.scale = 1.0;  // the photos are already small
  opt.exports.crs = "EPSG:32636";
  opt.mesh.write_obj = true;
  const double ax = 0.30, ay = 0.22;  // metres: half-size of the area all views cover
  opt.quality.area = {{-ax, -ay}, {ax, -ay}, {ax, ay}, {-ax, ay}};
  opt.quality.cell_size_m = 0.005;
  const Eigen::Vector3d origin(500000.0, 4200000.0, 100.0);
  const DenseSummary sum = run_dense(opt, scene.rec, scene.photos, origin, dir / "cache", dir / "out");

  std::cout << fmt::format(
      "dense summary: {} images, valid {:.2f}, consistent {:.2f}, gsd {:.2f} mm, voxel {:.2f} mm, "
      "{} voxels, {} faces, {} points, completeness {:.3f}, sparse median {:.2f} mm p95 {:.2f} mm\n"
      "  times: depth {:.2f} s, filter {:.2f} s, fusion {:.2f} s, mesh {:.2f} s, write {:.2f} s, "
      "total {:.2f} s, peak {:.0f} MB\n",
      sum.images_with_depth, sum.valid_depth_fraction, sum.consistent_depth_fraction, sum.gsd_m * 1e3,
      sum.voxel_size_m * 1e3, sum.active_voxels, sum.mesh_faces, sum.points, sum.completeness,
      sum.median_distance_sparse_m * 1e3, sum.p95_distance_sparse_m * 1e3, sum.depth_maps.seconds,
      sum.filtering.seconds, sum.fusion.seconds, sum.meshing.seconds, sum.writing.seconds,
      sum.total.seconds, sum.total.peak_memory_bytes / 1e6);

  EXPECT_EQ(sum.images_with_depth, 8);
  EXPECT_GE(sum.completeness, kMinCompleteness);
  EXPECT_LT(sum.median_distance_sparse_m, kSparseDistanceTolerance);
  ASSERT_EQ(sum.products.size(), 4u);
  for (const auto& p : sum.products) {
    EXPECT_TRUE(std::filesystem::exists(p.path)) << p.path;
    EXPECT_EQ(p.sha256.size(), 64u);
  }

  // The level set carries the site origin and CRS.
  const LevelSetInfo info = read_level_set_info(dir / "out" / "surface.vdb");
  EXPECT_EQ(info.site_origin, origin);
  EXPECT_EQ(info.crs, "EPSG:32636");
  EXPECT_DOUBLE_EQ(info.voxel_size_m, sum.voxel_size_m);

  // Heights against the analytic surface over the covered area.
  const double cell = 0.005;
  const int nx = static_cast<int>(2 * ax / cell) + 1, ny = static_cast<int>(2 * ay / cell) + 1;
  const RasterGrid grid = RasterGrid::from_south_west_centre(-ax, -ay, cell, nx, ny);
  const HeightRaster<double> hf = sample_top_surface(dir / "out" / "surface.vdb", grid);
  std::vector<double> err;
  int covered = 0;
  for (int row = 0; row < ny; ++row) {
    for (int col = 0; col < nx; ++col) {
      const double x = grid.x_centre(col), y = grid.y_centre(row);
      const double z = hf.at(col, row);
      if (!std::isfinite(z)) continue;
      ++covered;
      const double wall = std::min({std::abs(x - kBlockX0), std::abs(x - kBlockX1), std::abs(y - kBlockY0),
                                    std::abs(y - kBlockY1)});
      const bool near_wall = wall < kWallExclusion && x > kBlockX0 - kWallExclusion &&
                             x < kBlockX1 + kWallExclusion && y > kBlockY0 - kWallExclusion &&
                             y < kBlockY1 + kWallExclusion;
      if (!near_wall) err.push_back(std::abs(z - height(x, y)));
    }
  }
  const double completeness = static_cast<double>(covered) / (nx * ny);
  ASSERT_GT(err.size(), 1000u);
  const double median = percentile(err, 0.5), p95 = percentile(err, 0.95);
  std::cout << fmt::format("height error vs truth: median {:.2f} mm, p95 {:.2f} mm, completeness {:.3f}\n",
                           median * 1e3, p95 * 1e3, completeness);
  EXPECT_LT(median, kMedianHeightTolerance);
  EXPECT_LT(p95, kP95HeightTolerance);
  EXPECT_GE(completeness, kMinCompleteness);

  // The mesh is in site CRS doubles and near the truth; its faces point up.
  const PlyContents ply = read_ply(dir / "out" / "mesh.ply");
  ASSERT_TRUE(ply.double_coordinates);
  ASSERT_FALSE(ply.mesh.faces.empty());
  double up = 0;
  for (const auto& f : ply.mesh.faces) {
    const auto& v = ply.mesh.vertices;
    up += (v[f[1]] - v[f[0]]).cross(v[f[2]] - v[f[0]]).z();
  }
  EXPECT_GT(up, 0);
  std::vector<double> vert_err;
  for (const auto& v : ply.mesh.vertices) {
    const Eigen::Vector3d local = v - origin;
    if (std::abs(local.x()) < ax && std::abs(local.y()) < ay && !in_block(local.x(), local.y()) &&
        !in_block(local.x() + 0.01, local.y()) && !in_block(local.x() - 0.01, local.y()) &&
        !in_block(local.x(), local.y() + 0.01) && !in_block(local.x(), local.y() - 0.01)) {
      vert_err.push_back(std::abs(local.z() - height(local.x(), local.y())));
    }
  }
  ASSERT_FALSE(vert_err.empty());
  EXPECT_LT(percentile(vert_err, 0.5), kMedianHeightTolerance);

  // A second run reuses every cached depth map.
  const DenseSummary again = run_dense(opt, scene.rec, scene.photos, origin, dir / "cache", dir / "out");
  EXPECT_EQ(again.depth_maps_from_cache, 8);
}

// The surface must be complete INCLUDING a pit and its steep sides. The
// DTM-style top surface is sampled over an area that contains the whole pit; cells
// next to the vertical sides have no single true height and are excluded from the
// accuracy figures, but not from completeness.
TEST(Dense, PitWithSteepSidesIsComplete) {
  test::ScratchDir dir("dense_pit");
  const Scene scene = make_scene(dir.path(), pit_height);
  DenseOptions opt;
  opt.patch_match.scale = 1.0;  // the photos are already small
  const DenseSummary sum = run_dense(opt, scene.rec, scene.photos, Eigen::Vector3d(500000.0, 4200000.0, 100.0),
                                     dir / "cache", dir / "out");
  EXPECT_EQ(sum.images_with_depth, 8);

  const double ax = 0.25, ay = 0.2, cell = 0.005;  // metres: area around the pit, grid cell
  const int nx = static_cast<int>(2 * ax / cell) + 1, ny = static_cast<int>(2 * ay / cell) + 1;
  const RasterGrid grid = RasterGrid::from_south_west_centre(-ax, -ay, cell, nx, ny);
  const HeightRaster<double> hf = sample_top_surface(dir / "out" / "surface.vdb", grid);
  int cells = 0, covered = 0, pit_cells = 0, pit_covered = 0;
  std::vector<double> err, pit_err;
  for (int row = 0; row < ny; ++row) {
    for (int col = 0; col < nx; ++col) {
      const double x = grid.x_centre(col), y = grid.y_centre(row), z = hf.at(col, row);
      const bool pit = in_pit(x, y);
      ++cells;
      pit_cells += pit;
      if (!std::isfinite(z)) continue;
      ++covered;
      pit_covered += pit;
      const double side = std::min({std::abs(x - kPitX0), std::abs(x - kPitX1), std::abs(y - kPitY0),
                                    std::abs(y - kPitY1)});
      const bool near_side = side < kWallExclusion && x > kPitX0 - kWallExclusion &&
                             x < kPitX1 + kWallExclusion && y > kPitY0 - kWallExclusion &&
                             y < kPitY1 + kWallExclusion;
      if (near_side) continue;
      const double e = std::abs(z - pit_height(x, y));
      err.push_back(e);
      if (pit) pit_err.push_back(e);
    }
  }
  ASSERT_GT(pit_err.size(), 500u);
  const double completeness = static_cast<double>(covered) / cells;
  const double pit_completeness = static_cast<double>(pit_covered) / pit_cells;
  std::cout << fmt::format(
      "pit scene: completeness {:.3f} (pit {:.3f}), median |dz| {:.2f} mm, p95 {:.2f} mm, pit floor median "
      "{:.2f} mm, depth maps {:.1f} s\n",
      completeness, pit_completeness, percentile(err, 0.5) * 1e3, percentile(err, 0.95) * 1e3,
      percentile(pit_err, 0.5) * 1e3, sum.depth_maps.seconds);
  EXPECT_GE(completeness, kMinCompleteness);
  EXPECT_GE(pit_completeness, kMinCompleteness);
  EXPECT_LT(percentile(err, 0.5), kMedianHeightTolerance);
  EXPECT_LT(percentile(err, 0.95), kP95HeightTolerance);
  EXPECT_LT(percentile(pit_err, 0.5), kMedianHeightTolerance);
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

// The depth map of view 0 from views 1, 7, 2, 6, and where each of its pixels' rays
// meets the true surface.
struct ReferenceDepth {
  dense::PinholeCamera cam;
  dense::DepthMap map;
  std::optional<Eigen::Vector3d> hit(int x, int y) const {
    const Eigen::Vector3d C = cam.pose.centre();
    return cast(C, (cam.to_world(cam.ray_point(x, y, 1.0)) - C).normalized(), height);
  }
};

ReferenceDepth reference_depth(const Scene& scene, const PatchMatchOptions& pm) {
  const auto& in = scene.rec.groups[0].intrinsics;
  std::vector<dense::ViewImage> views;
  for (int v : {0, 1, 7, 2, 6}) {
    views.push_back(dense::undistort_image(scene.photos[v], in, scene.rec.images[v].pose, 1.0));
  }
  std::vector<const dense::ViewImage*> sources;
  for (std::size_t k = 1; k < views.size(); ++k) sources.push_back(&views[k]);
  return {views[0].camera, dense::patch_match(views[0], sources, 0.6, 1.3, pm)};
}

// Share of reference pixels near the block's edges whose depth is more than kGross
// off the truth: the "fattening" of the nearer surface across a depth edge that
// a plain NCC window produces and the bilateral weights are there to prevent.
double edge_gross_share(const Scene& scene, double sigma_colour) {
  constexpr double kGross = 0.02;       // metres: half the block's height
  constexpr double kBand = 0.012;       // metres from a block edge (about 4 window radii)
  PatchMatchOptions pm;
  pm.bilateral_sigma_colour = sigma_colour;
  const ReferenceDepth ref = reference_depth(scene, pm);
  const dense::PinholeCamera& cam = ref.cam;
  const dense::DepthMap& map = ref.map;
  int band = 0, gross = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const auto hit = ref.hit(x, y);
      if (!hit) continue;
      const double px = hit->x(), py = hit->y();
      // Only the block's top and the soil beside it: the vertical faces themselves,
      // seen at a grazing angle, have no reliable depth with any window.
      const double top = std::abs(hit->z() - kBlockTop), soil = std::abs(hit->z() - ground(px, py));
      if (std::min(top, soil) > 0.002) continue;
      const double edge = std::min({std::abs(px - kBlockX0), std::abs(px - kBlockX1), std::abs(py - kBlockY0),
                                    std::abs(py - kBlockY1)});
      const bool near = edge < kBand && px > kBlockX0 - kBand && px < kBlockX1 + kBand && py > kBlockY0 - kBand &&
                        py < kBlockY1 + kBand;
      const float d = map.depth[static_cast<std::size_t>(y) * cam.width + x];
      if (!near || !(d > 0)) continue;
      ++band;
      const double truth = (cam.pose.R * *hit + cam.pose.t).z();
      if (std::abs(d - truth) > kGross) ++gross;
    }
  }
  EXPECT_GT(band, 500) << "the reference view must see the block's edges";
  return band > 0 ? static_cast<double>(gross) / band : 1.0;
}

// Stones' edges in the trench are depth edges where the DTM must not bleed
// the stone top onto the soil beside it.
TEST(Dense, BilateralWeightsKeepStoneEdgesSharp) {
  constexpr double kMaxGrossShare = 0.08;  // of the pixels within kBand of an edge (plain NCC: ~0.10)
  constexpr double kMinGain = 0.75;        // bilateral must remove at least a quarter of them
  test::ScratchDir dir("dense_edges");
  const Scene scene = make_scene(dir.path(), height, stone_on_soil);
  const double plain = edge_gross_share(scene, 0.0);
  const double bilateral = edge_gross_share(scene, PatchMatchOptions{}.bilateral_sigma_colour);
  std::cout << fmt::format("gross depth errors near the block edges: plain NCC {:.1f} %, bilateral {:.1f} %\n",
                           100 * plain, 100 * bilateral);
  EXPECT_LT(bilateral, kMinGain * plain);
  EXPECT_LT(bilateral, kMaxGrossShare);
}


// Share of the reference view's pixels on the scene (ground or block top, not the
// grazing vertical faces) whose depth is within kAccurate of the truth.
double accurate_share(const Scene& scene, const PatchMatchOptions& pm) {
  constexpr double kAccurate = 0.003;  // metres: the median height target
  const ReferenceDepth ref = reference_depth(scene, pm);
  const dense::PinholeCamera& cam = ref.cam;
  const dense::DepthMap& map = ref.map;
  int seen = 0, accurate = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const auto hit = ref.hit(x, y);
      if (!hit) continue;
      const double top = std::abs(hit->z() - kBlockTop), soil = std::abs(hit->z() - ground(hit->x(), hit->y()));
      if (std::min(top, soil) > 0.002) continue;
      ++seen;
      const float d = map.depth[static_cast<std::size_t>(y) * cam.width + x];
      const double truth = (cam.pose.R * *hit + cam.pose.t).z();
      if (d > 0 && std::abs(d - truth) < kAccurate) ++accurate;
    }
  }
  EXPECT_GT(seen, cam.width * cam.height / 2) << "the reference view must see the scene";
  return seen > 0 ? static_cast<double>(accurate) / seen : 0.0;
}

// Time: the half-resolution pass must let 2 full-resolution sweeps do
// what 4 sweeps from random planes do, and must be what makes the difference.
TEST(Dense, CoarseToFineNeedsFewerFullResolutionSweeps) {
  constexpr double kMaxLoss = 0.02;  // share of pixels, coarse-to-fine vs 4 full sweeps
  test::ScratchDir dir("dense_c2f");
  const Scene scene = make_scene(dir.path());
  PatchMatchOptions c2f;  // the defaults: coarse to fine, 2 full-resolution sweeps
  ASSERT_TRUE(c2f.coarse_to_fine);
  PatchMatchOptions full = c2f;
  full.coarse_to_fine = false;
  PatchMatchOptions short_full = full;
  short_full.iterations = c2f.fine_iterations;
  const double a_c2f = accurate_share(scene, c2f), a_full = accurate_share(scene, full),
               a_short = accurate_share(scene, short_full);
  std::cout << fmt::format("pixels within 3 mm: coarse-to-fine {:.1f} %, {} full sweeps {:.1f} %, {} full sweeps {:.1f} %\n",
                           100 * a_c2f, full.iterations, 100 * a_full, short_full.iterations, 100 * a_short);
  EXPECT_GT(a_c2f, a_full - kMaxLoss);
  EXPECT_GT(a_c2f, a_short);
}

// ---- free-space test of the consistency filter ----------------------------------
// A floater: a wrong depth patch 20 cm over flat ground that one neighbour happens
// to confirm, while three others see the ground through it.
constexpr double kFloaterHeight = 0.2;   // metres above the ground plane z = 0
constexpr double kFloaterHalf = 0.05;    // metres, half side of the floater square
constexpr double kFloaterVoxel = 0.012;         // metres, fusion test voxel
constexpr double kFloaterPieceFraction = 0.1;  // share of the band below which a piece is removed (test)

// Depth map of flat ground, with the floater square when `with_floater`.
dense::DepthMap render_plane(const dense::PinholeCamera& cam, bool with_floater) {
  dense::DepthMap m;
  m.resize(cam.width, cam.height);
  const Eigen::Vector3d C = cam.pose.centre();
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      // World direction of the pixel's ray, scaled so that its camera z is 1: the
      // parameter t of a hit is its depth.
      const Eigen::Vector3d d = cam.pose.R.transpose() * cam.ray_point(u, v, 1.0);
      double t = -C.z() / d.z();
      const Eigen::Vector3d top = C + (kFloaterHeight - C.z()) / d.z() * d;
      if (with_floater && std::abs(top.x()) <= kFloaterHalf && std::abs(top.y()) <= kFloaterHalf) {
        t = (kFloaterHeight - C.z()) / d.z();
      }
      const std::size_t i = static_cast<std::size_t>(v) * cam.width + u;
      m.depth[i] = static_cast<float>(t);
      m.normal[3 * i + 2] = -1.f;
      m.confidence[i] = 1.f;
    }
  }
  return m;
}

// A small depth-map camera 1 m over the floor, looking at the origin.
dense::PinholeCamera looking_at_origin(const Eigen::Vector3d& centre) {
  dense::PinholeCamera c;
  c.width = 120;
  c.height = 100;
  c.fx = c.fy = 110;
  c.cx = 59.5;
  c.cy = 49.5;
  c.pose = Pose::look_at(centre, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY());
  return c;
}

// The reference view (which sees the floater) and four neighbours around it.
const dense::PinholeCamera kFloaterRef = looking_at_origin({0.01, 0.02, 1.0});
const std::vector<dense::PinholeCamera> kFloaterNeighbours = {
    looking_at_origin({0.3, 0, 1.0}), looking_at_origin({-0.3, 0, 1.0}), looking_at_origin({0, 0.3, 1.0}),
    looking_at_origin({0, -0.3, 1.0})};

TEST(Dense, FreeSpaceTestDropsFloatersThatNeighboursSeeThrough) {
  const dense::PinholeCamera& ref = kFloaterRef;
  const std::vector<dense::PinholeCamera>& cams = kFloaterNeighbours;
  const dense::DepthMap ref_depth = render_plane(ref, true);
  std::vector<dense::DepthMap> maps;
  for (std::size_t k = 0; k < cams.size(); ++k) maps.push_back(render_plane(cams[k], k == 0));
  std::vector<dense::DepthNeighbour> neighbours;
  for (std::size_t k = 0; k < cams.size(); ++k) neighbours.push_back({&maps[k], &cams[k]});

  // Kept share of the floater's pixels and of the ground's pixels.
  auto kept = [&](const ConsistencyOptions& opt) {
    const dense::DepthMap out = dense::filter_consistent(ref_depth, ref, neighbours, opt);
    std::array<double, 2> n{}, k{};  // [floater, ground]
    for (std::size_t i = 0; i < ref_depth.depth.size(); ++i) {
      const int which = ref_depth.depth[i] < 0.9f ? 0 : 1;
      ++n[which];
      k[which] += out.depth[i] > 0 ? 1 : 0;
    }
    EXPECT_GT(n[0], 50) << "the floater covers too few reference pixels for the test";
    return std::array<double, 2>{k[0] / n[0], k[1] / n[1]};
  };
  ConsistencyOptions off;
  off.max_free_space_violations = 0;
  const auto without = kept(off);
  const auto with = kept(ConsistencyOptions{});
  // One agreeing neighbour is enough without the test: the floater survives.
  EXPECT_GT(without[0], 0.9);
  // With it, three neighbours see the ground through the floater: it is dropped.
  EXPECT_LT(with[0], 0.05);
  // Ground next to the floater is occluded in one neighbour, never seen through: it
  // stays (edge pixels may fall to the 1-pixel reprojection rounding either way).
  EXPECT_GT(with[1], 0.95);
  EXPECT_NEAR(with[1], without[1], 0.01);
}

TEST(Dense, SmallFloatingPiecesOfTheFusedBandAreRemoved) {
  // The reference depth map with the floater fused with four that see the floor
  // under it: the floater's band is a piece of its own, 20 cm over the floor's.
  // Voxels a little coarser than the depth maps' 9 mm pixels on the floor, so that
  // one depth map leaves no gaps in the band.
  dense::TsdfVolume volume(kFloaterVoxel, 4 * kFloaterVoxel);
  const std::vector<std::uint8_t> grey(std::size_t(kFloaterRef.width) * kFloaterRef.height * 3, 128);
  volume.integrate(kFloaterRef, render_plane(kFloaterRef, true), grey);
  for (const auto& cam : kFloaterNeighbours) volume.integrate(cam, render_plane(cam, false), grey);
  volume.finalise(0.2);
  // The height of one cell centred at (x, y).
  auto top_at = [&](double x, double y) {
    return volume.top_surface(RasterGrid::from_south_west_centre(x, y, kFloaterVoxel, 1, 1)).z.at(0);
  };
  auto top_at_origin = [&] { return top_at(0.0, 0.0); };
  ASSERT_NEAR(top_at_origin(), kFloaterHeight, kFloaterVoxel) << "the floater should be the uppermost surface first";
  EXPECT_EQ(volume.remove_small_components(0), 0u);
  const std::size_t before = volume.active_voxels();
  // The floater's piece is a few percent of the band; 10 % removes it and nothing else.
  const std::size_t removed = volume.remove_small_components(kFloaterPieceFraction);
  EXPECT_GT(removed, 0u);
  EXPECT_LT(double(removed), kFloaterPieceFraction * double(before));
  EXPECT_NEAR(top_at_origin(), 0.0, kFloaterVoxel) << "the floor under the floater should be the top surface now";
  EXPECT_NEAR(top_at(0.2, 0.1), 0.0, kFloaterVoxel);
}

// The point cloud leaves out vertices seen too little: a floor seen head-on by four
// depth maps, and beyond their views a strip that one doubtful map (confidence 0.5)
// alone saw. The mesh keeps the strip; the points do not.
TEST(Dense, PointCloudLeavesOutSurfaceSeenTooLittle) {
  const std::vector<std::uint8_t> grey(std::size_t(kFloaterRef.width) * kFloaterRef.height * 3, 128);
  dense::TsdfVolume volume(kFloaterVoxel, 4 * kFloaterVoxel);
  for (const auto& cam : kFloaterNeighbours) volume.integrate(cam, render_plane(cam, false), grey);
  // Off to the side: its view reaches past the others' (x > 1.1 m).
  const dense::PinholeCamera side = [] {
    dense::PinholeCamera c = looking_at_origin({1.6, 0.0, 0.6});
    c.pose = Pose::look_at({1.6, 0.0, 0.6}, {1.4, 0.0, 0.0}, Eigen::Vector3d::UnitY());
    return c;
  }();
  dense::DepthMap doubtful = render_plane(side, false);
  for (float& c : doubtful.confidence) c = 0.5f;
  volume.integrate(side, doubtful, grey);
  volume.finalise(0.2);
  const DenseMesh mesh = volume.extract_mesh(0.0);
  auto count_beyond = [](const DenseMesh& m, double x) {
    return std::count_if(m.vertices.begin(), m.vertices.end(), [x](const Eigen::Vector3d& v) { return v.x() > x; });
  };
  ASSERT_GT(count_beyond(mesh, 1.3), 50) << "the strip only the side view saw should be in the mesh";
  const DenseMesh kept = volume.points_from_mesh(mesh, 1.5, 2.0);
  const DenseMesh every = volume.points_from_mesh(mesh, 0.0, 0.0);
  EXPECT_EQ(every.vertices.size(), mesh.vertices.size());
  EXPECT_EQ(count_beyond(kept, 1.3), 0) << "one doubtful depth map is not enough for the cloud";
  // The floor under the four maps stays (all of it within their common view).
  auto count_within = [](const DenseMesh& m, double r) {
    return std::count_if(m.vertices.begin(), m.vertices.end(),
                         [r](const Eigen::Vector3d& v) { return v.head<2>().norm() < r; });
  };
  EXPECT_EQ(count_within(kept, 0.2), count_within(mesh, 0.2));
  EXPECT_EQ(kept.normals.size(), kept.vertices.size());
  EXPECT_EQ(kept.colours.size(), kept.vertices.size());
}

// The fused surface states its height uncertainty per cell from the agreement of
// the depth maps: maps that disagree by sigma (each one shifted as a whole, as a
// view's error is) give a height sigma of about sigma / sqrt(views); noisier maps
// a larger one; and a cell that fewer maps see, a larger one still.
TEST(Dense, FusedHeightsCarryTheUncertaintyOfTheirDepthMaps) {
  const std::vector<dense::PinholeCamera> cams = {
      kFloaterRef, kFloaterNeighbours[0], kFloaterNeighbours[1], kFloaterNeighbours[2], kFloaterNeighbours[3],
      looking_at_origin({0.2, 0.2, 1.0}), looking_at_origin({-0.2, -0.2, 1.0}), looking_at_origin({0.2, -0.2, 1.0})};
  const std::vector<std::uint8_t> grey(std::size_t(kFloaterRef.width) * kFloaterRef.height * 3, 128);
  auto fused_sigma = [&](double map_sigma, std::size_t views, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> shift(0, map_sigma);
    dense::TsdfVolume volume(kFloaterVoxel, 6 * kFloaterVoxel);  // the band holds 3 sigma of the noisy maps
    for (std::size_t k = 0; k < views; ++k) {
      dense::DepthMap m = render_plane(cams[k], false);
      const float d = float(shift(rng));
      for (float& z : m.depth) z += d;
      volume.integrate(cams[k], m, grey);
    }
    volume.finalise(0.2);
    const HeightRaster<double> hf = volume.top_surface(RasterGrid::from_south_west_centre(-0.05, -0.05, 0.01, 11, 11));
    EXPECT_TRUE(hf.has_sigma());
    std::vector<double> s;
    for (std::size_t c = 0; c < hf.z.size(); ++c)
      if (std::isfinite(hf.z[c])) s.push_back(hf.sigma[c]);
    EXPECT_GT(s.size(), 60u);  // of 121 cells
    std::nth_element(s.begin(), s.begin() + std::ptrdiff_t(s.size() / 2), s.end());
    return s[s.size() / 2];
  };
  // Averaged over draws: the spread of 8 shifts is itself a random estimate.
  double noisy = 0, quiet = 0, few = 0;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    noisy += fused_sigma(0.02, 8, seed) / 6;
    quiet += fused_sigma(0.005, 8, seed) / 6;
    few += fused_sigma(0.02, 3, seed) / 6;
  }
  std::printf("fused height sigma: 8 maps of 20 mm %.2f mm (20 / sqrt 8 = %.2f), of 5 mm %.2f mm; 3 maps of 20 mm "
              "%.2f mm\n", 1000 * noisy, 20 / std::sqrt(8.0), 1000 * quiet, 1000 * few);
  const double expected = 0.02 / std::sqrt(8.0);
  EXPECT_GT(noisy, 0.5 * expected);
  EXPECT_LT(noisy, 2.0 * expected);
  EXPECT_GT(noisy, 2.0 * quiet) << "four times the disagreement should show";
  EXPECT_GT(few, noisy) << "three views know the height less well than eight";
}

TEST(DenseOptions, ValidationNamesTheField) {
  DenseOptions o;
  EXPECT_NO_THROW(o.validate());
  o.patch_match.scale = 0.3;
  try {
    o.validate();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("patch_match.scale"), std::string::npos);
  }
  o = DenseOptions();
  o.fusion.truncation_voxels = 1;
  EXPECT_THROW(o.validate(), InputError);
}

}  // namespace
}  // namespace strata
