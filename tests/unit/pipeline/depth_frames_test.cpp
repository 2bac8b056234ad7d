// Depth frames as inputs of the fusion (docs/range.md, "Fusion of depth frames"):
// each point carries its pixel's colour from the colour frame, the fused mesh shows
// it, a frame without a colour frame stays grey, and an overlapping sequence without
// photos takes the voxel of its points' noise, not of all their points' spacing.
#include "core/error.hpp"
#include "dense/internal.hpp"
#include "pipeline/depth_frames.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>

namespace fs = std::filesystem;

namespace strata {
namespace {

// A camera 2 m above the plane z = 0, looking straight down: 4 mm pixels there.
constexpr int kWidth = 120, kHeight = 90;
constexpr double kFocal = 500;       // pixels
constexpr double kHeightM = 2.0;     // metres
constexpr int kStride = 2;           // as layer_scans fuses frames
constexpr int kFrames = 12;
const Rgb8 kWest(200, 40, 30), kEast(20, 90, 210);  // u < kWidth / 2, and the rest
constexpr int kColourTolerance = 3;  // 8-bit levels: float sums, a vertex's trilinear mix of one patch

DepthSequenceRecord sequence() {
  DepthSequenceRecord s;
  s.name = "seq";
  s.intrinsics = {kWidth, kHeight, kFocal, kFocal, (kWidth - 1) / 2.0, (kHeight - 1) / 2.0};
  s.depth_scale_m = 0.001;
  s.noise_k = 0.0015;
  return s;
}

// Frame i, moved along x and y by a few millimetres each (a hand-held pass).
DepthFrameRecord frame(int i) {
  DepthFrameRecord f;
  f.name = fmt::format("{:04d}.png", i);
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  pose.topLeftCorner<3, 3>() << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // x right = east, z forward = down
  pose.topRightCorner<3, 1>() = Eigen::Vector3d(0.0031 * i, 0.0017 * ((3 * i) % kFrames), kHeightM);
  f.pose = pose;
  return f;
}

class DepthFramesTest : public ::testing::Test {
 protected:
  test::ScratchDir dir_{"depth_frames_test"};
  fs::path depth_ = dir_ / "depth.png", colour_ = dir_ / "colour.png";

  void SetUp() override {
    const cv::Mat depth(kHeight, kWidth, CV_16UC1, cv::Scalar(std::uint16_t(kHeightM * 1000)));
    ASSERT_TRUE(cv::imwrite(depth_.string(), depth));
    cv::Mat bgr(kHeight, kWidth, CV_8UC3);
    for (int r = 0; r < kHeight; ++r)
      for (int c = 0; c < kWidth; ++c) {
        const Rgb8& rgb = c < kWidth / 2 ? kWest : kEast;
        bgr.at<cv::Vec3b>(r, c) = cv::Vec3b(rgb[2], rgb[1], rgb[0]);
      }
    ASSERT_TRUE(cv::imwrite(colour_.string(), bgr));
  }

  struct Read {
    std::vector<Eigen::Vector3d> points;
    std::vector<Rgb8> colours;
  };
  static Read read(const RangeScanInput& in) {
    Read out;
    in.read([&](const std::vector<Eigen::Vector3d>& p, const std::vector<Eigen::Vector3f>&, const std::vector<Rgb8>& c) {
      out.points.insert(out.points.end(), p.begin(), p.end());
      out.colours.insert(out.colours.end(), c.begin(), c.end());
    });
    return out;
  }
};

TEST_F(DepthFramesTest, EachPointCarriesItsPixelsColour) {
  const DepthFrameRecord f = frame(0);
  const Read with = read(depth_frame_input(depth_, sequence(), f, kStride, colour_));
  ASSERT_EQ(with.points.size(), std::size_t(kWidth / kStride) * (kHeight / kStride));
  ASSERT_EQ(with.colours.size(), with.points.size());
  for (std::size_t i = 0; i < with.points.size(); ++i) {
    // Back to the pixel: the camera looks down with x east, so u grows with x.
    const double u = kFocal * with.points[i].x() / kHeightM + (kWidth - 1) / 2.0;
    ASSERT_EQ(with.colours[i], std::lround(u) < kWidth / 2 ? kWest : kEast) << "point " << i << " at u " << u;
  }
  const Read without = read(depth_frame_input(depth_, sequence(), f, kStride));
  EXPECT_EQ(without.points.size(), with.points.size());
  EXPECT_TRUE(without.colours.empty());
}

TEST_F(DepthFramesTest, AColourFrameOfTheWrongSizeIsOneLineNamingIt) {
  const fs::path small = dir_ / "small.png";
  ASSERT_TRUE(cv::imwrite(small.string(), cv::Mat(10, 10, CV_8UC3, cv::Scalar(1, 2, 3))));
  try {
    read(depth_frame_input(depth_, sequence(), frame(0), kStride, small));
    FAIL() << "a colour frame of 10 x 10 pixels was read";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(small.string() + ": the colour frame is 10 x 10 pixels, the intrinsics "
                                                          "say 120 x 90"),
              std::string::npos)
        << e.what();
  }
}

// The fused sequence: the frames' colours on the mesh; without colour frames, grey.
TEST_F(DepthFramesTest, AFusedSequenceShowsItsColourFramesOrStaysGrey) {
  std::vector<RangeScanInput> coloured, plain;
  for (int i = 0; i < kFrames; ++i) {
    coloured.push_back(depth_frame_input(depth_, sequence(), frame(i), kStride, colour_));
    plain.push_back(depth_frame_input(depth_, sequence(), frame(i), kStride));
  }
  const double voxel = 0.01;  // metres: 1.25 x one frame's 8 mm spacing
  auto mesh_of = [&](const std::vector<RangeScanInput>& frames) {
    dense::TsdfVolume volume(voxel, 4 * voxel);
    dense::fuse_scans(volume, frames, voxel);
    volume.finalise(0.2);
    return volume.extract_mesh(0.0);
  };
  // Vertices on the plane 3 voxels or more from the patches' edge, x = 0 in frame 0
  // and up to 3.4 cm east in the others: the west patch x < -3 voxels, the east x > 4 cm.
  auto worst = [&](const DenseMesh& m, const Rgb8& want, bool west) {
    int off = 0, n = 0;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      const Eigen::Vector3d& v = m.vertices[i];
      if (std::abs(v.z()) > voxel || std::abs(v.y()) > 0.06) continue;
      if (west ? v.x() > -3 * voxel || v.x() < -0.18 : v.x() < 0.034 + 3 * voxel || v.x() > 0.2) continue;
      ++n;
      for (int k = 0; k < 3; ++k) off = std::max(off, std::abs(int(m.colours[i][k]) - int(want[k])));
    }
    return std::make_pair(off, n);
  };
  const DenseMesh mesh = mesh_of(coloured);
  const auto [west, n_west] = worst(mesh, kWest, true);
  const auto [east, n_east] = worst(mesh, kEast, false);
  EXPECT_GT(n_west, 50);
  EXPECT_GT(n_east, 50);
  EXPECT_LE(west, kColourTolerance);
  EXPECT_LE(east, kColourTolerance);
  const DenseMesh grey = mesh_of(plain);
  const auto [grey_west, n_grey] = worst(grey, Rgb8(128, 128, 128), true);
  EXPECT_GT(n_grey, 50);
  EXPECT_EQ(grey_west, 0) << "frames without colour frames leave the surface grey";
}

// The dense stage of a layer with these frames and no photo: twelve frames 3 mm
// apart together sample the plane every 2-3 mm, but each point is 6 mm noisy (k z^2
// at 2 m): the voxel is 6 mm, as for any one of the frames, not 1.25 x the spacing of
// all their points.
TEST_F(DepthFramesTest, AnOverlappingSequencesVoxelIsItsPointsNoise) {
  std::vector<RangeScanInput> frames;
  for (int i = 0; i < kFrames; ++i) frames.push_back(depth_frame_input(depth_, sequence(), frame(i), kStride, colour_));
  const double noise = sequence().noise_k * kHeightM * kHeightM;
  const dense::ScanSampling all = dense::scan_sampling(frames), one = dense::scan_sampling({frames[0]});
  EXPECT_NEAR(all.noise_m, noise, 1e-9);
  EXPECT_NEAR(one.noise_m, noise, 1e-9);
  const DenseOptions options;
  EXPECT_LT(options.fusion.voxel_gsd_factor * all.spacing_m, 0.6 * noise) << "the frames together are much finer";
  const DenseSummary summary =
      run_dense(options, Reconstruction{}, {}, frames, Eigen::Vector3d::Zero(), dir_ / "cache", dir_ / "out");
  EXPECT_NEAR(summary.voxel_size_m, noise, 1e-9);
  EXPECT_EQ(summary.scans_fused, kFrames);
}

}  // namespace
}  // namespace strata
