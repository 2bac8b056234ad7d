// reader.point_cloud: every format read back against the points the test wrote.
#include "core/error.hpp"
#include "importers/scans/point_cloud.hpp"
#include "scan_files.hpp"

#include <gtest/gtest.h>

namespace strata {
namespace {

namespace fs = std::filesystem;
using namespace test;

// LAS stores integers times 0.001 m: a coordinate comes back within half of that
// (here exactly representable millimetres, so the error is only the double rounding).
constexpr double kLasTolerance = 0.5 * kLasScale;
constexpr int kPoints = 9;

class PointCloudTest : public ::testing::Test {
 protected:
  fs::path write(const std::string& name, const std::string& bytes) {
    const fs::path p = scratch_ / name;
    write_bytes(p, bytes);
    return p;
  }
  ScratchDir scratch_{"cloud"};
  const std::vector<TestPoint> truth_ = sample_points(kPoints);
};

// What a float property holds of a coordinate. Through a volatile: g++ 12 -O2 folds
// the vectorised double -> float -> double round trip of a Vector3d's x and y away.
double float_rounded(double v) {
  const volatile float f = static_cast<float>(v);
  return static_cast<double>(f);
}

void expect_positions(const PointCloud& c, const std::vector<TestPoint>& truth, double tolerance) {
  ASSERT_EQ(c.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i)
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(c.positions[i][a], truth[i].position[a], tolerance) << "point " << i;
}

void expect_colours(const PointCloud& c, const std::vector<TestPoint>& truth) {
  ASSERT_EQ(c.colours.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) EXPECT_EQ(c.colours[i], truth[i].colour) << "point " << i;
}

void expect_intensities(const PointCloud& c, const std::vector<TestPoint>& truth) {
  ASSERT_EQ(c.intensities.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) EXPECT_EQ(c.intensities[i], truth[i].intensity) << "point " << i;
}

TEST_F(PointCloudTest, PlyInEveryEncodingReadsBackExactly) {
  for (auto encoding : {PlyEncoding::ascii, PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
    for (bool doubles : {true, false}) {
      PlyLayout layout;
      layout.encoding = encoding;
      layout.doubles = doubles;
      const fs::path file = write("cloud.ply", ply_bytes(truth_, layout));
      SCOPED_TRACE(fmt::format("encoding {}, doubles {}", int(encoding), doubles));
      PointCloudInfo info;
      const PointCloud c = read_point_cloud(file, &info);
      const char* names[] = {"ply ascii", "ply binary_little_endian", "ply binary_big_endian"};
      EXPECT_EQ(info.format, names[int(encoding)]);
      EXPECT_EQ(info.points, std::uint64_t(kPoints));
      EXPECT_TRUE(info.has_colour && info.has_intensity && info.has_normals);
      ASSERT_EQ(c.size(), truth_.size());
      for (std::size_t i = 0; i < truth_.size(); ++i) {
        // Floats hold the coordinate as the writer rounded it, not better.
        Eigen::Vector3d expected = truth_[i].position;
        if (!doubles)
          for (int a = 0; a < 3; ++a) expected[a] = float_rounded(expected[a]);
        EXPECT_EQ(c.positions[i], expected) << "point " << i;
        EXPECT_EQ(c.normals[i], truth_[i].normal) << "point " << i;
      }
      expect_colours(c, truth_);
      expect_intensities(c, truth_);
      EXPECT_EQ(info.min, truth_.front().position.cwiseMin(truth_.back().position));
    }
  }
}

TEST_F(PointCloudTest, PlySkipsOtherElementsAndPropertiesByTheirTypes) {
  for (auto encoding : {PlyEncoding::ascii, PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
    PlyLayout layout;
    layout.encoding = encoding;
    layout.extras = true;
    layout.normals = false;
    layout.intensity_name = "scalar_intensity";
    PointCloudInfo info;
    const PointCloud c = read_point_cloud(write("extras.ply", ply_bytes(truth_, layout)), &info);
    expect_positions(c, truth_, 0.0);
    expect_colours(c, truth_);
    expect_intensities(c, truth_);
    EXPECT_FALSE(info.has_normals);
    EXPECT_TRUE(c.normals.empty());
  }
  // Only x y z: no attributes.
  PlyLayout bare;
  bare.colour = bare.intensity = bare.normals = false;
  PointCloudInfo info;
  const PointCloud c = read_point_cloud(write("bare.ply", ply_bytes(truth_, bare)), &info);
  expect_positions(c, truth_, 0.0);
  EXPECT_FALSE(info.has_colour || info.has_intensity || info.has_normals);
  EXPECT_TRUE(c.colours.empty() && c.intensities.empty());
}

TEST_F(PointCloudTest, PtsWithEachLayoutAndSeveralBlocks) {
  for (int fields : {3, 4, 7}) {
    PointCloudInfo info;
    const PointCloud c = read_point_cloud(write("scan.pts", pts_text(truth_, fields)), &info);
    SCOPED_TRACE(fields);
    EXPECT_EQ(info.format, "pts");
    expect_positions(c, truth_, 0.0);
    EXPECT_EQ(info.has_intensity, fields >= 4);
    EXPECT_EQ(info.has_colour, fields == 7);
    if (fields >= 4) expect_intensities(c, truth_);
    if (fields == 7) expect_colours(c, truth_);
  }
  // Two stations in one file: two blocks, each with its count.
  const std::vector<TestPoint> first(truth_.begin(), truth_.begin() + 4), second(truth_.begin() + 4, truth_.end());
  const PointCloud c = read_point_cloud(write("two.pts", pts_text(first, 7) + pts_text(second, 7)));
  expect_positions(c, truth_, 0.0);
  expect_colours(c, truth_);
}

TEST_F(PointCloudTest, XyzSpaceOrCommaSeparatedWithComments) {
  for (const char* sep : {" ", ",", "\t", ", "}) {
    for (bool colour : {false, true}) {
      PointCloudInfo info;
      const PointCloud c = read_point_cloud(write("scan.xyz", xyz_text(truth_, colour, sep)), &info);
      EXPECT_EQ(info.format, "xyz");
      expect_positions(c, truth_, 0.0);
      EXPECT_EQ(info.has_colour, colour);
      if (colour) expect_colours(c, truth_);
      EXPECT_FALSE(info.has_intensity);
    }
  }
  // .txt is read as XYZ too.
  const PointCloud c = read_point_cloud(write("scan.txt", xyz_text(truth_, true, " ")));
  expect_colours(c, truth_);
}

TEST_F(PointCloudTest, LasEveryPointFormatWithScaleOffsetColourAndIntensity) {
  struct Case {
    int minor, format;
  };
  for (const Case k : {Case{2, 0}, Case{2, 1}, Case{2, 2}, Case{2, 3}, Case{3, 1}, Case{4, 0}, Case{4, 3}, Case{4, 6},
                       Case{4, 7}, Case{4, 8}}) {
    SCOPED_TRACE(fmt::format("LAS 1.{} format {}", k.minor, k.format));
    PointCloudInfo info;
    const PointCloud c = read_point_cloud(write("scan.las", las_bytes(truth_, k.minor, k.format)), &info);
    EXPECT_EQ(info.format, fmt::format("las 1.{} point format {}", k.minor, k.format));
    expect_positions(c, truth_, kLasTolerance);
    expect_intensities(c, truth_);
    const bool rgb = k.format == 2 || k.format == 3 || k.format >= 7;
    EXPECT_EQ(info.has_colour, rgb);
    if (rgb) expect_colours(c, truth_);
  }
  // Records longer than the format's fields (extra bytes) are skipped over.
  const PointCloud c = read_point_cloud(write("extra.las", las_bytes(truth_, 4, 7, 5)));
  expect_positions(c, truth_, kLasTolerance);
  expect_colours(c, truth_);
}

TEST_F(PointCloudTest, ChunksArriveInOrderAndNoLargerThanAsked) {
  const fs::path file = write("chunks.las", las_bytes(truth_, 2, 3));
  std::vector<std::uint64_t> firsts;
  std::vector<std::size_t> sizes;
  std::vector<Eigen::Vector3d> seen;
  ReadOptions options;
  options.chunk_points = 4;
  const PointCloudInfo info = read_point_cloud_chunks(
      file,
      [&](const PointCloud& chunk, std::uint64_t first) {
        firsts.push_back(first);
        sizes.push_back(chunk.size());
        EXPECT_EQ(chunk.colours.size(), chunk.size());
        seen.insert(seen.end(), chunk.positions.begin(), chunk.positions.end());
      },
      options);
  EXPECT_EQ(firsts, (std::vector<std::uint64_t>{0, 4, 8}));
  EXPECT_EQ(sizes, (std::vector<std::size_t>{4, 4, 1}));
  EXPECT_EQ(info.points, std::uint64_t(kPoints));
  ASSERT_EQ(seen.size(), truth_.size());
  EXPECT_NEAR(seen[5].x(), truth_[5].position.x(), kLasTolerance);
}

TEST_F(PointCloudTest, E57AndLazAreRefusedWithWhatToConvertThemTo) {
  const fs::path e57 = write("station.e57", std::string("ASTM-E57") + std::string(64, '\0'));
  try {
    read_point_cloud(e57);
    ADD_FAILURE() << "E57 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(e57.string() + ": E57 is not read by strata"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("convert it to LAS or PLY"), std::string::npos) << e.what();
  }
  // LASzip's compressed point formats have bit 7 set, whatever the extension.
  std::string las = las_bytes(truth_, 2, 3);
  las[104] = char(3 | 0x80);
  const fs::path laz = write("compressed.las", las);
  try {
    read_point_cloud(laz);
    ADD_FAILURE() << "LAZ accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(laz.string() + ": LAZ (compressed LAS) is not read"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("decompress it to LAS"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_point_cloud(write("scan.laz", "anything")), InputError);
  EXPECT_THROW(read_point_cloud(write("scan.obj", "v 1 2 3\n")), InputError);
}

}  // namespace
}  // namespace strata
