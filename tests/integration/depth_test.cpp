// An RGB-D-only layer through the real CLI: a short simulated depth sequence imported
// with its drifting recorded poses, registered (frame to model, loop closure) closer
// to the true poses than the device recorded them, and fused into a DTM whose points
// carry the colour frames' colours; a truncated frame is refused in one line naming
// it, and the project stays as it was. A sequence imported without poses: tracked
// from its colour frames' features and placed in the site frame on the surveyed
// markers they see; with fewer than 3 markers surveyed it is refused in one line
// naming it, the project unchanged. A sequence without poses that sees fewer than 3
// surveyed markers: placed by ICP against the layer's photo surface, levelled on its
// ground first; with no photo surface it is refused in one line, the project unchanged.
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

// `args` refused: a failing exit, one line of error holding every fragment, `dir` (the
// project) as it was.
void expect_refused(const std::vector<std::string>& args, const fs::path& dir,
                    const std::vector<std::string>& fragments) {
  const std::string before = tree_fingerprint(dir);
  const CommandResult r = run_strata(args);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  for (const std::string& f : fragments) EXPECT_NE(r.err.find(f), std::string::npos) << r.err;
  EXPECT_EQ(tree_fingerprint(dir), before);
}

// file -> camera pose (camera -> site frame), from a poses file ('file tx ty tz qx qy qz qw').
std::map<std::string, Eigen::Isometry3d> poses(const fs::path& file) {
  std::map<std::string, Eigen::Isometry3d> out;
  std::istringstream in(read_text(file));
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream f(line);
    std::string name;
    Eigen::Vector3d t;
    Eigen::Quaterniond q;
    f >> name >> t.x() >> t.y() >> t.z() >> q.x() >> q.y() >> q.z() >> q.w();
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = q.normalized().toRotationMatrix();
    pose.translation() = t;
    out[name] = pose;
  }
  return out;
}

// file -> camera centre, from a poses file.
std::map<std::string, Eigen::Vector3d> centres(const fs::path& file) {
  std::map<std::string, Eigen::Vector3d> out;
  for (const auto& [name, pose] : poses(file)) out[name] = pose.translation();
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
  expect_refused(bad, dir / "site", {"importer.depth.png: " + cut.string() + ": byte ", "truncated"});

  args.insert(args.end(), {"--poses", (seq / "poses_recorded.txt").string(), "--colour", (seq / "colour").string()});
  args.insert(args.end(), frames.begin(), frames.end());
  CommandResult r = run_strata(args);
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

// `synth` with `options` besides a depth sequence of kFrames frames.
MarkerLoop simulated_loop(const ScratchDir& dir, const std::vector<std::string>& options) {
  MarkerLoop m;
  m.data = dir / "data";
  std::vector<std::string> args = {"-q", "synth", m.data.string(), "--stages", "1", "--depth", "--depth-frames",
                                   std::to_string(kFrames)};
  args.insert(args.end(), options.begin(), options.end());
  const CommandResult r = run_strata(args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  m.seq = m.data / "depth" / "L2";
  for (const auto& e : fs::directory_iterator(m.seq / "depth")) m.frames.push_back(e.path().string());
  std::sort(m.frames.begin(), m.frames.end());
  return m;
}

MarkerLoop marker_loop(const ScratchDir& dir) {
  return simulated_loop(dir, {"--photos", "3", "--width", "200", "--depth-offset", "1.0"});
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
  expect_refused({"-q", "register", "depth", few, "--layer", "L2"}, few,
                 {"register.depth: sequence 'depth': ", "at least 3 are needed"});
  // Asking for the device's datum without recorded poses: refused too.
  expect_refused({"-q", "register", "depth", few, "--layer", "L2", "--datum", "device"}, few,
                 {"imported without --poses"});
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
  expect_refused({"-q", "register", "depth", site, "--layer", "L2"}, site,
                 {"register.depth: sequence 'depth': frame 00", ": tracking lost after frame 00",
                  "% of its points within the gate of the model"});
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

// The surface datum, measured (docs/range.md, "Depth sequences, measured"): on this
// 24-frame loop 0.3 m outside the trench edge, placed on the photo surface of 14
// photos (800 px wide) the cameras came out at most 7.7 mm (RMS 4.6 mm) and 2.4 mrad
// from their true poses. The bound is 1.9 x and 2.5 x that, room for the surface's own
// noise (its scans' allowance: 4 mm) and the tracking (10 mm with recorded poses,
// kMaxRegisteredErrorM); it is below the markers datum's 20 mm.
constexpr double kMaxSurfaceDatumErrorM = 0.015;
constexpr double kMaxSurfaceDatumRotationRad = 0.006;

// The default loop (0.3 m outside the trench edge) sees one coded target, GCP17, which
// is not surveyed: no marker can place it.
// (Its photos: 14 of 800 px, enough for a dense surface of the small trench.)
MarkerLoop near_loop(const ScratchDir& dir) {
  return simulated_loop(dir, {"--size", "small", "--photos", "14", "--width", "800"});
}

TEST(DepthLayer, ASequenceWithoutPosesOrMarkersAndNoPhotoSurfaceIsRefused) {
  ScratchDir dir("depth_no_surface");
  MarkerLoop m = near_loop(dir);
  m.frames.resize(8);  // the refusal comes after the tracking: a third of the loop keeps it short
  const std::string site = project_without_poses(dir, m, "site", m.data / "markers.csv");
  expect_refused({"-q", "register", "depth", site, "--layer", "L2", "--datum", "auto"}, site,
                 {"register.depth: sequence 'depth': 0 surveyed marker(s) seen", "at least 3 are needed",
                  "no photo surface", "--until dense"});
}

// The layer's photos processed to their dense surface; the sequence, imported without
// poses, sees no surveyed marker: auto places it on the photo surface.
TEST(DepthLayer, ASequenceWithoutPosesOrMarkersIsPlacedOnThePhotoSurface) {
  ScratchDir dir("depth_surface");
  const MarkerLoop m = near_loop(dir);
  const std::string site = project_without_poses(dir, m, "site", m.data / "markers.csv");
  std::vector<std::string> photos = {"-q", "import", "photos", site, "--layer", "L2"};
  for (const auto& e : fs::directory_iterator(m.data / "photos" / "L2")) photos.push_back(e.path().string());
  ok(run_strata(photos));
  // The generator's clicks on the layer's photos (its coded targets are too few pixels
  // wide to be found at this size).
  write_gcp_lines_of(m.data / "gcp_list.txt", "L2_", dir / "gcp_L2.txt");
  ok(run_strata({"-q", "import", "markers", site, (dir / "gcp_L2.txt").string(), "--format", "odm"}));
  ok(run_strata({"-q", "import", "markers", site, (m.data / "markers.csv").string()}));  // the survey, as imported
  ok(run_strata({"-q", "process", site, "--layer", "L2", "--until", "dense"}));

  CommandResult r = run_strata({"-q", "register", "depth", site, "--layer", "L2", "--datum", "auto", "--json"});
  ok(r);
  const nlohmann::json reg = nlohmann::json::parse(r.out);
  const auto& s = reg["sequences"][0];
  const auto& datum = s["datum"];
  EXPECT_EQ(datum["datum"], "surface");
  EXPECT_EQ(datum["against"], "L2");
  for (const char* field : {"rms_m", "inlier_share", "sigma_translation_m", "sigma_rotation_rad", "transform"})
    EXPECT_TRUE(datum.contains(field)) << field;
  EXPECT_GT(datum["inlier_share"].get<double>(), 0.3);
  const auto truth = poses(m.seq / "poses_true.txt");
  double worst = 0, worst_rad = 0;
  for (const auto& f : s["frames"]) {
    const Eigen::Isometry3d& t = truth.at(f["frame"].get<std::string>());
    const nlohmann::json& p = f["pose"];
    Eigen::Matrix3d R;
    R << p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10];
    worst = std::max(worst, (Eigen::Vector3d(p[3], p[7], p[11]) - t.translation()).norm());
    worst_rad = std::max(worst_rad, Eigen::AngleAxisd(t.linear().transpose() * R).angle());
  }
  EXPECT_LT(worst, kMaxSurfaceDatumErrorM);
  EXPECT_LT(worst_rad, kMaxSurfaceDatumRotationRad);
}

}  // namespace
}  // namespace strata::test
