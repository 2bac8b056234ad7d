// An RGB-D-only layer through the real CLI: a short simulated depth sequence imported
// with its drifting recorded poses, registered (frame to model, loop closure) closer
// to the true poses than the device recorded them, and fused into a DTM whose points
// carry the colour frames' colours; a truncated frame is refused in one line naming
// it, and the project stays as it was. A sequence imported without poses: tracked
// from its colour frames' features and placed in the site frame on the surveyed
// markers they see; with fewer than 3 markers surveyed it is refused in one line
// naming it, the project unchanged.
#include "importers/mesh/ply_mesh.hpp"
#include "support/test_support.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

namespace strata::test {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 24;
// The recorded poses drift by centimetres round the loop; registration must bring the
// worst camera within a few depth-noise sigmas (~5 mm at 2 m) of its true place.
constexpr double kMaxRegisteredErrorM = 0.01;
// The fused points' colour from the colour frames: a grey point is one no coloured
// frame reached (a few at the band's edges); the synthetic albedo's green varies by
// tens of levels over soil and stones (grey points would give 0).
constexpr double kMaxGreyShare = 0.01;
constexpr double kMinColourSpreadLevels = 10;

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }
void ok(const CommandResult& r) { ASSERT_EQ(r.exit_code, 0) << r.err; }

// file -> camera centre, from a poses file ('file tx ty tz qx qy qz qw').
std::map<std::string, Eigen::Vector3d> centres(const fs::path& file) {
  std::map<std::string, Eigen::Vector3d> out;
  std::istringstream in(read_text(file));
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream f(line);
    std::string name;
    Eigen::Vector3d t;
    f >> name >> t.x() >> t.y() >> t.z();
    out[name] = t;
  }
  return out;
}

TEST(ImportDepth, HelpTeachesTheFilesAndAnExample) {
  const CommandResult r = run_strata({"import", "depth", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* want : {"16-bit greyscale PNG", "--intrinsics", "--depth-scale", "--poses", "--colour",
                           "Example: strata import depth"})
    EXPECT_NE(r.out.find(want), std::string::npos) << want << " not in:\n" << r.out;
}

TEST(DepthLayer, ImportRegisterAndFuseASimulatedSequence) {
  ScratchDir dir("depth");
  const fs::path data = dir / "data";
  ok(run_strata({"-q", "synth", data.string(), "--stages", "1", "--photos", "3", "--width", "200", "--depth",
                 "--depth-frames", std::to_string(kFrames)}));
  const fs::path seq = data / "depth" / "L2";
  const std::string site = (dir / "site").string();
  ok(run_strata({"-q", "init", site, "--crs", "EPSG:32636", "--origin", "734000,4174000,1450"}));
  ok(run_strata({"-q", "unit", "add", site, "102"}));
  ok(run_strata({"-q", "layer", "add", site, "L2", "--unit", "102"}));
  std::vector<std::string> frames;
  for (const auto& e : fs::directory_iterator(seq / "depth")) frames.push_back(e.path().string());
  std::sort(frames.begin(), frames.end());
  ASSERT_EQ(int(frames.size()), kFrames);

  // A truncated frame among good ones: one line naming it, nothing imported.
  const fs::path cut = dir / "cut" / "0099.png";
  {
    const std::string bytes = read_text(frames[0]);
    write_text(cut, bytes.substr(0, bytes.size() / 2));
  }
  std::vector<std::string> args = {"import", "depth", site, "--layer", "L2", "--intrinsics",
                                   (seq / "intrinsics.txt").string()};
  std::vector<std::string> bad = args;
  bad.insert(bad.end(), {frames[1], cut.string()});
  const std::string tree = tree_fingerprint(dir / "site");
  CommandResult r = run_strata(bad);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("importer.depth.png: " + cut.string() + ": byte "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
  EXPECT_EQ(tree_fingerprint(dir / "site"), tree);

  args.insert(args.end(), {"--poses", (seq / "poses_recorded.txt").string(), "--colour", (seq / "colour").string()});
  args.insert(args.end(), frames.begin(), frames.end());
  r = run_strata(args);
  ok(r);
  EXPECT_NE(r.out.find("layer L2: depth sequence 'depth' imported: 24 frame(s) of 640 x 480 px, 24 with colour, "
                       "24 with a recorded pose"),
            std::string::npos)
      << r.out;

  r = run_strata({"register", "depth", site, "--layer", "L2", "--json"});
  ok(r);
  const nlohmann::json reg = nlohmann::json::parse(r.out);
  ASSERT_EQ(reg["sequences"].size(), 1u);
  const auto& s = reg["sequences"][0];
  EXPECT_TRUE(s["loop_closed"].get<bool>());
  const auto truth = centres(seq / "poses_true.txt");
  double worst_recorded = 0, worst_registered = 0;
  for (const auto& f : s["frames"]) {
    const Eigen::Vector3d t = truth.at(f["frame"].get<std::string>());
    auto centre = [](const nlohmann::json& m) { return Eigen::Vector3d(m[3], m[7], m[11]); };
    worst_recorded = std::max(worst_recorded, (centre(f["recorded_pose"]) - t).norm());
    worst_registered = std::max(worst_registered, (centre(f["pose"]) - t).norm());
    EXPECT_GT(f["inlier_share"].get<double>(), 0.3);
  }
  EXPECT_GT(worst_recorded, kMaxRegisteredErrorM) << "the recorded poses should drift for this test to mean anything";
  EXPECT_LT(worst_registered, kMaxRegisteredErrorM);

  r = run_strata({"process", site, "--layer", "L2", "--json"});
  ok(r);
  const nlohmann::json q = nlohmann::json::parse(r.out);
  EXPECT_EQ(q["dense"]["scans_fused"].get<int>(), kFrames);
  EXPECT_TRUE(fs::exists(dir / "site" / "products" / "L2" / "dtm.tif"));
  // The colour frames reach the fused points: hardly a point is left mid grey, and
  // their colours vary as the synthetic albedo does.
  const DenseMesh points = read_ply(dir / "site" / "products" / "L2" / "dense" / "points.ply").mesh;
  ASSERT_EQ(points.colours.size(), points.vertices.size());
  ASSERT_GT(points.vertices.size(), 10000u);
  std::size_t grey = 0;
  double sum = 0, sum2 = 0;
  for (const auto& c : points.colours) {
    grey += c == Rgb8(128, 128, 128);
    sum += c[1];
    sum2 += double(c[1]) * c[1];
  }
  const double n = double(points.colours.size()), mean = sum / n;
  EXPECT_LT(double(grey) / n, kMaxGreyShare);
  EXPECT_GT(std::sqrt(sum2 / n - mean * mean), kMinColourSpreadLevels) << "green channel's spread over the points";
}

// Placed on the markers: the survey (3 mm), the marker centres' depth and the tracking
// (a few mm each) leave the cameras within a couple of centimetres of their true places.
constexpr double kMaxMarkerDatumErrorM = 0.02;

// A short sequence of the synthetic camera's wider loop, which sees the markers round
// the trench, and a project holding it imported without poses (and `markers`).
struct MarkerLoop {
  fs::path data, seq;
  std::vector<std::string> frames;
};

MarkerLoop marker_loop(const ScratchDir& dir) {
  MarkerLoop m;
  m.data = dir / "data";
  const CommandResult r =
      run_strata({"-q", "synth", m.data.string(), "--stages", "1", "--photos", "3", "--width", "200", "--depth",
                  "--depth-frames", std::to_string(kFrames), "--depth-offset", "1.0"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  m.seq = m.data / "depth" / "L2";
  for (const auto& e : fs::directory_iterator(m.seq / "depth")) m.frames.push_back(e.path().string());
  std::sort(m.frames.begin(), m.frames.end());
  return m;
}

std::string project_without_poses(const ScratchDir& dir, const MarkerLoop& m, const std::string& name,
                                  const fs::path& markers) {
  const std::string site = (dir / name).string();
  EXPECT_EQ(run_strata({"-q", "init", site, "--crs", "EPSG:32636", "--origin", "734000,4174000,1450"}).exit_code, 0);
  EXPECT_EQ(run_strata({"-q", "unit", "add", site, "102"}).exit_code, 0);
  EXPECT_EQ(run_strata({"-q", "layer", "add", site, "L2", "--unit", "102"}).exit_code, 0);
  EXPECT_EQ(run_strata({"-q", "import", "markers", site, markers.string()}).exit_code, 0);
  std::vector<std::string> args = {"import", "depth", site, "--layer", "L2", "--intrinsics",
                                   (m.seq / "intrinsics.txt").string(), "--colour", (m.seq / "colour").string()};
  args.insert(args.end(), m.frames.begin(), m.frames.end());
  const CommandResult r = run_strata(args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(std::to_string(m.frames.size()) + " with colour, 0 with a recorded pose"), std::string::npos)
      << r.out;
  return site;
}

TEST(DepthLayer, ASequenceWithoutPosesAndTooFewMarkersIsRefused) {
  ScratchDir dir("depth_few_markers");
  const MarkerLoop m = marker_loop(dir);
  // Only two of the markers surveyed: refused, naming the sequence, nothing changed.
  {
    std::istringstream all(read_text(m.data / "markers.csv"));
    std::string line, two;
    for (int i = 0; i < 3 && std::getline(all, line); ++i) two += line + "\n";  // the header and 2 markers
    write_text(dir / "two_markers.csv", two);
  }
  const std::string few = project_without_poses(dir, m, "few", dir / "two_markers.csv");
  const std::string before = tree_fingerprint(few);
  CommandResult r = run_strata({"-q", "register", "depth", few, "--layer", "L2"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("register.depth: sequence 'depth': "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("at least 3 are needed"), std::string::npos) << r.err;
  EXPECT_EQ(tree_fingerprint(few), before);
  // Asking for the device's datum without recorded poses: refused too.
  r = run_strata({"-q", "register", "depth", few, "--layer", "L2", "--datum", "device"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("imported without --poses"), std::string::npos) << r.err;
  EXPECT_EQ(tree_fingerprint(few), before);
}

// Where the tracking without the device's motion breaks, the command is refused in one
// line naming the frame and why, the project unchanged: every other frame of the loop
// (30 degrees a frame on average, its corners 60-90 degrees: no features agree across
// them and the model cannot place the frame).
TEST(DepthLayer, ASequenceWhoseTrackingIsLostIsRefusedNamingTheFrame) {
  ScratchDir dir("depth_lost");
  MarkerLoop m = marker_loop(dir);
  std::vector<std::string> every_other;
  for (std::size_t i = 0; i < m.frames.size(); i += 2) every_other.push_back(m.frames[i]);
  m.frames = every_other;
  const std::string site = project_without_poses(dir, m, "site", m.data / "markers.csv");
  const std::string before = tree_fingerprint(site);
  const CommandResult r = run_strata({"-q", "register", "depth", site, "--layer", "L2"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("register.depth: sequence 'depth': frame 00"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(": tracking lost after frame 00"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("% of its points within the gate of the model"), std::string::npos) << r.err;
  EXPECT_EQ(tree_fingerprint(site), before);
}

// Tracked from the colour frames' features round the loop, its corners (22-53 degrees
// between two frames) bridged by the wide match (docs/range.md, "Depth sequences,
// measured"), and placed on the markers.
TEST(DepthLayer, ASequenceWithoutPosesIsPlacedOnTheMarkers) {
  ScratchDir dir("depth_markers");
  const MarkerLoop m = marker_loop(dir);
  const fs::path& seq = m.seq;
  const std::string site = project_without_poses(dir, m, "site", m.data / "markers.csv");
  const CommandResult r = run_strata({"-q", "register", "depth", site, "--layer", "L2", "--json"});
  ok(r);
  const nlohmann::json reg = nlohmann::json::parse(r.out);
  const auto& s = reg["sequences"][0];
  EXPECT_EQ(s["datum"]["datum"], "markers");
  EXPECT_GE(s["datum"]["inliers"].get<int>(), 3);
  EXPECT_NEAR(s["datum"]["scale"].get<double>(), 1.0, 0.01);
  const auto truth = centres(seq / "poses_true.txt");
  int from_features = 0;
  double worst = 0;
  for (const auto& f : s["frames"]) {
    EXPECT_FALSE(f.contains("recorded_pose"));
    from_features += f["start"] == "features";
    const Eigen::Vector3d t = truth.at(f["frame"].get<std::string>());
    const nlohmann::json& pose = f["pose"];
    worst = std::max(worst, (Eigen::Vector3d(pose[3], pose[7], pose[11]) - t).norm());
  }
  // 24 frames a loop are 15 degrees apart: most, not all, pairs share enough features.
  EXPECT_GE(from_features, kFrames / 2);
  EXPECT_LT(worst, kMaxMarkerDatumErrorM);
}

}  // namespace
}  // namespace strata::test
