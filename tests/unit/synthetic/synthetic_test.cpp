// Tests of the synthetic excavation generator: the truth must be consistent with
// itself and with the photos (docs/synthetic.md).
#include "core/error.hpp"
#include "geometry/camera.hpp"
#include "support/shared_scene.hpp"
#include "support/test_support.hpp"
#include "synthetic/depth_camera.hpp"
#include "synthetic/finds.hpp"
#include "synthetic/render.hpp"
#include "synthetic/scans.hpp"
#include "synthetic/scene.hpp"
#include "synthetic/synthetic.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

namespace fs = std::filesystem;

namespace strata {
namespace {

// ---- tolerances, each with its reason -------------------------------------------
// Float32 rasters of heights near 1450 m: a ulp is 0.12 mm.
constexpr double kRasterUlp = 2e-4;  // metres
// Volumes from the 5 mm truth rasters (midpoint rule) vs the exact integral over
// the 4 mm height field: they differ only at the steep sides, well under 1 %.
constexpr double kVolumeRelTol = 0.01;
// gcp_list pixels are written with 4 decimals.
constexpr double kGcpPixelTol = 1e-3;
// Surveyed markers carry 3 mm Gaussian noise: 5 sigma bound per axis.
constexpr double kSurveyNoiseBound = 5 * 0.003;
// A detected ArUco centre (diagonal intersection of 4 corners found to ~0.1-0.3 px
// after JPEG and noise) vs the true projection of the printed centre.
constexpr double kArucoCentreTol = 1.0;  // pixels
// ArUco must find the markers whose code cells appear at least this large (pixels,
// across the foreshortened direction) ...
constexpr double kMinCellPixels = 4.0;
// ... at least this often (JPEG, noise and grazing views defeat a few).
constexpr double kMinDetectionRate = 0.7;
// The centroid of a painted 1.5 cm disc vs the projection of its centre: pixel
// quantisation and the tiny perspective bias of a disc (radius^2 / distance).
constexpr double kSpotTol = 0.3;  // pixels
// A find's height vs a truth raster cell whose centre is up to 3.5 mm away on a
// surface of at most ~30 % slope (away from the trench sides and the wall).
constexpr double kFindRasterSlack = 0.002;  // metres
// A ray ending at a point hidden behind the trench side stops this much earlier.
constexpr double kOcclusionMargin = 0.05;  // metres

using Table = std::vector<std::map<std::string, std::string>>;

Table read_csv(const fs::path& path, std::string* header = nullptr) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::string line;
  std::getline(in, line);
  if (header) *header = line;
  std::vector<std::string> names;
  std::stringstream hs(line);
  for (std::string f; std::getline(hs, f, ',');) names.push_back(f);
  Table rows;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::map<std::string, std::string> row;
    std::stringstream ls(line);
    std::size_t i = 0;
    for (std::string f; std::getline(ls, f, ',') && i < names.size(); ++i) row[names[i]] = f;
    rows.push_back(row);
  }
  return rows;
}

struct GcpLine {
  double e, n, z, u, v;
  std::string image, marker;
};
std::vector<GcpLine> read_gcp(const fs::path& path, std::string* first) {
  std::ifstream in(path);
  std::getline(in, *first);
  std::vector<GcpLine> out;
  for (GcpLine g; in >> g.e >> g.n >> g.z >> g.u >> g.v >> g.image >> g.marker;) out.push_back(g);
  return out;
}

struct Raster {
  double gt[6]{};
  int cols = 0, rows = 0;
  std::vector<float> z;
  std::string wkt;
  double nodata = 0;
};
Raster read_raster(const fs::path& path) {
  GDALAllRegister();
  Raster r;
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.string().c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) {
    ADD_FAILURE() << "cannot open " << path;
    return r;
  }
  ds->GetGeoTransform(r.gt);
  r.cols = ds->GetRasterXSize();
  r.rows = ds->GetRasterYSize();
  r.z.resize(std::size_t(r.cols) * std::size_t(r.rows));
  auto* band = ds->GetRasterBand(1);
  r.nodata = band->GetNoDataValue();
  EXPECT_EQ(band->GetRasterDataType(), GDT_Float32);
  EXPECT_EQ(band->RasterIO(GF_Read, 0, 0, r.cols, r.rows, r.z.data(), r.cols, r.rows, GDT_Float32, 0, 0), CE_None);
  if (const auto* srs = ds->GetSpatialRef()) r.wkt = srs->GetAuthorityCode(nullptr) ? srs->GetAuthorityCode(nullptr) : "";
  return r;
}

// Camera in the site frame from a truth cameras.csv row.
Camera camera_from_row(const std::map<std::string, std::string>& row, const Eigen::Vector3d& origin, int w, int h) {
  Camera c;
  c.intrinsics = {w, h, std::stod(row.at("fx")), std::stod(row.at("fy")), std::stod(row.at("ppx")),
                  std::stod(row.at("ppy")), std::stod(row.at("k1")),
                  std::stod(row.at("k2"))};
  Eigen::Matrix3d R;
  const char* names[9] = {"r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33"};
  for (int i = 0; i < 9; ++i) R(i / 3, i % 3) = std::stod(row.at(names[i]));
  const Eigen::Vector3d centre(std::stod(row.at("X")), std::stod(row.at("Y")), std::stod(row.at("Z")));
  c.pose = Pose::from_centre(R, centre - origin);
  return c;
}

// The small scene, generated once for every process of the suite (ctest runs each
// test in its own process; support/shared_scene.hpp). The tests only read it; the
// generator's summary figures they check are kept beside it, in summary.txt.
class SmallExcavation : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    options_ = SyntheticExcavationOptions::preset(SyntheticExcavationOptions::Size::small);
    options_.seed = 3;
    options_.photos.per_layer = 8;  // the small preset, fewer photos: keeps the suite fast
    const fs::path scene = test::shared_scene("synthetic_small", "small seed 3 photos 8", [](const fs::path& d) {
      const auto s = generate_excavation(options_, d / "data");
      std::ofstream(d / "summary.txt") << s.layers << " " << s.photos << " " << s.finds << " "
                                       << s.planted_contradictions << "\n";
    });
    dir_ = scene / "data";
    std::ifstream(scene / "summary.txt") >> summary_.layers >> summary_.photos >> summary_.finds >>
        summary_.planted_contradictions;
  }
  static Eigen::Vector3d origin() {
    return {options_.site.origin_e, options_.site.origin_n, options_.site.origin_z};
  }
  static fs::path dir_;
  static SyntheticExcavationOptions options_;
  static SyntheticExcavationSummary summary_;
};
fs::path SmallExcavation::dir_;
SyntheticExcavationOptions SmallExcavation::options_;
SyntheticExcavationSummary SmallExcavation::summary_;

TEST_F(SmallExcavation, WritesTheDocumentedLayout) {
  const fs::path& d = dir_;
  const int layers = options_.site.stages + 1;
  EXPECT_EQ(summary_.layers, layers);
  EXPECT_EQ(summary_.photos, layers * options_.photos.per_layer);
  std::string h;
  read_csv(d / "units.csv", &h);
  EXPECT_EQ(h, "code,type,description");
  read_csv(d / "relations.csv", &h);
  EXPECT_EQ(h, "a,relation,b");
  const auto layer_rows = read_csv(d / "layers.csv", &h);
  EXPECT_EQ(h, "layer,unit,captured_at,photos_dir");
  ASSERT_EQ(int(layer_rows.size()), layers);
  read_csv(d / "markers.csv", &h);
  EXPECT_EQ(h, "name,E,N,Z,sigma,kind");
  read_csv(d / "truth" / "markers.csv", &h);
  EXPECT_EQ(h, "name,E,N,Z,sigma,kind");
  const auto volumes = read_csv(d / "truth" / "units.csv", &h);
  EXPECT_EQ(h, "unit,volume_m3,area_m2,mean_thickness_m,max_thickness_m");
  EXPECT_EQ(int(volumes.size()), options_.site.stages);
  std::set<std::string> names;
  for (int k = 1; k <= layers; ++k) {
    const std::string l = "L" + std::to_string(k);
    EXPECT_EQ(layer_rows[std::size_t(k - 1)].at("layer"), l);
    EXPECT_EQ(layer_rows[std::size_t(k - 1)].at("photos_dir"), "photos/" + l);
    const auto cams = read_csv(d / "truth" / l / "cameras.csv", &h);
    EXPECT_EQ(h, "image,fx,fy,ppx,ppy,k1,k2,r11,r12,r13,r21,r22,r23,r31,r32,r33,X,Y,Z");
    EXPECT_EQ(int(cams.size()), options_.photos.per_layer);
    for (const auto& c : cams) {
      EXPECT_TRUE(fs::exists(d / "photos" / l / c.at("image"))) << c.at("image");
      EXPECT_TRUE(names.insert(c.at("image")).second) << "image names must be unique: " << c.at("image");
    }
    EXPECT_TRUE(fs::exists(d / "truth" / l / "surface.tif"));
  }
  std::ifstream site(d / "site.json");
  std::string json((std::istreambuf_iterator<char>(site)), {});
  EXPECT_NE(json.find("\"crs\": \"EPSG:32636\""), std::string::npos);
  EXPECT_NE(json.find("\"photos\": \"photos/L1\""), std::string::npos);
  // Relations name existing units and include the pit's cut and fill.
  std::set<std::string> codes;
  for (const auto& u : read_csv(d / "units.csv")) codes.insert(u.at("code"));
  bool cuts = false, fills = false;
  for (const auto& r : read_csv(d / "relations.csv")) {
    EXPECT_TRUE(codes.count(r.at("a")) && codes.count(r.at("b")));
    cuts |= r.at("relation") == "cuts";
    fills |= r.at("relation") == "fills";
  }
  EXPECT_TRUE(cuts && fills);
}

TEST_F(SmallExcavation, LaterSurfacesNeverRiseAndGroundOutsideStays) {
  const int layers = options_.site.stages + 1;
  const Raster first = read_raster(dir_ / "truth" / "L1" / "surface.tif");
  EXPECT_EQ(first.wkt, "32636");
  EXPECT_DOUBLE_EQ(first.gt[1], options_.render.truth_cell);
  // The site.json trench box, to tell inside from outside.
  const Table markers = read_csv(dir_ / "truth" / "markers.csv");
  Raster prev = first;
  for (int k = 2; k <= layers; ++k) {
    const Raster r = read_raster(dir_ / "truth" / ("L" + std::to_string(k)) / "surface.tif");
    ASSERT_EQ(r.z.size(), prev.z.size());
    int lowered = 0, same_edge = 0, edge = 0;
    for (int row = 0; row < r.rows; ++row)
      for (int col = 0; col < r.cols; ++col) {
        const std::size_t i = std::size_t(row) * std::size_t(r.cols) + std::size_t(col);
        EXPECT_LE(r.z[i], prev.z[i] + kRasterUlp) << "layer L" << k << " rises at row " << row << " col " << col;
        lowered += r.z[i] < prev.z[i] - kRasterUlp;
        // The outer ring of the raster lies outside the trench (0.25 m margin).
        if (row == 0 || col == 0 || row == r.rows - 1 || col == r.cols - 1) {
          ++edge;
          same_edge += std::abs(r.z[i] - first.z[i]) <= kRasterUlp;
        }
      }
    EXPECT_GT(lowered, 0);
    EXPECT_EQ(same_edge, edge) << "ground outside the trench changed in L" << k;
    prev = r;
  }
}

TEST_F(SmallExcavation, UnitVolumesAgreeWithTheTruthRasters) {
  const Table volumes = read_csv(dir_ / "truth" / "units.csv");
  for (std::size_t k = 0; k < volumes.size(); ++k) {
    const Raster before = read_raster(dir_ / "truth" / ("L" + std::to_string(k + 1)) / "surface.tif");
    const Raster after = read_raster(dir_ / "truth" / ("L" + std::to_string(k + 2)) / "surface.tif");
    double volume = 0;
    for (std::size_t i = 0; i < before.z.size(); ++i) volume += double(before.z[i]) - double(after.z[i]);
    volume *= before.gt[1] * before.gt[1];
    const double truth = std::stod(volumes[k].at("volume_m3"));
    EXPECT_NEAR(volume, truth, kVolumeRelTol * truth) << "unit " << volumes[k].at("unit");
    // 4 m x 3 m at 5-30 cm.
    const double area = std::stod(volumes[k].at("area_m2")), mean = std::stod(volumes[k].at("mean_thickness_m"));
    EXPECT_NEAR(mean, truth / area, 1e-6);
    EXPECT_GT(mean, options_.site.min_unit_thickness);
    EXPECT_LT(mean, options_.site.max_unit_thickness);
    EXPECT_LE(area, options_.site.trench_size_e * options_.site.trench_size_n * 1.02);
  }
}

// The truth surface at (E, N): the raster cell that holds the point.
double height_at(const Raster& r, double e, double n) {
  const int col = int(std::floor((e - r.gt[0]) / r.gt[1])), row = int(std::floor((n - r.gt[3]) / r.gt[5]));
  return r.z[std::size_t(row) * std::size_t(r.cols) + std::size_t(col)];
}

TEST_F(SmallExcavation, FindsArePlantedWellInsideTheirTrueUnit) {
  std::string h;
  const Table truth = read_csv(dir_ / "truth" / "finds.csv", &h);
  EXPECT_EQ(h, "id,E,N,Z,true_unit,recorded_unit,planted_contradiction,depth_m,clearance_m");
  const Table measured = read_csv(dir_ / "finds.csv", &h);
  EXPECT_EQ(h, "id,E,N,Z,unit,type,description");
  const int stages = options_.site.stages;
  ASSERT_EQ(int(truth.size()), stages * synthetic::kFindsPerUnit + synthetic::kPlantedContradictions);
  ASSERT_EQ(measured.size(), truth.size());
  EXPECT_EQ(summary_.finds, int(truth.size()));
  EXPECT_EQ(summary_.planted_contradictions, synthetic::kPlantedContradictions);
  std::map<std::string, int> per_unit;
  int contradictions = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const auto& t = truth[i];
    const auto& m = measured[i];
    ASSERT_EQ(m.at("id"), t.at("id"));
    EXPECT_EQ(m.at("unit"), t.at("recorded_unit"));
    const bool wrong = t.at("planted_contradiction") == "1";
    EXPECT_EQ(wrong, t.at("true_unit") != t.at("recorded_unit")) << t.at("id");
    contradictions += wrong;
    per_unit[t.at("true_unit")] += wrong ? 0 : 1;
    const double e = std::stod(t.at("E")), n = std::stod(t.at("N")), z = std::stod(t.at("Z"));
    for (const char* axis : {"E", "N", "Z"})
      EXPECT_NEAR(std::stod(m.at(axis)), std::stod(t.at(axis)), kSurveyNoiseBound) << t.at("id") << " " << axis;
    // Unit 10k lies between the surfaces of layers L(k-100) and L(k-99).
    const int k = std::stoi(t.at("true_unit")) - 100;
    const Raster top = read_raster(dir_ / "truth" / ("L" + std::to_string(k)) / "surface.tif");
    const Raster bottom = read_raster(dir_ / "truth" / ("L" + std::to_string(k + 1)) / "surface.tif");
    // The raster cell's centre is up to half a cell away: allow for the slope.
    EXPECT_GE(height_at(top, e, n) - z, synthetic::kFindMinClearance - kFindRasterSlack) << t.at("id");
    EXPECT_GE(z - height_at(bottom, e, n), synthetic::kFindMinClearance - kFindRasterSlack) << t.at("id");
    EXPECT_GE(std::stod(t.at("clearance_m")), synthetic::kFindMinClearance) << t.at("id");
  }
  EXPECT_EQ(contradictions, synthetic::kPlantedContradictions);
  for (int k = 0; k < stages; ++k) EXPECT_EQ(per_unit[std::to_string(101 + k)], synthetic::kFindsPerUnit);
}

TEST_F(SmallExcavation, MarkersProjectOntoTheGcpListPixels) {
  std::string first;
  const auto gcp = read_gcp(dir_ / "gcp_list.txt", &first);
  EXPECT_EQ(first, "EPSG:32636");
  ASSERT_FALSE(gcp.empty());
  std::map<std::string, Eigen::Vector3d> truth, surveyed;
  std::map<std::string, std::string> kind;
  for (const auto& m : read_csv(dir_ / "truth" / "markers.csv"))
    truth[m.at("name")] = {std::stod(m.at("E")), std::stod(m.at("N")), std::stod(m.at("Z"))};
  for (const auto& m : read_csv(dir_ / "markers.csv")) {
    surveyed[m.at("name")] = {std::stod(m.at("E")), std::stod(m.at("N")), std::stod(m.at("Z"))};
    kind[m.at("name")] = m.at("kind");
  }
  EXPECT_EQ(int(truth.size()), options_.site.markers);
  int checks = 0;
  for (const auto& [name, k] : kind) checks += k == "check";
  EXPECT_EQ(checks, options_.site.check_markers);
  for (const auto& [name, t] : truth) EXPECT_LT((surveyed.at(name) - t).cwiseAbs().maxCoeff(), kSurveyNoiseBound);

  std::map<std::string, Camera> cameras;
  for (int k = 1; k <= options_.site.stages + 1; ++k)
    for (const auto& row : read_csv(dir_ / "truth" / ("L" + std::to_string(k)) / "cameras.csv"))
      cameras[row.at("image")] = camera_from_row(row, origin(), options_.photos.width, options_.photos.height);
  std::map<std::string, int> per_image;
  for (const auto& g : gcp) {
    const auto px = cameras.at(g.image).project(truth.at(g.marker) - origin());
    ASSERT_TRUE(px.has_value());
    EXPECT_NEAR(px->x(), g.u, kGcpPixelTol) << g.image << " " << g.marker;
    EXPECT_NEAR(px->y(), g.v, kGcpPixelTol) << g.image << " " << g.marker;
    EXPECT_NEAR(g.e, surveyed.at(g.marker).x(), 1e-4);
    ++per_image[g.image];
  }
  // Oblique views keep markers in view (the near-vertical ones over the trench
  // do not): a quarter of all photos show three or more, and each layer sees
  // all but at most two of the markers.
  int with_three = 0;
  for (const auto& [image, n] : per_image) with_three += n >= 3;
  EXPECT_GE(with_three, int(cameras.size()) / 4);
  std::map<std::string, std::set<std::string>> seen;
  for (const auto& g : gcp) seen[g.image.substr(0, g.image.find('_'))].insert(g.marker);
  EXPECT_EQ(int(seen.size()), options_.site.stages + 1);
  for (const auto& [layer, names] : seen) EXPECT_GE(int(names.size()), options_.site.markers - 2) << layer;
}

// The photos themselves: ArUco finds the printed targets where the truth says.
TEST_F(SmallExcavation, ArucoFindsTheMarkersAtTheTruePixels) {
  std::string first;
  const auto gcp = read_gcp(dir_ / "gcp_list.txt", &first);
  std::map<std::string, Eigen::Vector3d> truth;
  for (const auto& m : read_csv(dir_ / "truth" / "markers.csv"))
    truth[m.at("name")] = Eigen::Vector3d(std::stod(m.at("E")), std::stod(m.at("N")), std::stod(m.at("Z"))) - origin();
  std::map<std::string, Camera> cameras;
  for (int k = 1; k <= options_.site.stages + 1; ++k)
    for (const auto& row : read_csv(dir_ / "truth" / ("L" + std::to_string(k)) / "cameras.csv"))
      cameras[row.at("image")] = camera_from_row(row, origin(), options_.photos.width, options_.photos.height);
  // Expected: per image, marker id -> (true pixel, apparent cell size in pixels).
  std::map<std::string, std::map<int, std::pair<Eigen::Vector2d, double>>> expected;
  for (const auto& g : gcp) {
    const Camera& cam = cameras.at(g.image);
    const Eigen::Vector3d ray = truth.at(g.marker) - cam.pose.centre();
    double cell = options_.site.marker_size / 8 * cam.intrinsics.fx / ray.norm() * (-ray.normalized().z());
    // A marker cut by the frame cannot be decoded: count it as small.
    const double reach = 0.75 * options_.site.marker_size * cam.intrinsics.fx / ray.norm();  // px, half diagonal
    if (g.u < reach || g.v < reach || g.u > cam.intrinsics.width - 1 - reach || g.v > cam.intrinsics.height - 1 - reach)
      cell = 0;
    expected[g.image][std::stoi(g.marker.substr(3))] = {{g.u, g.v}, cell};
  }
  auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  auto params = cv::aruco::DetectorParameters::create();
  params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
  int found = 0, must_find = 0, found_of_must = 0;
  for (const auto& [name, markers] : expected) {
    const std::string layer = name.substr(0, name.find('_'));
    const cv::Mat img = cv::imread((dir_ / "photos" / layer / name).string());
    ASSERT_FALSE(img.empty()) << name;
    std::vector<int> ids;
    std::vector<std::vector<cv::Point2f>> corners;
    cv::aruco::detectMarkers(img, dict, corners, ids, params);
    std::set<int> detected;
    for (std::size_t m = 0; m < ids.size(); ++m) {
      // Soil texture occasionally decodes as some other code, as real ground does;
      // an id of ours where the truth sees none would be a rendering error.
      if (ids[m] < 1 || ids[m] > options_.site.markers) continue;
      auto it = markers.find(ids[m]);
      if (it == markers.end()) {
        ADD_FAILURE() << name << ": detected GCP" << ids[m] << " that the truth does not see";
        continue;
      }
      detected.insert(ids[m]);
      ++found;
      // Position accuracy is only meaningful for markers imaged large enough.
      if (it->second.second < kMinCellPixels) continue;
      // Centre of the printed square = intersection of the diagonals of its corners.
      const auto& c = corners[m];
      const Eigen::Vector3d a = Eigen::Vector3d(c[0].x, c[0].y, 1).cross(Eigen::Vector3d(c[2].x, c[2].y, 1));
      const Eigen::Vector3d b = Eigen::Vector3d(c[1].x, c[1].y, 1).cross(Eigen::Vector3d(c[3].x, c[3].y, 1));
      const Eigen::Vector3d x = a.cross(b);
      const Eigen::Vector2d centre = x.head<2>() / x.z();
      EXPECT_LT((centre - it->second.first).norm(), kArucoCentreTol)
          << name << " GCP" << ids[m] << " cell " << it->second.second << " px";
    }
    for (const auto& [id, e] : markers)
      if (e.second >= kMinCellPixels) {
        ++must_find;
        found_of_must += detected.count(id) ? 1 : 0;
      }
  }
  EXPECT_GT(must_find, 0);
  EXPECT_GE(double(found_of_must), kMinDetectionRate * must_find)
      << found_of_must << " of " << must_find << " well-imaged markers detected (" << found << " in all)";
}

// ---- internal API: the renderer agrees with the camera model ------------------------

SyntheticExcavationOptions tiny_options() {
  auto o = SyntheticExcavationOptions::preset(SyntheticExcavationOptions::Size::small);
  o.site.stages = 2;
  o.photos.per_layer = 3;
  o.photos.width = 320;
  o.photos.height = 214;
  o.render.texel = 0.005;  // coarse: these tests check geometry, not texture
  return o;
}

TEST(SyntheticRender, ASurfacePointAppearsWhereTheCameraProjectsIt) {
  const auto o = tiny_options();
  const synthetic::Scene scene(o);
  const int layer = scene.layers() - 1;  // the deepest floor: trench sides all around
  const synthetic::Lighting light;
  const synthetic::LayerTexture texture(scene, layer, light, o.render.texel);
  // A point on the floor, off the trench centre, not on a stone.
  const double x = scene.trench_x0() + 0.45 * o.site.trench_size_e, y = scene.trench_y0() + 0.3 * o.site.trench_size_n;
  const Eigen::Vector3d point(x, y, scene.surface(layer).sample(x, y));
  synthetic::RenderSettings settings;
  settings.edge_samples = 0;
  // Blue: no soil, stone or grass colour comes near it.
  settings.spot = synthetic::RenderSettings::Spot{{x, y}, 0.015, {0.02f, 0.02f, 0.9f}};
  Intrinsics k{640, 427, 560, 560, 331.7, 209.2, -0.08, 0.02};
  for (const Eigen::Vector3d& eye : {Eigen::Vector3d(x + 0.2, y - 0.1, point.z() + 1.8),
                                     Eigen::Vector3d(x - 0.6, scene.trench_y0() - 0.5, point.z() + 2.0)}) {
    const Camera cam{k, Pose::look_at(eye, point + Eigen::Vector3d(0.1, 0.05, 0))};
    const auto expected = cam.project(point);
    ASSERT_TRUE(expected.has_value());
    const auto img = synthetic::render_view(scene, layer, texture, light, cam, settings);
    double su = 0, sv = 0, sw = 0;
    for (int v = 0; v < img.height; ++v)
      for (int u = 0; u < img.width; ++u) {
        const float* p = &img.rgb[3 * (std::size_t(v) * std::size_t(img.width) + std::size_t(u))];
        // Weight: how much bluer than anything else in the scene the pixel is.
        const double w = std::max(0.0, double(p[2]) - 2.0 * double(std::max(p[0], p[1])));
        su += w * u;
        sv += w * v;
        sw += w;
      }
    ASSERT_GT(sw, 0) << "the spot is not visible";
    EXPECT_NEAR(su / sw, expected->x(), kSpotTol);
    EXPECT_NEAR(sv / sw, expected->y(), kSpotTol);
  }
}

TEST(SyntheticRender, TrenchSidesHideTheFloorBehindThem) {
  const auto o = tiny_options();
  const synthetic::Scene scene(o);
  const int layer = scene.layers() - 1;
  // A floor point 5 cm inside the north side, seen from a low eye 1 m north of the trench.
  const double x = 0.5 * (scene.trench_x0() + scene.trench_x1()), y = scene.trench_y1() - 0.05;
  const Eigen::Vector3d point(x, y, scene.surface(layer).sample(x, y));
  const Eigen::Vector3d low(x, scene.trench_y1() + 1.0, scene.ground_smooth(x, scene.trench_y1() + 1.0) + 0.4);
  const Eigen::Vector3d high(x, y - 0.3, point.z() + 1.8);
  const auto hidden = synthetic::cast_ray(scene, layer, low, (point - low).normalized());
  EXPECT_LT(hidden.t, (point - low).norm() - kOcclusionMargin);
  const auto seen = synthetic::cast_ray(scene, layer, high, (point - high).normalized());
  EXPECT_NEAR(seen.t, (point - high).norm(), 1e-4);
}

// ---- simulated laser scans -----------------------------------------------------------
// The scan's range noise, and the bounds its residuals must meet over a few thousand
// points: the mean within 4 standard errors, the sample sigma within 15 %.
constexpr double kScanSigma = 0.003;  // metres
constexpr double kScanSigmaRelTol = 0.15;
// The noise-free point lies on the bilinear height field (float32 heights ~1 m:
// 0.1 um; the ray marcher's root refinement is finer than this).
constexpr double kOnSurfaceTol = 2e-4;  // metres
// A line of sight grazing the trench edge may touch the surface by rounding.
constexpr double kSightlineSlack = 1e-3;  // metres
// The ray caster (render.cpp, shared with the photos) tests each 4-5 mm cell at its
// entry and exit: a ray that grazes a crest inside one cell (a stone's edge) and
// leaves it above may pass it. A few such rays in ten thousand.
constexpr double kMaxGrazingShare = 0.001;
// A floor point counts as hidden from the station when its line of sight passes this
// far below the surface somewhere (not just grazing an edge).
constexpr double kDeepShadow = 0.02;  // metres
// Next to a near occluder (a stone's foot) a point 2 cm deep in shadow may have a
// visible neighbour within 5 mm: so few hidden points have a scanned one that close.
constexpr double kMaxHiddenNearScanned = 0.01;

// How far below the surface the straight line from `from` to `to` passes at worst
// (metres, > 0 when it does; the last `skip` metres before `to` are not looked at).
double sightline_depth(const synthetic::HeightGrid& g, const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                       double skip) {
  const double len = (to - from).norm();
  double worst = -1;
  for (double t = 0.02; t < len - skip; t += 0.0025) {
    const Eigen::Vector3d p = from + (to - from) * (t / len);
    if (g.contains(p.x(), p.y())) worst = std::max(worst, g.sample(p.x(), p.y()) - p.z());
  }
  return worst;
}

TEST(SyntheticScan, RangesMatchTheTruthWithinTheirNoiseAndHiddenGroundIsNotScanned) {
  auto o = tiny_options();
  o.scans.enabled = true;
  o.scans.step_mrad = 6;  // coarse: geometry, not density, is checked here
  o.scans.sigma_m = kScanSigma;
  const synthetic::Scene scene(o);
  const int layer = scene.layers() - 1;  // the deepest floor: the trench sides shade their foot
  const auto& grid = scene.surface(layer);
  const auto stations = synthetic::plan_scan_stations(scene, layer, o.seed);
  ASSERT_EQ(stations.size(), 3u);
  const synthetic::ScanStation& st = stations[0];  // south of the trench
  EXPECT_LT(st.origin.y(), scene.trench_y0());
  EXPECT_NEAR(st.origin.z() - grid.sample(st.origin.x(), st.origin.y()), o.scans.height_m, 1e-9);
  const Eigen::Matrix4d pose = st.scanner_to_site();
  EXPECT_NEAR(pose(2, 2), 1.0, 1e-12);  // a rotation about the vertical only
  const Eigen::Matrix3d rotation = pose.topLeftCorner<3, 3>();
  EXPECT_NEAR(rotation.determinant(), 1.0, 1e-12);

  const synthetic::SimulatedScan scan = synthetic::simulate_scan(scene, layer, st, 11);
  ASSERT_GT(scan.points.size(), 5000u);
  ASSERT_EQ(scan.intensity.size(), scan.points.size());
  const Eigen::Matrix3d& R = rotation;
  double sum = 0, sum2 = 0;
  std::size_t off_surface = 0, blocked = 0;
  std::map<std::pair<int, int>, std::vector<Eigen::Vector3d>> scanned;  // 1 cm XY cell -> true points there
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Eigen::Vector3d p = R * scan.points[i].cast<double>() + st.origin;  // into the site frame
    const Eigen::Vector3d dir = (p - st.origin).normalized();
    const double range = (p - st.origin).norm();
    const double e = range - scan.true_range[i];
    sum += e;
    sum2 += e * e;
    const Eigen::Vector3d truth = st.origin + double(scan.true_range[i]) * dir;
    if (std::abs(truth.z() - grid.sample(truth.x(), truth.y())) > kOnSurfaceTol) ++off_surface;
    if (sightline_depth(grid, st.origin, truth, 0.01) > kSightlineSlack) ++blocked;
    scanned[{int(std::floor(truth.x() / 0.01)), int(std::floor(truth.y() / 0.01))}].push_back(truth);
    EXPECT_GE(scan.intensity[i], 0.f);
    EXPECT_LE(scan.intensity[i], 1.f);
  }
  const double n = double(scan.points.size());
  const double mean = sum / n, sigma = std::sqrt(sum2 / n - mean * mean);
  EXPECT_LT(std::abs(mean), 4 * kScanSigma / std::sqrt(n)) << "range bias " << mean;
  EXPECT_NEAR(sigma, kScanSigma, kScanSigmaRelTol * kScanSigma);
  EXPECT_EQ(off_surface, 0u) << "noise-free points off the truth surface";
  EXPECT_LT(double(blocked), kMaxGrazingShare * n) << "points whose line of sight passes through the ground";

  // Floor points deep in the shadow of the trench side: none of them was scanned.
  std::size_t hidden = 0, hidden_scanned = 0;
  for (double x = scene.trench_x0() + 0.05; x < scene.trench_x1() - 0.05; x += 0.02)
    for (double y = scene.trench_y0() + 0.01; y < scene.trench_y1() - 0.05; y += 0.02) {
      const Eigen::Vector3d q(x, y, grid.sample(x, y));
      if (grid.normal(x, y).z() < 0.9 || sightline_depth(grid, st.origin, q, 0.05) < kDeepShadow) continue;
      ++hidden;
      for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
          const auto it = scanned.find({int(std::floor(x / 0.01)) + di, int(std::floor(y / 0.01)) + dj});
          if (it == scanned.end()) continue;
          for (const Eigen::Vector3d& p : it->second)
            if ((p - q).norm() < 0.005) ++hidden_scanned;
        }
    }
  EXPECT_GT(hidden, 50u) << "the trench side should shade part of the floor";
  EXPECT_LT(double(hidden_scanned), kMaxHiddenNearScanned * double(hidden)) << hidden_scanned << " of " << hidden;
}

// ---- simulated depth camera -----------------------------------------------------------
// Depth errors normalised by their noise (k z^2 and the millimetre rounding) over
// thousands of pixels: mean within 4 standard errors, spread within 15 % of 1.
constexpr double kDepthSpreadRelTol = 0.15;
// The recorded poses drift: after a loop of 1 mrad and 2 mm a step, plus the bias,
// the last camera is centimetres off (and the first exact).
constexpr double kMinRecordedDrift = 0.01;  // metres

TEST(SyntheticDepth, FramesMatchTheSurfaceWithinTheirNoiseAndRecordedPosesDrift) {
  auto o = tiny_options();
  o.depth.enabled = true;
  o.depth.frames = 12;
  o.depth.width = 160;  // a quarter of the pixels each way: the geometry, not the density, is checked
  o.depth.height = 120;
  o.depth.focal_px = 131.25;
  const synthetic::Scene scene(o);
  const int layer = scene.layers() - 1;
  const auto plan = synthetic::plan_depth_sequence(scene, layer, o.seed);
  ASSERT_EQ(plan.size(), 12u);
  EXPECT_EQ(plan[0].recorded_pose.matrix(), plan[0].true_pose.matrix());
  EXPECT_GT((plan.back().recorded_pose.translation() - plan.back().true_pose.translation()).norm(), kMinRecordedDrift);
  // Each camera outside the trench, looking down into it.
  for (const auto& f : plan) {
    const Eigen::Vector3d c = f.true_pose.translation();
    EXPECT_TRUE(c.x() < scene.trench_x0() || c.x() > scene.trench_x1() || c.y() < scene.trench_y0() ||
                c.y() > scene.trench_y1());
    EXPECT_LT(f.true_pose.linear().col(2).z(), -0.3) << "optical axis not pointing down";
  }
  const Eigen::Isometry3d& pose = plan[3].true_pose;
  const synthetic::DepthFrame frame = synthetic::render_depth_frame(scene, layer, pose, 5);
  ASSERT_GT(frame.valid, 10000);
  const double f = o.depth.focal_px, cx = 0.5 * (o.depth.width - 1), cy = 0.5 * (o.depth.height - 1);
  double sum = 0, sum2 = 0;
  int n = 0;
  for (int v = 0; v < o.depth.height; ++v)
    for (int u = 0; u < o.depth.width; ++u) {
      const std::uint16_t d = frame.depth_mm[std::size_t(v) * std::size_t(o.depth.width) + std::size_t(u)];
      if (d == 0) continue;
      const Eigen::Vector3d ray((u - cx) / f, (v - cy) / f, 1.0);
      const auto hit = synthetic::cast_ray(scene, layer, pose.translation(), pose.linear() * ray.normalized());
      ASSERT_NE(hit.where, synthetic::RayHit::Where::sky);
      const double z = hit.t / ray.norm();
      const double sigma = std::hypot(o.depth.noise_k * z * z, 0.001 / std::sqrt(12.0));
      const double e = (0.001 * d - z) / sigma;
      sum += e;
      sum2 += e * e;
      ++n;
    }
  const double mean = sum / n, spread = std::sqrt(sum2 / n - mean * mean);
  EXPECT_LT(std::abs(mean), 4 / std::sqrt(double(n))) << "normalised depth bias";
  EXPECT_NEAR(spread, 1.0, kDepthSpreadRelTol);
}

TEST(SyntheticOptions, InvalidOptionsNameTheField) {
  auto o = tiny_options();
  o.photos.width = 10;
  try {
    o.validate();
    FAIL() << "accepted a 10 px width";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("photos.width"), std::string::npos) << e.what();
  }
  o = tiny_options();
  o.site.check_markers = o.site.markers;
  EXPECT_THROW(o.validate(), InputError);
}

TEST(SyntheticGenerate, SameSeedSameBytesOtherSeedOtherScene) {
  test::ScratchDir scratch("determinism");
  auto o = tiny_options();
  o.site.stages = 1;
  o.seed = 11;
  generate_excavation(o, scratch / "a");
  generate_excavation(o, scratch / "b");
  EXPECT_EQ(test::tree_fingerprint(scratch / "a"), test::tree_fingerprint(scratch / "b"));
  o.seed = 12;
  generate_excavation(o, scratch / "c");
  EXPECT_NE(test::read_text(scratch / "a" / "truth" / "units.csv"), test::read_text(scratch / "c" / "truth" / "units.csv"));
  // A non-empty folder is refused and left as it was.
  const auto before = test::tree_fingerprint(scratch / "a");
  EXPECT_THROW(generate_excavation(o, scratch / "a"), InputError);
  EXPECT_EQ(test::tree_fingerprint(scratch / "a"), before);
}

TEST(SyntheticCli, SynthCommandWritesADatasetAndRejectsBadOptions) {
  test::ScratchDir scratch("cli");
  const auto ok = test::run_strata({"synth", (scratch / "dig").string(), "--size", "small", "--stages", "1",
                                    "--photos", "3", "--width", "320", "--seed", "5"});
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(fs::exists(scratch / "dig" / "site.json"));
  EXPECT_TRUE(fs::exists(scratch / "dig" / "photos" / "L2" / "L2_0003.jpg"));
  const auto bad = test::run_strata({"synth", (scratch / "bad").string(), "--photos", "1"});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("photos.per_layer"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(scratch / "bad"));
}

}  // namespace
}  // namespace strata
