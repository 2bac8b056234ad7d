// Range scans fused into the TSDF (docs/range.md, "Fusion"): a simulated scan of an
// analytic scene (a block on a plane) must give its surface to the millimetre, and
// the weights must follow the noise: a 1 mm scan beside a noisier depth map pulls
// the surface to itself, a 20 mm scan hardly moves the depth map's.
#include "core/error.hpp"
#include "dense/dense.hpp"
#include "dense/internal.hpp"
#include "support/box_scan.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>

namespace strata {
namespace {

// ---- the analytic scene: the plane z = 0 with a block on it ------------------------
constexpr double kBlockHalf = 0.1;   // metres: the block spans -0.1..0.1 in x and y
constexpr double kBlockTop = 0.08;   // metres
constexpr double kVoxel = 0.004;     // metres
constexpr double kTruncation = 4 * kVoxel;
constexpr double kAngularStep = 1.5e-3;  // radians: 2-4 mm between rays at 1.5-2.5 m
// Tolerances: the fused height of a 1 mm scan at 4 mm voxels (median over cells;
// the zero crossing is interpolated between voxel centres, ~0.1 voxel).
constexpr double kHeightMedianTol = 0.001;   // metres
constexpr double kHeightP95Tol = 0.003;      // metres
constexpr double kMinCoverage = 0.95;        // of the cells both stations see

bool in_block(double x, double y) { return std::abs(x) <= kBlockHalf && std::abs(y) <= kBlockHalf; }
double truth(double x, double y) { return in_block(x, y) ? kBlockTop : 0.0; }

// A scan from `station` over the square |x|, |y| < 0.4 m, each range with Gaussian noise.
std::vector<Eigen::Vector3d> scan_points(const Eigen::Vector3d& station, double sigma, unsigned seed) {
  const test::BoxOnPlane scene{{-kBlockHalf, -kBlockHalf, 0}, {kBlockHalf, kBlockHalf, kBlockTop}, {-0.4, -0.4}, {0.4, 0.4}};
  return test::box_scene_scan(scene, station, -1.45, -0.3, -3.1416, 3.1416, kAngularStep, sigma, seed);
}

RangeScanInput in_memory(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& station, double sigma) {
  RangeScanInput in;
  in.name = "test scan";
  in.sigma_m = sigma;
  in.station = station;
  in.read = [points](const RangeScanInput::ChunkSink& sink) {
    for (std::size_t i = 0; i < points.size(); i += 50000) {
      const std::vector<Eigen::Vector3d> chunk(points.begin() + std::ptrdiff_t(i),
                                               points.begin() + std::ptrdiff_t(std::min(points.size(), i + 50000)));
      sink(chunk, {}, {});
    }
  };
  return in;
}

struct Errors {
  double median = 0, p95 = 0, coverage = 0;
};

// |fused - truth| over the cells of the square, away from the block's vertical sides.
Errors height_errors(const HeightRaster<double>& hf) {
  std::vector<double> e;
  std::size_t cells = 0;
  for (std::size_t c = 0; c < hf.z.size(); ++c) {
    const Eigen::Vector2d p = hf.grid.centre(c);
    const double x = p.x(), y = p.y();
    if (std::abs(std::abs(x) - kBlockHalf) < 0.01 || std::abs(std::abs(y) - kBlockHalf) < 0.01) continue;
    ++cells;
    if (std::isfinite(hf.z[c])) e.push_back(std::abs(hf.z[c] - truth(x, y)));
  }
  Errors r;
  if (e.empty()) return r;
  std::sort(e.begin(), e.end());
  r.median = e[e.size() / 2];
  r.p95 = e[std::size_t(0.95 * double(e.size() - 1))];
  r.coverage = double(e.size()) / double(cells);
  return r;
}

TEST(ScanFusion, TwoStationsOfABlockOnAPlaneGiveItsSurfaceToTheMillimetre) {
  const Eigen::Vector3d west(-0.9, 0.05, 1.5), east(0.9, -0.05, 1.5);
  const double sigma = 0.001;
  dense::TsdfVolume volume(kVoxel, kTruncation);
  const std::vector<RangeScanInput> scans = {in_memory(scan_points(west, sigma, 1), west, sigma),
                                             in_memory(scan_points(east, sigma, 2), east, sigma)};
  const dense::ScanFusionFigures f = dense::fuse_scans(volume, scans, kVoxel);
  EXPECT_EQ(f.scans, 2);
  EXPECT_GT(f.points, 100000u);
  EXPECT_GT(f.weight, 0);
  volume.finalise(0.2);
  const HeightRaster<double> hf = volume.top_surface(RasterGrid::from_south_west_centre(-0.3, -0.3, 0.005, 121, 121));
  const Errors e = height_errors(hf);
  EXPECT_LT(e.median, kHeightMedianTol);
  EXPECT_LT(e.p95, kHeightP95Tol);
  EXPECT_GT(e.coverage, kMinCoverage);
  EXPECT_NEAR(hf.at(60, 60), kBlockTop, kHeightMedianTol) << "the block's top at the centre";
  // Each cell states its height sigma from the agreement of the stations: below the
  // one-voxel prior when many 1 mm points agree.
  ASSERT_TRUE(hf.has_sigma());
  EXPECT_LT(hf.sigma[std::size_t(60) * 121 + 60], kVoxel);
  EXPECT_GT(hf.sigma[std::size_t(60) * 121 + 60], 0);
}

TEST(ScanFusion, OneStationLeavesTheBlocksShadowUnseen) {
  const Eigen::Vector3d west(-0.9, 0.0, 1.5);
  dense::TsdfVolume volume(kVoxel, kTruncation);
  dense::fuse_scans(volume, {in_memory(scan_points(west, 0.001, 3), west, 0.001)}, kVoxel);
  volume.finalise(0.2);
  // The plane just east of the block is in its shadow from the west (the block is
  // 8 cm tall, the station 1.5 m up 0.8 m away: the shadow is ~4 cm long).
  const HeightRaster<double> shadow =
      volume.top_surface(RasterGrid::from_south_west_centre(kBlockHalf + 0.015, -0.05, 0.005, 1, 21));
  for (double z : shadow.z) EXPECT_FALSE(std::isfinite(z) && std::abs(z) < 0.003) << z;
  const HeightRaster<double> lit =
      volume.top_surface(RasterGrid::from_south_west_centre(-kBlockHalf - 0.03, -0.05, 0.005, 1, 21));
  for (double z : lit.z) EXPECT_NEAR(z, 0.0, 0.002);
}

// A depth map of the plane z = `height` from a camera 1 m straight above.
dense::DepthMap plane_depth(const dense::PinholeCamera& cam, double height) {
  dense::DepthMap m;
  m.resize(cam.width, cam.height);
  for (std::size_t p = 0; p < m.depth.size(); ++p) {
    m.depth[p] = float(1.0 - height);
    m.normal[3 * p + 2] = -1.f;
    m.confidence[p] = 1.f;
  }
  return m;
}

TEST(ScanFusion, WeightsFollowTheNoiseOfScansAndDepthMaps) {
  dense::PinholeCamera cam;
  cam.width = cam.height = 200;
  cam.fx = cam.fy = 200;
  cam.cx = cam.cy = 99.5;
  cam.pose.R << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // looking straight down from (0, 0, 1)
  cam.pose.t = Eigen::Vector3d(0, 0, 1);
  const std::vector<std::uint8_t> grey(std::size_t(cam.width) * cam.height * 3, 128);
  // The depth map stands 6 mm above the truth (a photo depth of 5 mm sigma, its unit
  // sigma); the scans see the truth with 1 mm or 20 mm noise.
  constexpr double kPhotoOffset = 0.006, kUnitSigma = 0.005;
  const Eigen::Vector3d station(-0.9, 0.0, 1.5);
  auto fused_height = [&](double scan_sigma) {
    dense::TsdfVolume volume(kVoxel, 2 * kTruncation);
    volume.integrate(cam, plane_depth(cam, kPhotoOffset), grey);
    dense::fuse_scans(volume, {in_memory(scan_points(station, scan_sigma, 4), station, scan_sigma)}, kUnitSigma);
    volume.finalise(0.2);
    // The plane, clear of the block.
    const HeightRaster<double> hf = volume.top_surface(RasterGrid::from_south_west_centre(-0.3, 0.15, 0.01, 20, 10));
    std::vector<double> z;
    for (double v : hf.z)
      if (std::isfinite(v)) z.push_back(v);
    EXPECT_GT(z.size(), 150u);
    std::nth_element(z.begin(), z.begin() + std::ptrdiff_t(z.size() / 2), z.end());
    return z[z.size() / 2];
  };
  const double precise = fused_height(0.001), noisy = fused_height(0.02);
  std::printf("fused plane height: depth map at +%.1f mm with a 1 mm scan %.2f mm, with a 20 mm scan %.2f mm\n",
              1000 * kPhotoOffset, 1000 * precise, 1000 * noisy);
  // 1 mm: each point weighs (5/1)^2 = 25 photo depths; the scan wins.
  EXPECT_LT(std::abs(precise), 0.1 * kPhotoOffset);
  // 20 mm: each point weighs 1/16 of a depth, but a voxel averages about 30 points
  // (n_eff of its Gaussian tube), an observation of 20 / sqrt 30 = 3.7 mm against the
  // depth's 5 mm: by inverse variances 6 x 5^-2 / (5^-2 + 3.7^-2) = 2.1 mm.
  EXPECT_GT(noisy, 0.2 * kPhotoOffset);
  EXPECT_LT(noisy, 0.6 * kPhotoOffset);
  EXPECT_GT(noisy, 10 * std::abs(precise));
}

// A depth camera's points carry their own noise (RangeScanInput::point_sigma, k z^2):
// two scans of the same rays, one 6 mm above the truth whose points say 2 mm, one on
// the truth whose points say 6 mm, must meet at their inverse-variance mean
// 6 x 2^-2 / (2^-2 + 6^-2) = 5.4 mm; with the sigmas swapped at 0.6 mm. A point
// sigma equal to the scan's sigma_m must fuse exactly as no point sigma.
TEST(ScanFusion, PointSigmasWeighEachPointByItsOwnNoise) {
  constexpr double kOffset = 0.006, kSigmaScale = 0.001;
  constexpr double kMeanTolerance = 0.0005;  // metres: the zero crossing between voxel centres, a few tenths of a mm
  const Eigen::Vector3d station(-0.9, 0.0, 1.5);
  const std::vector<Eigen::Vector3d> rays = scan_points(station, 0.0, 5);
  std::vector<Eigen::Vector3d> raised = rays;
  for (auto& p : raised) p.z() += kOffset;
  auto with_sigma = [&](const std::vector<Eigen::Vector3d>& points, double sigma) {
    RangeScanInput in = in_memory(points, station, kSigmaScale);
    in.point_sigma = [sigma](const Eigen::Vector3d&) { return sigma; };
    return in;
  };
  auto plane_height = [&](const std::vector<RangeScanInput>& scans) {
    dense::TsdfVolume volume(kVoxel, 2 * kTruncation);
    dense::fuse_scans(volume, scans, kVoxel);
    volume.finalise(0.2);
    const HeightRaster<double> hf = volume.top_surface(RasterGrid::from_south_west_centre(-0.3, 0.15, 0.01, 20, 10));
    std::vector<double> z;
    for (double v : hf.z)
      if (std::isfinite(v)) z.push_back(v);
    EXPECT_GT(z.size(), 150u);
    std::nth_element(z.begin(), z.begin() + std::ptrdiff_t(z.size() / 2), z.end());
    return z[z.size() / 2];
  };
  const double raised_precise = plane_height({with_sigma(raised, 0.002), with_sigma(rays, 0.006)});
  const double raised_noisy = plane_height({with_sigma(raised, 0.006), with_sigma(rays, 0.002)});
  const double expected = kOffset * (1 / 4.0) / (1 / 4.0 + 1 / 36.0);
  EXPECT_NEAR(raised_precise, expected, kMeanTolerance);
  EXPECT_NEAR(raised_noisy, kOffset - expected, kMeanTolerance);
  // Equal point sigmas: the same as a constant sigma_m.
  const double constant = plane_height({in_memory(raised, station, 0.002), in_memory(rays, station, 0.006)});
  EXPECT_NEAR(constant, raised_precise, 1e-6);
}

// ---- colour ---------------------------------------------------------------------
// The plane's west half (x < 0) and east half in the coloured scans.
const Rgb8 kWest(200, 40, 30), kEast(20, 90, 210), kGrey(128, 128, 128);
// A fused colour within this of the scan's: the trilinear colour of a vertex mixes
// only voxels of one patch away from its edge; float sums round to a level or so.
constexpr int kColourTolerance = 3;  // 8-bit levels

RangeScanInput with_colours(RangeScanInput in, const std::function<Rgb8(const Eigen::Vector3d&)>& colour) {
  auto read = in.read;
  in.read = [read, colour](const RangeScanInput::ChunkSink& sink) {
    read([&](const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3f>& normals,
             const std::vector<Rgb8>&) {
      std::vector<Rgb8> colours;
      for (const auto& p : points) colours.push_back(colour(p));
      sink(points, normals, colours);
    });
  };
  return in;
}

// The largest channel difference from `want` over the mesh's vertices on the plane
// (z = 0) within the XY box, and how many there were.
std::pair<int, int> worst_colour(const DenseMesh& mesh, const Rgb8& want, double x0, double x1, double y0, double y1) {
  int worst = 0, n = 0;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d& v = mesh.vertices[i];
    if (v.x() < x0 || v.x() > x1 || v.y() < y0 || v.y() > y1 || std::abs(v.z()) > 0.003) continue;
    ++n;
    for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(int(mesh.colours[i][k]) - int(want[k])));
  }
  return {worst, n};
}

TEST(ScanFusion, AScansColoursReachTheMeshAndAScanWithoutColoursStaysGrey) {
  const Eigen::Vector3d station(-0.9, 0.05, 1.5);
  const RangeScanInput plain = in_memory(scan_points(station, 0.001, 6), station, 0.001);
  auto mesh_of = [](const RangeScanInput& scan) {
    dense::TsdfVolume volume(kVoxel, kTruncation);
    dense::fuse_scans(volume, {scan}, kVoxel);
    volume.finalise(0.2);
    return volume.extract_mesh(0.0);
  };
  const DenseMesh coloured = mesh_of(with_colours(plain, [](const Eigen::Vector3d& p) { return p.x() < 0 ? kWest : kEast; }));
  ASSERT_EQ(coloured.colours.size(), coloured.vertices.size());
  // Away from the patches' common edge (x = 0) and from the block.
  const auto [west, n_west] = worst_colour(coloured, kWest, -0.3, -0.15, 0.15, 0.3);
  const auto [east, n_east] = worst_colour(coloured, kEast, 0.15, 0.3, 0.15, 0.3);
  EXPECT_GT(n_west, 500);
  EXPECT_GT(n_east, 500);
  EXPECT_LE(west, kColourTolerance);
  EXPECT_LE(east, kColourTolerance);
  const DenseMesh grey = mesh_of(plain);
  const auto [off_grey, n_grey] = worst_colour(grey, kGrey, -0.3, 0.3, -0.3, 0.3);
  EXPECT_GT(n_grey, 2000);
  EXPECT_EQ(off_grey, 0) << "a scan without colours leaves its voxels mid grey";
}

// Two coloured scans of the same rays average their colours as their geometry: by
// the inverse variances of their points, (100 / 2^2 + 200 / 6^2) / (1 / 2^2 + 1 /
// 6^2) = 110. Where a photo coloured the voxel, its colour stays.
TEST(ScanFusion, ScanColoursAverageByTheirWeightsAndPhotosKeepTheirs) {
  const Eigen::Vector3d station(-0.9, 0.0, 1.5);
  const std::vector<Eigen::Vector3d> rays = scan_points(station, 0.0, 7);
  auto grey_scan = [&](double sigma, std::uint8_t level) {
    RangeScanInput in = in_memory(rays, station, 0.001);
    in.point_sigma = [sigma](const Eigen::Vector3d&) { return sigma; };
    return with_colours(in, [level](const Eigen::Vector3d&) { return Rgb8(level, level, level); });
  };
  {
    dense::TsdfVolume volume(kVoxel, 2 * kTruncation);
    dense::fuse_scans(volume, {grey_scan(0.002, 100), grey_scan(0.006, 200)}, kVoxel);
    volume.finalise(0.2);
    const double expected = (100 / 4.0 + 200 / 36.0) / (1 / 4.0 + 1 / 36.0);
    const auto [off, n] = worst_colour(volume.extract_mesh(0.0), Rgb8(110, 110, 110), -0.3, 0.3, 0.15, 0.3);
    EXPECT_GT(n, 500);
    EXPECT_NEAR(expected, 110.0, 0.5);
    EXPECT_LE(off, 1);
  }
  // A photo of the west half (x < 0) in green, then a scan of the whole plane in the
  // west patch's red. Its pixels 3.1 mm apart on the plane, finer than the voxel as
  // the automatic voxel makes them (1.25 GSD): every voxel under it is on a ray.
  dense::PinholeCamera cam;
  cam.width = cam.height = 320;
  cam.fx = cam.fy = 320;
  cam.cx = cam.cy = 159.5;
  cam.pose.R << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // looking straight down from (0, 0, 1): u grows with x
  cam.pose.t = Eigen::Vector3d(0, 0, 1);
  dense::DepthMap west_half = plane_depth(cam, 0.0);
  std::vector<std::uint8_t> green(std::size_t(cam.width) * cam.height * 3);
  for (std::size_t p = 0; p < west_half.depth.size(); ++p) {
    if (int(p % std::size_t(cam.width)) >= cam.width / 2) west_half.depth[p] = 0;
    green[3 * p] = 30;
    green[3 * p + 1] = 160;
    green[3 * p + 2] = 40;
  }
  dense::TsdfVolume volume(kVoxel, 2 * kTruncation);
  volume.integrate(cam, west_half, green);
  dense::fuse_scans(volume, {with_colours(in_memory(rays, station, 0.001), [](const Eigen::Vector3d&) { return kWest; })},
                    kVoxel);
  volume.finalise(0.2);
  const DenseMesh mesh = volume.extract_mesh(0.0);
  const auto [photo_off, n_photo] = worst_colour(mesh, Rgb8(30, 160, 40), -0.3, -0.15, 0.15, 0.3);
  const auto [scan_off, n_scan] = worst_colour(mesh, kWest, 0.15, 0.3, 0.15, 0.3);
  EXPECT_GT(n_photo, 500);
  EXPECT_GT(n_scan, 500);
  EXPECT_LE(photo_off, kColourTolerance) << "the photo's colour stays where it saw the plane";
  EXPECT_LE(scan_off, kColourTolerance) << "the scan's colour where no photo saw the plane";
}

// ---- the voxel of a layer without photos --------------------------------------------
// A square of points on a regular grid of `step`, shifted by `offset`.
RangeScanInput grid_input(double step, const Eigen::Vector2d& offset, double sigma) {
  std::vector<Eigen::Vector3d> points;
  for (double y = 0; y < 0.5; y += step)
    for (double x = 0; x < 0.5; x += step) points.emplace_back(x + offset.x(), y + offset.y(), 0.0);
  return in_memory(points, Eigen::Vector3d(0, 0, 2), sigma);
}

TEST(ScanFusion, ScanSamplingIsAllPointsSpacingAndTheScansMedianNoise) {
  // 5 mm: four points in every 1 cm cell, wherever the grid starts; sixteen inputs
  // shifted from one another put 64 there: 1.25 mm.
  constexpr double kStep = 0.005;
  constexpr int kInputs = 16;
  std::vector<RangeScanInput> inputs;
  for (int i = 0; i < kInputs; ++i)
    inputs.push_back(grid_input(kStep, Eigen::Vector2d(0.0003 * i, 0.0007 * ((i * 5) % kInputs)), 0.003));
  EXPECT_NEAR(dense::scan_sampling({inputs[0]}).spacing_m, kStep, 1e-9);
  dense::ScanSampling s = dense::scan_sampling(inputs);
  EXPECT_NEAR(s.spacing_m, kStep / 4, 1e-9);
  EXPECT_DOUBLE_EQ(s.noise_m, 0.003);
  // Points of their own noise (a depth camera's): the median of each input's, then
  // over the inputs: 5 of 16 inputs at 8 mm, the rest at 2 mm + 1 mm per metre of x.
  for (int i = 0; i < kInputs; ++i)
    inputs[i].point_sigma = [i](const Eigen::Vector3d& p) { return i < 5 ? 0.008 : 0.002 + 0.001 * p.x(); };
  s = dense::scan_sampling(inputs);
  EXPECT_NEAR(s.noise_m, 0.002 + 0.001 * 0.25, 2e-5) << "the middle input's median point, x = 0.25 m";
  // An input without points does not count; none at all is an error.
  EXPECT_DOUBLE_EQ(dense::scan_sampling({grid_input(kStep, {0, 0}, 0.003), in_memory({}, {0, 0, 2}, 0.009)}).noise_m,
                   0.003);
  EXPECT_THROW(dense::scan_sampling({in_memory({}, Eigen::Vector3d(0, 0, 2), 0.003)}), ProcessingError);
}

TEST(ScanFusion, RaysWithoutAStationFollowTheNormalsOrTheVertical) {
  RangeScanInput scan;
  scan.sigma_m = 0.003;
  const std::vector<Eigen::Vector3d> points = {{0, 0, 0}, {1, 0, 0}};
  // Normals pointing down are turned up: the sensor looked from above.
  const std::vector<Eigen::Vector3f> normals = {{0, 0, -1}, {1, 0, 0}};
  auto d = dense::scan_ray_directions(scan, points, normals);
  EXPECT_TRUE(d[0].isApprox(Eigen::Vector3d(0, 0, -1)));
  EXPECT_TRUE(d[1].isApprox(Eigen::Vector3d(-1, 0, 0)));
  d = dense::scan_ray_directions(scan, points, {});
  EXPECT_TRUE(d[1].isApprox(Eigen::Vector3d(0, 0, -1)));
  scan.station = Eigen::Vector3d(0, 0, 2);
  d = dense::scan_ray_directions(scan, points, normals);
  EXPECT_TRUE(d[1].isApprox(Eigen::Vector3d(1, 0, -2).normalized()));
}

}  // namespace
}  // namespace strata
