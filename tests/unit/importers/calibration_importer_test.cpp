// importer.calibration.opencv / .metashape: values land in strata's conventions,
// malformed files are refused with one line naming the stage, file and element, and a
// refused import leaves the project unchanged.
#include "core/error.hpp"
#include "importer_fixture.hpp"
#include "importers/calibration/calibration_importer.hpp"
#include "importers/photos/photo_importer.hpp"
#include "project/calibration_records.hpp"

#include <opencv2/core/persistence.hpp>

#include <cmath>
#include <functional>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::ImporterTest;

// Pixel positions computed two ways (strata's model vs Metashape's formula written out
// here) agree to rounding: the conversion itself is exact.
constexpr double kProjectionTolerancePx = 1e-9;
// The fixture's photos (make_photo) are 160 x 120 px.
constexpr int kWidth = 160;
constexpr int kHeight = 120;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

fs::path write_opencv(const fs::path& path, int width, int height, const cv::Mat& K, const cv::Mat& D,
                      bool fisheye) {
  fs::create_directories(path.parent_path());
  cv::FileStorage out(path.string(), cv::FileStorage::WRITE);
  out << "image_width" << width << "image_height" << height;
  if (fisheye) out << "fisheye_model" << 1;
  out << "camera_matrix" << K << "distortion_coefficients" << D;
  out.release();
  return path;
}

cv::Mat camera_matrix(double fx, double fy, double cx, double cy) {
  return (cv::Mat_<double>(3, 3) << fx, 0, cx, 0, fy, cy, 0, 0, 1);
}

// Metashape's frame camera (manual, appendix "Camera models"), pixels from the top-left
// corner of the image, written out independently of the importer.
Eigen::Vector2d metashape_frame_pixel(const Eigen::Vector2d& xn, int w, int h, double f, double cx, double cy,
                                      double b1, const double K[3], double P1, double P2) {
  const double x = xn.x(), y = xn.y(), r2 = x * x + y * y;
  const double radial = 1 + K[0] * r2 + K[1] * r2 * r2 + K[2] * r2 * r2 * r2;
  const double xd = x * radial + P1 * (r2 + 2 * x * x) + 2 * P2 * x * y;
  const double yd = y * radial + P2 * (r2 + 2 * y * y) + 2 * P1 * x * y;
  return {w * 0.5 + cx + xd * f + xd * b1, h * 0.5 + cy + yd * f};
}

TEST_F(ImporterTest, OpenCvYamlBrownValuesLandExactly) {
  const cv::Mat D = (cv::Mat_<double>(1, 5) << -0.12, 0.05, 0.0011, -0.0023, 0.013);
  const auto file = write_opencv(scratch() / "cal.yml", kWidth, kHeight, camera_matrix(151.25, 150.5, 80.3, 59.6),
                                 D, false);
  const CalibrationFile c = read_calibration_file(file);
  EXPECT_EQ(c.format, "opencv");
  const Intrinsics& k = c.intrinsics;
  EXPECT_EQ(k.model, CameraModel::brown);
  EXPECT_EQ(k.width, kWidth);
  EXPECT_EQ(k.height, kHeight);
  EXPECT_DOUBLE_EQ(k.fx, 151.25);
  EXPECT_DOUBLE_EQ(k.fy, 150.5);
  EXPECT_DOUBLE_EQ(k.cx, 80.3);  // OpenCV's pixel convention is strata's: no shift
  EXPECT_DOUBLE_EQ(k.cy, 59.6);
  EXPECT_DOUBLE_EQ(k.k1, -0.12);
  EXPECT_DOUBLE_EQ(k.k2, 0.05);
  EXPECT_DOUBLE_EQ(k.p1, 0.0011);  // OpenCV order k1 k2 p1 p2 k3
  EXPECT_DOUBLE_EQ(k.p2, -0.0023);
  EXPECT_DOUBLE_EQ(k.k3, 0.013);
}

TEST_F(ImporterTest, OpenCvXmlFisheyeAndFourCoefficientForms) {
  const cv::Mat D4 = (cv::Mat_<double>(4, 1) << 0.02, -0.011, 0.004, -0.0007);
  auto c = read_calibration_file(
      write_opencv(scratch() / "fish.xml", kWidth, kHeight, camera_matrix(70, 70, 79.5, 59.5), D4, true));
  EXPECT_EQ(c.intrinsics.model, CameraModel::fisheye);
  EXPECT_DOUBLE_EQ(c.intrinsics.k1, 0.02);
  EXPECT_DOUBLE_EQ(c.intrinsics.k2, -0.011);
  EXPECT_DOUBLE_EQ(c.intrinsics.k3, 0.004);
  EXPECT_DOUBLE_EQ(c.intrinsics.k4, -0.0007);
  EXPECT_EQ(c.intrinsics.p1, 0.0);
  // The same four numbers without the fisheye flag are OpenCV's k1 k2 p1 p2.
  c = read_calibration_file(
      write_opencv(scratch() / "four.xml", kWidth, kHeight, camera_matrix(150, 150, 79.5, 59.5), D4, false));
  EXPECT_EQ(c.intrinsics.model, CameraModel::brown);
  EXPECT_DOUBLE_EQ(c.intrinsics.p1, 0.004);
  EXPECT_DOUBLE_EQ(c.intrinsics.p2, -0.0007);
  EXPECT_EQ(c.intrinsics.k3, 0.0);
  // Only k1, k2 in use: the radial model.
  const cv::Mat D5 = (cv::Mat_<double>(1, 5) << -0.2, 0.07, 0, 0, 0);
  c = read_calibration_file(
      write_opencv(scratch() / "radial.yml", kWidth, kHeight, camera_matrix(150, 150, 79.5, 59.5), D5, false));
  EXPECT_EQ(c.intrinsics.model, CameraModel::radial);
  EXPECT_DOUBLE_EQ(c.intrinsics.k1, -0.2);
}

TEST_F(ImporterTest, MalformedOpenCvFilesNameTheElement) {
  const auto K = camera_matrix(150, 150, 79.5, 59.5);
  const cv::Mat D = (cv::Mat_<double>(1, 5) << -0.2, 0.07, 0, 0, 0);
  test::write_text(scratch() / "syntax.yml", "%YAML:1.0\n---\nimage_width: 160\nimage_height 120\n");
  std::string e = error_of([&] { read_calibration_file(scratch() / "syntax.yml"); });
  EXPECT_EQ(e, "importer.calibration.opencv: " + (scratch() / "syntax.yml").string() + ":4: Missing ':'");
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;

  test::write_text(scratch() / "nok.yml", "%YAML:1.0\n---\nimage_width: 160\nimage_height: 120\n");
  e = error_of([&] { read_calibration_file(scratch() / "nok.yml"); });
  EXPECT_NE(e.find("nok.yml: <camera_matrix> is missing"), std::string::npos) << e;

  const cv::Mat skewed = (cv::Mat_<double>(3, 3) << 150, 0.3, 79.5, 0, 150, 59.5, 0, 0, 1);
  e = error_of([&] { read_calibration_file(write_opencv(scratch() / "skew.yml", kWidth, kHeight, skewed, D, false)); });
  EXPECT_NE(e.find("<camera_matrix> has skew 0.3"), std::string::npos) << e;

  const cv::Mat D8 = (cv::Mat_<double>(1, 8) << -0.2, 0.07, 0, 0, 0, 0.01, 0, 0);
  e = error_of([&] { read_calibration_file(write_opencv(scratch() / "rational.yml", kWidth, kHeight, K, D8, false)); });
  EXPECT_NE(e.find("<distortion_coefficients> k4 = 0.01"), std::string::npos) << e;

  // A matrix header larger than its data (OpenCV allocated the 16 GB it declares
  // before reading the data; found by fuzzing, tests/fuzz/corpus/calibration).
  test::write_text(scratch() / "huge.yml",
                   "%YAML:1.0\n---\nimage_width: 160\nimage_height: 120\ncamera_matrix: !!opencv-matrix\n"
                   "   rows: 3\n   cols: 2147483647\n   dt: d\n   data: [ 150., 0., 79.5 ]\n");
  e = error_of([&] { read_calibration_file(scratch() / "huge.yml"); });
  EXPECT_NE(e.find("huge.yml: <camera_matrix> declares 6442450941 values but holds 3"), std::string::npos) << e;
  test::write_text(scratch() / "text.yml",
                   "%YAML:1.0\n---\nimage_width: 160\nimage_height: 120\ncamera_matrix: !!opencv-matrix\n"
                   "   rows: 3\n   cols: three\n   dt: d\n   data: [ 150., 0., 79.5 ]\n");
  e = error_of([&] { read_calibration_file(scratch() / "text.yml"); });
  EXPECT_NE(e.find("text.yml: <camera_matrix> has a size that is not a whole number"), std::string::npos) << e;

  // A NUL byte inside the document (OpenCV 4.6's XML parser crashed on it).
  test::write_text(scratch() / "nul.xml", std::string("<?xml version=\0\0\"1\"?><opencv_storage/>\n", 39));
  e = error_of([&] { read_calibration_file(scratch() / "nul.xml"); });
  EXPECT_NE(e.find("nul.xml: holds NUL bytes: not a text file"), std::string::npos) << e;

  const cv::Mat D3 = (cv::Mat_<double>(1, 3) << -0.2, 0.07, 0);
  e = error_of([&] { read_calibration_file(write_opencv(scratch() / "three.yml", kWidth, kHeight, K, D3, false)); });
  EXPECT_NE(e.find("<distortion_coefficients> has 3 values"), std::string::npos) << e;

  e = error_of([&] {
    read_calibration_file(write_opencv(scratch() / "pp.yml", kWidth, kHeight, camera_matrix(150, 150, 400, 59.5), D, false));
  });
  EXPECT_NE(e.find("importer.calibration.opencv: " + (scratch() / "pp.yml").string() +
                   ": principal point cx = 400 px is outside"),
            std::string::npos)
      << e;
  e = error_of([&] {
    read_calibration_file(write_opencv(scratch() / "f.yml", kWidth, kHeight, camera_matrix(-150, 150, 79.5, 59.5), D, false));
  });
  EXPECT_NE(e.find("focal length fx = -150 px must be positive"), std::string::npos) << e;
}

std::string metashape_xml(const std::string& projection, const std::string& body) {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<calibration>\n  <projection>" + projection +
         "</projection>\n  <width>160</width>\n  <height>120</height>\n" + body +
         "  <date>2026-11-30T10:00:00Z</date>\n</calibration>\n";
}

TEST_F(ImporterTest, MetashapeFrameConventionsAreConverted) {
  const double f = 150, cx = 1.5, cy = -2.25, b1 = 0.75;
  const double K[3] = {-0.11, 0.06, -0.012};
  const double P1 = 0.0012, P2 = -0.0021;
  const auto file = scratch() / "ms.xml";
  test::write_text(file, metashape_xml("frame", fmt::format("  <f>{}</f>\n  <cx>{}</cx>\n  <cy>{}</cy>\n  <b1>{}</b1>\n"
                                                            "  <b2>0</b2>\n  <k1>{}</k1>\n  <k2>{}</k2>\n  <k3>{}</k3>\n"
                                                            "  <k4>0</k4>\n  <p1>{}</p1>\n  <p2>{}</p2>\n",
                                                            f, cx, cy, b1, K[0], K[1], K[2], P1, P2)));
  const CalibrationFile c = read_calibration_file(file);
  EXPECT_EQ(c.format, "metashape");
  const Intrinsics& k = c.intrinsics;
  EXPECT_EQ(k.model, CameraModel::brown);
  EXPECT_DOUBLE_EQ(k.fx, f + b1);
  EXPECT_DOUBLE_EQ(k.fy, f);
  EXPECT_DOUBLE_EQ(k.cx, kWidth / 2.0 + cx - 0.5);   // offset from the centre, corner origin
  EXPECT_DOUBLE_EQ(k.cy, kHeight / 2.0 + cy - 0.5);
  EXPECT_DOUBLE_EQ(k.p1, P2);  // named the other way round
  EXPECT_DOUBLE_EQ(k.p2, P1);
  EXPECT_DOUBLE_EQ(k.k3, K[2]);
  EXPECT_FALSE(c.notes.empty());
  // The strongest check: both models put every point at the same place (strata's
  // pixel = Metashape's corner-origin pixel - 0.5).
  for (const Eigen::Vector2d& xn : {Eigen::Vector2d(0.3, -0.2), Eigen::Vector2d(-0.45, 0.38), Eigen::Vector2d(0.05, 0.5)}) {
    const Eigen::Vector2d ours = k.to_pixel(xn);
    const Eigen::Vector2d theirs = metashape_frame_pixel(xn, kWidth, kHeight, f, cx, cy, b1, K, P1, P2);
    EXPECT_NEAR(ours.x(), theirs.x() - 0.5, kProjectionTolerancePx);
    EXPECT_NEAR(ours.y(), theirs.y() - 0.5, kProjectionTolerancePx);
  }
}

TEST_F(ImporterTest, MetashapeFisheyeAndCamerasXmlForm) {
  test::write_text(scratch() / "fish.xml",
                   metashape_xml("fisheye", "  <f>70</f>\n  <k1>0.02</k1>\n  <k2>-0.01</k2>\n  <k3>0.003</k3>\n"
                                            "  <k4>-0.0005</k4>\n"));
  auto c = read_calibration_file(scratch() / "fish.xml");
  EXPECT_EQ(c.intrinsics.model, CameraModel::fisheye);
  EXPECT_DOUBLE_EQ(c.intrinsics.fx, 70);
  EXPECT_DOUBLE_EQ(c.intrinsics.cx, 79.5);  // cx omitted = the image centre
  EXPECT_DOUBLE_EQ(c.intrinsics.k4, -0.0005);
  // A sensor's calibrations in a cameras.xml export: the adjusted one is taken.
  test::write_text(scratch() / "cameras.xml",
                   "<document><chunk><sensors><sensor id=\"0\">\n"
                   "<calibration type=\"frame\" class=\"initial\"><resolution width=\"160\" height=\"120\"/>"
                   "<f>140</f></calibration>\n"
                   "<calibration type=\"frame\" class=\"adjusted\"><resolution width=\"160\" height=\"120\"/>"
                   "<f>152.5</f><cx>-1</cx><cy>2</cy><k1>-0.1</k1></calibration>\n"
                   "</sensor></sensors></chunk></document>\n");
  c = read_calibration_file(scratch() / "cameras.xml");
  EXPECT_EQ(c.intrinsics.model, CameraModel::radial);
  EXPECT_DOUBLE_EQ(c.intrinsics.fx, 152.5);
  EXPECT_DOUBLE_EQ(c.intrinsics.cx, 78.5);
  EXPECT_DOUBLE_EQ(c.intrinsics.cy, 61.5);
  EXPECT_DOUBLE_EQ(c.intrinsics.k1, -0.1);
}

TEST_F(ImporterTest, MalformedMetashapeFilesNameTheElement) {
  const std::string stage = "importer.calibration.metashape: ";
  auto refused = [&](const std::string& name, const std::string& text) {
    test::write_text(scratch() / name, text);
    const std::string e = error_of([&] { read_calibration_file(scratch() / name, CalibrationFormat::metashape); });
    EXPECT_EQ(e.rfind(stage + (scratch() / name).string() + ": ", 0), 0u) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    return e;
  };
  EXPECT_NE(refused("nof.xml", metashape_xml("frame", "  <cx>1</cx>\n")).find("<calibration>/<f> is missing"),
            std::string::npos);
  EXPECT_NE(refused("nan.xml", metashape_xml("frame", "  <f>150</f>\n  <k1>abc</k1>\n"))
                .find("<calibration>/<k1> 'abc' is not a number"),
            std::string::npos);
  EXPECT_NE(refused("skew.xml", metashape_xml("frame", "  <f>150</f>\n  <b2>3</b2>\n")).find("<calibration>/<b2> = 3"),
            std::string::npos);
  EXPECT_NE(refused("k4.xml", metashape_xml("frame", "  <f>150</f>\n  <k4>0.001</k4>\n")).find("<calibration>/<k4>"),
            std::string::npos);
  EXPECT_NE(refused("fp.xml", metashape_xml("fisheye", "  <f>70</f>\n  <p1>0.001</p1>\n")).find("<calibration>/<p1>"),
            std::string::npos);
  EXPECT_NE(refused("sph.xml", metashape_xml("spherical", "  <f>70</f>\n")).find("'spherical' is not supported"),
            std::string::npos);
  EXPECT_NE(refused("broken.xml", "<calibration><f>150</f>\n<width>160</calibration>\n").find("not a valid XML file"),
            std::string::npos);
  EXPECT_NE(refused("none.xml", "<document><chunk/></document>\n").find("no <calibration> element"),
            std::string::npos);
  // An image size beyond int (it was converted unchecked before, undefined behaviour).
  EXPECT_NE(refused("huge.xml", "<calibration><width>4e12</width><height>120</height><f>150</f></calibration>\n")
                .find("<calibration>/<width> 4000000000000 must be a positive whole number of pixels"),
            std::string::npos);
  // A tiny skew (well under a tenth of a pixel at the edge) is dropped with a note.
  test::write_text(scratch() / "tiny.xml", metashape_xml("frame", "  <f>150</f>\n  <b2>0.01</b2>\n"));
  const auto c = read_calibration_file(scratch() / "tiny.xml");
  ASSERT_EQ(c.notes.size(), 1u);
  EXPECT_NE(c.notes[0].find("b2 = 0.01"), std::string::npos);
}

TEST_F(ImporterTest, ImportStoresForTheCameraScalesSameAspectAndRefusesOthers) {
  import_photos(project(), {"L1", false}, {make_photo("a.jpg", 1), make_photo("b.jpg", 2)});
  const auto images = list_images(db());
  ASSERT_TRUE(images[0].camera_id.has_value());
  const std::int64_t camera_id = *images[0].camera_id;
  const cv::Mat D = (cv::Mat_<double>(1, 5) << -0.12, 0.05, 0.0011, -0.0023, 0.013);

  // Calibrated on the full-size 320 x 240 photos; the project holds 160 x 120 copies.
  const auto big = write_opencv(scratch() / "big.yml", 2 * kWidth, 2 * kHeight,
                                camera_matrix(300.5, 301.5, 160.1, 119.3), D, false);
  auto s = import_calibration(project(), {"a.jpg", true, CalibrationFormat::automatic}, big);
  EXPECT_EQ(s.camera_id, camera_id);
  EXPECT_FALSE(s.replaced);
  auto stored = find_calibration(db(), camera_id);
  ASSERT_TRUE(stored.has_value());
  EXPECT_TRUE(stored->fixed);
  EXPECT_EQ(stored->source, "file big.yml (opencv)");
  EXPECT_EQ(stored->intrinsics.width, kWidth);
  EXPECT_DOUBLE_EQ(stored->intrinsics.fx, 300.5 / 2);
  EXPECT_DOUBLE_EQ(stored->intrinsics.fy, 301.5 / 2);
  EXPECT_DOUBLE_EQ(stored->intrinsics.cx, (160.1 + 0.5) / 2 - 0.5);  // pixel corners scale, not centres
  EXPECT_DOUBLE_EQ(stored->intrinsics.cy, (119.3 + 0.5) / 2 - 0.5);
  EXPECT_DOUBLE_EQ(stored->intrinsics.k3, 0.013);  // normalised distortion is size-free
  ASSERT_FALSE(s.notes.empty());
  EXPECT_EQ(s.notes.back().rfind("scaled from 320x240", 0), 0u) << s.notes.back();

  // Another aspect ratio (here: rotated) and a malformed file: refused, nothing changes.
  const std::string before = dump();
  const auto rotated = write_opencv(scratch() / "rot.yml", kHeight, kWidth, camera_matrix(150, 150, 59.5, 79.5), D, false);
  std::string e = error_of([&] { import_calibration(project(), {std::to_string(camera_id), false, {}}, rotated); });
  EXPECT_NE(e.find("calibrated for 120x160 px photos, but the camera's photos are 160x120 px (rotated"),
            std::string::npos) << e;
  test::write_text(scratch() / "bad.xml", metashape_xml("frame", "  <f>x</f>\n"));
  e = error_of([&] { import_calibration(project(), {"a.jpg", false, {}}, scratch() / "bad.xml"); });
  EXPECT_NE(e.find("<calibration>/<f> 'x' is not a number"), std::string::npos) << e;
  e = error_of([&] { import_calibration(project(), {"nosuch.jpg", false, {}}, big); });
  EXPECT_NE(e.find("camera 'nosuch.jpg': no camera with that id and no photo of that name"), std::string::npos) << e;
  EXPECT_EQ(dump(), before);

  // The same size: stored as read; replaces the earlier one.
  const auto same = write_opencv(scratch() / "same.yml", kWidth, kHeight, camera_matrix(150, 150, 79.5, 59.5), D, false);
  s = import_calibration(project(), {std::to_string(camera_id), false, {}}, same);
  EXPECT_TRUE(s.replaced);
  stored = find_calibration(db(), camera_id);
  EXPECT_FALSE(stored->fixed);
  EXPECT_DOUBLE_EQ(stored->intrinsics.fx, 150);
  EXPECT_EQ(list_calibrations(db()).size(), 1u);
}

}  // namespace
}  // namespace strata
