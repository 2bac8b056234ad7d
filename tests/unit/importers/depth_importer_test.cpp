// importer.depth: a depth sequence stored like photos (content-addressed, unchanged),
// its intrinsics and recorded poses read back, and every bad file refused with one
// message naming it (and where in it the fault is) while the project stays as it was.
#include "core/error.hpp"
#include "core/hash.hpp"
#include "importer_fixture.hpp"
#include "importers/depth/depth_importer.hpp"
#include "project/depth_records.hpp"
#include "scan_files.hpp"

#include <Eigen/Geometry>

#include <fstream>
#include <functional>
#include <iterator>

namespace strata {
namespace {

namespace fs = std::filesystem;
using namespace test;

constexpr int kWidth = 32, kHeight = 24;
// A pose read from 9 printed decimals of a unit quaternion and 6 of a translation.
constexpr double kPoseTolerance = 1e-6;

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class DepthImportTest : public ImporterTest {
 protected:
  void SetUp() override {
    ImporterTest::SetUp();
    Transaction tx(db());
    project().set_origin_if_unset({734010, 4174015, 1450});
    tx.commit();
    intrinsics_ = write("intrinsics.txt", "# test camera\nwidth 32\nheight 24\nfx 30\nfy 30\ncx 15.5\ncy 11.5\n");
  }

  // A 16-bit depth frame: a slope in millimetres, different for each seed; `zero`
  // pixels left without depth.
  fs::path depth_frame(const std::string& name, int seed, int width = kWidth, int height = kHeight, int type = CV_16UC1) {
    cv::Mat img(height, width, type);
    for (int r = 0; r < height; ++r)
      for (int c = 0; c < width; ++c) {
        const int v = 1000 + 10 * seed + 7 * r + 3 * c + ((r * 31 + c * 17 + seed) % 5 == 0 ? 0 : 1);
        if (type == CV_16UC1) img.at<std::uint16_t>(r, c) = std::uint16_t(r == 0 && c < 4 ? 0 : v);
        else img.at<std::uint8_t>(r, c) = std::uint8_t(v % 256);
      }
    const fs::path p = scratch() / "in" / "depth" / name;
    fs::create_directories(p.parent_path());
    EXPECT_TRUE(cv::imwrite(p.string(), img));
    return p;
  }
  fs::path colour_frame(const std::string& name, int seed) {
    cv::Mat img(kHeight, kWidth, CV_8UC3, cv::Scalar(seed, 2 * seed, 3 * seed));
    const fs::path p = scratch() / "in" / "colour" / name;
    fs::create_directories(p.parent_path());
    EXPECT_TRUE(cv::imwrite(p.string(), img));
    return p;
  }
  fs::path poses(const std::string& text) { return write("poses.txt", "# file tx ty tz qx qy qz qw\n" + text); }
  fs::path good_poses() {
    return poses("0001.png 11.5 17.2 1.25 0 0 0 1\n"
                 "0002.png 11.6 17.2 1.25 0.0499792 0 0 0.9987503\n"
                 "0003.png 11.7 17.3 1.26 0 0 0 1\n");
  }
  DepthImportOptions options() {
    DepthImportOptions o;
    o.layer = "L1";
    o.intrinsics = intrinsics_;
    return o;
  }
  std::vector<fs::path> three_frames() { return {depth_frame("0001.png", 1), depth_frame("0002.png", 2), depth_frame("0003.png", 3)}; }

  // Imports and expects one InputError containing every one of `expected`, the
  // database and media/ exactly as before.
  void expect_refused(const std::vector<fs::path>& frames, const DepthImportOptions& o,
                      const std::vector<std::string>& expected) {
    const std::string rows = dump();
    const std::string media = tree_fingerprint(project().media_dir());
    try {
      import_depth(project(), o, frames);
      ADD_FAILURE() << "accepted " << frames.front();
    } catch (const InputError& e) {
      for (const auto& want : expected)
        EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << "message: " << e.what() << "\nwanted: " << want;
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
    }
    EXPECT_EQ(dump(), rows);
    EXPECT_EQ(tree_fingerprint(project().media_dir()), media);
  }
  // A copy of `source` with its bytes changed by `edit`, as `name`.
  fs::path edited(const fs::path& source, const std::string& name, const std::function<void(std::string&)>& edit) {
    std::string bytes = read_all(source);
    edit(bytes);
    const fs::path p = scratch() / "in" / "bad" / name;
    write_bytes(p, bytes);
    return p;
  }

  fs::path intrinsics_;
};

TEST_F(DepthImportTest, SequenceIsStoredUnchangedWithIntrinsicsPosesAndColour) {
  const auto frames = three_frames();
  for (int i = 0; i < 3; ++i) colour_frame(frames[std::size_t(i)].filename().string(), 10 + i);
  DepthImportOptions o = options();
  o.poses = good_poses();
  o.colour_dir = scratch() / "in" / "colour";
  o.noise_k = 0.002;
  const DepthImportSummary s = import_depth(project(), o, frames);
  EXPECT_EQ(s.sequence, "depth");  // the frames' folder
  EXPECT_EQ(s.frames, 3);
  EXPECT_EQ(s.with_colour, 3);
  EXPECT_EQ(s.with_pose, 3);

  const auto seqs = list_depth_sequences(db());
  ASSERT_EQ(seqs.size(), 1u);
  EXPECT_EQ(seqs[0].intrinsics.width, kWidth);
  EXPECT_EQ(seqs[0].intrinsics.height, kHeight);
  EXPECT_DOUBLE_EQ(seqs[0].intrinsics.fx, 30);
  EXPECT_DOUBLE_EQ(seqs[0].intrinsics.cy, 11.5);
  EXPECT_DOUBLE_EQ(seqs[0].depth_scale_m, 0.001);
  EXPECT_DOUBLE_EQ(seqs[0].noise_k, 0.002);
  EXPECT_EQ(seqs[0].intrinsics_file, "intrinsics.txt");
  EXPECT_EQ(seqs[0].poses_file, std::optional<std::string>("poses.txt"));

  const auto rows = list_depth_frames(db(), seqs[0].id);
  ASSERT_EQ(rows.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const DepthFrameRecord& r = rows[std::size_t(i)];
    EXPECT_EQ(r.frame, i);
    EXPECT_EQ(r.name, frames[std::size_t(i)].filename().string());
    EXPECT_EQ(r.sha256, sha256_file(frames[std::size_t(i)]));
    EXPECT_EQ(r.media_path, "media/" + r.sha256.substr(0, 2) + "/" + r.sha256 + ".png");
    EXPECT_EQ(read_all(project().dir() / r.media_path), read_all(frames[std::size_t(i)]));  // byte for byte
    EXPECT_EQ(r.valid_pixels, kWidth * kHeight - 4);  // four pixels of the first row have no depth
    ASSERT_TRUE(r.colour_media_path);
    EXPECT_TRUE(fs::exists(project().dir() / *r.colour_media_path));
    EXPECT_FALSE(r.pose);  // registered later
    ASSERT_TRUE(r.recorded_pose);
  }
  // The second pose: 0.1 rad about x, from its quaternion.
  const Eigen::Isometry3d second(*rows[1].recorded_pose);
  const Eigen::Matrix3d want = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_LT((second.linear() - want).cwiseAbs().maxCoeff(), kPoseTolerance);
  EXPECT_LT((second.translation() - Eigen::Vector3d(11.6, 17.2, 1.25)).norm(), kPoseTolerance);
}

TEST_F(DepthImportTest, BadDepthFramesAreRefusedNamingFileAndByte) {
  const fs::path good = depth_frame("0001.png", 1);
  const fs::path other = depth_frame("0002.png", 2);
  // A truncated file: cut inside its image data.
  const fs::path cut = edited(good, "cut.png", [](std::string& b) { b.resize(b.size() / 2); });
  expect_refused({other, cut}, options(), {"importer.depth.png", "cut.png", "byte ", "the file ends inside chunk 'IDAT'", "truncated"});
  // The end chunk missing.
  const fs::path no_end = edited(good, "noend.png", [](std::string& b) { b.resize(b.size() - 12); });
  expect_refused({no_end}, options(), {"noend.png", "without its IEND chunk"});
  // Not a PNG (a wrong header).
  const fs::path text = write("depth/notpng.png", "P2\n32 24\n65535\n");
  expect_refused({text}, options(), {"importer.depth.png", "notpng.png", "byte 0", "not a PNG file"});
  // One byte of the image data changed: the chunk's CRC fails.
  const fs::path flipped = edited(good, "flipped.png", [](std::string& b) { b[b.size() - 20] ^= 0x55; });
  expect_refused({flipped}, options(), {"flipped.png", "CRC"});
  // An 8-bit image, a frame of another size, a frame without any depth.
  expect_refused({depth_frame("grey8.png", 1, kWidth, kHeight, CV_8UC1)}, options(),
                 {"grey8.png", "byte 24", "8-bit grey", "16-bit greyscale"});
  expect_refused({depth_frame("big.png", 1, 40, 30)}, options(), {"big.png", "40 x 30 pixels", "32 x 24"});
  const fs::path empty = scratch() / "in" / "depth" / "empty.png";
  cv::imwrite(empty.string(), cv::Mat(kHeight, kWidth, CV_16UC1, cv::Scalar(0)));
  expect_refused({empty}, options(), {"empty.png", "holds no depth"});
  // Missing file, the same frame twice.
  expect_refused({scratch() / "in" / "nowhere.png"}, options(), {"nowhere.png", "does not exist"});
  expect_refused({good, good}, options(), {"a second frame named '0001.png'"});
}

TEST_F(DepthImportTest, BadIntrinsicsPosesAndColourAreRefusedNamingFileAndLine) {
  const auto frames = three_frames();
  DepthImportOptions o = options();
  o.intrinsics = write("k1.txt", "width 32\nheight 24\nfx 30\nfy 30\ncx 15.5\n");
  expect_refused(frames, o, {"importer.depth.intrinsics", "k1.txt", "no 'cy' line"});
  o.intrinsics = write("k2.txt", "width 32\nheight 24\nfx 30\nfy 30\ncx 15.5\ncy 11.5\nk1 0.1\n");
  expect_refused(frames, o, {"k2.txt", "line 7", "unknown key 'k1'"});
  o.intrinsics = write("k3.txt", "width 32\nheight 24\nfx -30\nfy 30\ncx 15.5\ncy 11.5\n");
  expect_refused(frames, o, {"k3.txt", "line 3", "fx -30 must be > 0"});
  o.intrinsics = write("k4.txt", "width 32.5\nheight 24\nfx 30\nfy 30\ncx 15.5\ncy 11.5\n");
  expect_refused(frames, o, {"k4.txt", "line 1", "whole number"});
  o.intrinsics = write("k5.txt", "width 32\nheight 24\nfx 30\nfx 31\nfy 30\ncx 15.5\ncy 11.5\n");
  expect_refused(frames, o, {"k5.txt", "line 4", "'fx' given twice"});

  o = options();
  o.poses = poses("0001.png 11.5 17.2 1.25 0 0 0 1\n0002.png 11.6 17.2 1.25 0 0 0 1\n");
  expect_refused(frames, o, {"importer.depth", "poses.txt", "no pose for frame 0003.png"});
  o.poses = poses("0001.png 11.5 17.2 1.25 0 0 0 1\n0002.png 11.6 17.2 1.25 0 0 0 2\n0003.png 1 1 1 0 0 0 1\n");
  expect_refused(frames, o, {"importer.depth.poses", "line 3", "norm is 2"});
  o.poses = poses("0001.png 11.5 17.2 1.25 0 0 0 1\n0001.png 11.6 17.2 1.25 0 0 0 1\n");
  expect_refused(frames, o, {"line 3", "a second pose of '0001.png' (the first on line 2)"});
  o.poses = poses("0001.png 11.5 17.2 1.25 0 0 1\n");
  expect_refused(frames, o, {"line 2", "7 fields"});
  o.poses = poses("0001.png 11.5 17.2 x 0 0 0 1\n");
  expect_refused(frames, o, {"line 2", "tz 'x' is not a number"});

  o = options();
  o.colour_dir = scratch() / "in" / "colour";
  colour_frame("0001.png", 1);
  colour_frame("0002.png", 2);
  expect_refused(frames, o, {"importer.depth", "0003.png", "no colour frame"});
  // A 16-bit colour frame.
  const fs::path c3 = scratch() / "in" / "colour" / "0003.png";
  cv::imwrite(c3.string(), cv::Mat(kHeight, kWidth, CV_16UC3, cv::Scalar(1, 2, 3)));
  expect_refused(frames, o, {"importer.depth.colour", "0003.png", "16-bit RGB"});

  o = options();
  o.depth_scale_m = 0;
  expect_refused(frames, o, {"--depth-scale 0"});
  o = options();
  o.noise_k = -1;
  expect_refused(frames, o, {"--noise-k -1"});
}

TEST_F(DepthImportTest, TheSameSequenceTwiceIsRefusedAndChangesNothing) {
  const auto frames = three_frames();
  import_depth(project(), options(), frames);
  expect_refused(frames, options(), {"already has a depth sequence named 'depth'"});
  DepthImportOptions o = options();
  o.sequence = "again";
  expect_refused(frames, o, {"0001.png", "already imported"});
}

}  // namespace
}  // namespace strata
