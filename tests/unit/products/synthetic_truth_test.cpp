// Orthophotos of the synthetic excavation (strata synth, small preset, 2 layers)
// from the true cameras and the true surface: every marker that ArUco finds in the
// orthophoto lies within 2 pixels of its surveyed (true) position.
// Set STRATA_PRODUCTS_KEEP=DIR to keep the orthophotos and DTMs for inspection.
#include "core/error.hpp"
#include "crs/crs.hpp"
#include "products/ortho_markers.hpp"
#include "products/orthophoto.hpp"
#include "exporters/raster/geotiff.hpp"
#include "importers/raster/geotiff.hpp"
#include "support/test_support.hpp"
#include "synthetic/synthetic.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

namespace fs = std::filesystem;

namespace strata {
namespace {

const Eigen::Vector3d kOrigin(734000.0, 4174000.0, 1450.0);  // synth default site origin
constexpr double kOrthoCell = 0.0025;      // metres: 60 px per 15 cm target, enough for ArUco
constexpr double kMarkerTolerancePx = 2.0; // the orthophoto acceptance (docs/products.md)

std::vector<std::vector<std::string>> read_csv(const fs::path& p) {
  std::ifstream f(p);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  std::getline(f, line);  // header
  while (std::getline(f, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    if (!cells.empty()) rows.push_back(cells);
  }
  return rows;
}

// Bilinear resampling of a DTM onto a finer grid `margin` metres larger on every
// side. The generator's truth rasters cover 0.75 m around the trench, the markers
// included; beyond them the ground is the plane through the markers (the synthetic
// ground is smooth there and the targets lie on it).
Dtm resample(const Dtm& src, double cell, double margin, const Eigen::Vector3d& plane,
             const std::vector<Eigen::Vector3d>& markers) {
  Dtm d;
  d.grid.x_min = src.grid.x_min - margin;
  d.grid.y_max = src.grid.y_max + margin;
  d.grid.cell = cell;
  d.grid.width = int(std::floor((src.grid.x_max() - src.grid.x_min + 2 * margin) / cell));
  d.grid.height = int(std::floor((src.grid.y_max - src.grid.y_min() + 2 * margin) / cell));
  d.z.assign(d.grid.cells(), std::nanf(""));
  for (int r = 0; r < d.grid.height; ++r)
    for (int c = 0; c < d.grid.width; ++c) {
      // Plane plus inverse-distance (power 4) interpolation of the markers'
      // residuals, so the ground passes through every target exactly.
      const double x = d.grid.x_centre(c), y = d.grid.y_centre(r);
      const double p = plane.x() * x + plane.y() * y + plane.z();
      double ws = 0, wr = 0;
      for (const auto& m : markers) {
        const double d2 = (m.head<2>() - Eigen::Vector2d(x, y)).squaredNorm() + 1e-8;
        const double w = 1.0 / (d2 * d2);
        ws += w;
        wr += w * (m.z() - (plane.x() * m.x() + plane.y() * m.y() + plane.z()));
      }
      d.z[d.grid.index(c, r)] = float(p + wr / ws);
    }
  for (int r = 0; r < d.grid.height; ++r) {
    for (int c = 0; c < d.grid.width; ++c) {
      const double fx = (d.grid.x_centre(c) - src.grid.x_min) / src.grid.cell - 0.5;
      const double fy = (src.grid.y_max - d.grid.y_centre(r)) / src.grid.cell - 0.5;
      const int c0 = int(std::floor(fx)), r0 = int(std::floor(fy));
      if (c0 < 0 || r0 < 0 || c0 + 1 >= src.grid.width || r0 + 1 >= src.grid.height) continue;
      const double ax = fx - c0, ay = fy - r0;
      d.z[d.grid.index(c, r)] = float((1 - ay) * ((1 - ax) * src.at(c0, r0) + ax * src.at(c0 + 1, r0)) +
                                      ay * ((1 - ax) * src.at(c0, r0 + 1) + ax * src.at(c0 + 1, r0 + 1)));
    }
  }
  return d;
}

class SyntheticTruth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::ScratchDir("products_synthetic_truth");
    auto o = SyntheticExcavationOptions::preset(SyntheticExcavationOptions::Size::small);
    o.site.stages = 1;  // two layers keep the test short
    o.photos.per_layer = 12;  // the photo size below is read back as the cameras' size
    o.photos.width = 800;
    o.photos.height = 533;
    generate_excavation(o, dir_->path() / "data");
  }
  static void TearDownTestSuite() { delete dir_; }
  static test::ScratchDir* dir_;
};
test::ScratchDir* SyntheticTruth::dir_ = nullptr;

TEST_F(SyntheticTruth, MarkersLandWithinTwoPixels) {
  const fs::path data = dir_->path() / "data";
  std::map<int, Eigen::Vector2d> truth;  // ArUco id -> E, N
  for (const auto& row : read_csv(data / "truth" / "markers.csv")) {
    truth[std::stoi(row[0].substr(3))] = {std::stod(row[1]), std::stod(row[2])};
  }
  ASSERT_GE(truth.size(), 6u);
  // Least-squares plane z = a x + b y + c through the markers, site frame.
  std::vector<Eigen::Vector3d> markers;
  Eigen::MatrixXd A(0, 3);
  Eigen::VectorXd b(0);
  for (const auto& row : read_csv(data / "truth" / "markers.csv")) {
    A.conservativeResize(A.rows() + 1, 3);
    b.conservativeResize(b.rows() + 1);
    A.row(A.rows() - 1) << std::stod(row[1]) - kOrigin.x(), std::stod(row[2]) - kOrigin.y(), 1.0;
    b(b.rows() - 1) = std::stod(row[3]) - kOrigin.z();
    markers.push_back(A.row(A.rows() - 1).transpose());
    markers.back().z() = b(b.rows() - 1);
  }
  const Eigen::Vector3d plane = A.colPivHouseholderQr().solve(b);
  const RasterGeoreference geo{describe_crs("EPSG:32636").wkt, kOrigin};
  int checked = 0;
  for (const std::string layer : {"L1", "L2"}) {
    const Dtm truth_dtm = convert_raster<float>(read_height_geotiff(data / "truth" / layer / "surface.tif", kOrigin));
    const Dtm dtm = resample(truth_dtm, kOrthoCell, 0.5, plane, markers);
    std::vector<OrthoView> views;
    for (const auto& row : read_csv(data / "truth" / layer / "cameras.csv")) {
      OrthoView v;
      v.name = row[0];
      Intrinsics& K = v.camera.intrinsics;
      K.width = 800;
      K.height = 533;
      K.fx = std::stod(row[1]);
      K.fy = std::stod(row[2]);
      K.cx = std::stod(row[3]);
      K.cy = std::stod(row[4]);
      K.k1 = std::stod(row[5]);
      K.k2 = std::stod(row[6]);
      Eigen::Matrix3d R;
      for (int k = 0; k < 9; ++k) R(k / 3, k % 3) = std::stod(row[std::size_t(7 + k)]);
      const Eigen::Vector3d C(std::stod(row[16]) - kOrigin.x(), std::stod(row[17]) - kOrigin.y(),
                              std::stod(row[18]) - kOrigin.z());
      v.camera.pose = Pose::from_centre(R, C);
      v.photo = data / "photos" / layer / row[0];
      views.push_back(v);
    }
    OrthoSummary s;
    const RgbaRaster ortho = build_orthophoto(dtm, views, OrthoOptions{}, &s);
    EXPECT_GT(s.coverage, 0.8) << layer;
    if (const char* keep = std::getenv("STRATA_PRODUCTS_KEEP")) {
      fs::create_directories(keep);
      write_rgba_geotiff(fs::path(keep) / (layer + "_ortho.tif"), ortho, geo);
      write_dtm_geotiff(fs::path(keep) / (layer + "_dtm.tif"), truth_dtm, geo);
    }
    // The product's own check: targets detected in the orthophoto against the
    // true marker positions (site frame).
    std::vector<SurveyedMarker> survey;
    for (const auto& [id, en] : truth) {
      survey.push_back({"GCP" + std::to_string(id), Eigen::Vector3d(en.x() - kOrigin.x(), en.y() - kOrigin.y(), 0),
                        "control"});
    }
    const OrthoMarkerCheck check = check_ortho_markers(ortho, survey, OrthoMarkerCheckOptions{});
    for (const OrthoMarkerOffset& m : check.markers) {
      if (m.status != OrthoMarkerStatus::detected) {
        std::printf("%s %s: %s\n", layer.c_str(), m.name.c_str(), to_string(m.status));
        continue;
      }
      EXPECT_LT(m.offset_px, kMarkerTolerancePx) << layer << " " << m.name;
      std::printf("%s %s: %.2f px (%.1f mm)\n", layer.c_str(), m.name.c_str(), m.offset_px, m.offset_m * 1000);
      ++checked;
    }
    EXPECT_EQ(check.over_tolerance, 0) << layer;
    std::printf("%s: coverage %.3f, views used %d/%d, seams %.3f, balance rms %.3f -> %.3f, %.2f s\n",
                layer.c_str(), s.coverage, s.views_used, s.views, s.seam_fraction, s.balance_rms_before,
                s.balance_rms_after, s.seconds);
  }
  EXPECT_GE(checked, 4) << "too few markers detected in the orthophotos";
}

}  // namespace
}  // namespace strata
