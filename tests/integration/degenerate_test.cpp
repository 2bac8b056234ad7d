// Degenerate field data (docs/reliability.md): a layer of one photo,
// too few or collinear markers, markers no photo sees, the same photo in two layers,
// black or blurred photos, several cameras in one layer, and a layer whose photos form
// two groups (some of another place), photos of another place entirely (with this site's
// clicks, or with its own targets). Each either works or fails with one clear line,
// and a refused command leaves the project as it was.
#include "integration/field_project.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::run_strata;

// Width of the synthetic photos (test::synth's --width) and of the resized photos of
// the second camera, pixels.
constexpr int kSynthWidth = 800;
constexpr int kSecondCameraWidth = 600;
// Gaussian blur of the "blurred" photos, pixels: no feature survives it at 800 px.
constexpr double kBlurSigmaPx = 25;

class Degenerate : public ::testing::Test {
 protected:
  // The synthetic excavation (seed 5), made once for every process of the suite
  // (support/shared_scene.hpp; the tests only read it); another place (seed 9) is
  // made by the test that needs it.
  static void SetUpTestSuite() {
    scratch_ = new test::ScratchDir("degenerate");
    try {
      shared_ = test::shared_project("degenerate", 1, 12, 5, std::nullopt);
    } catch (const std::exception& e) {
      setup_error_ = e.what();
    }
  }
  void SetUp() override {
    if (!setup_error_.empty()) FAIL() << "the synthetic data could not be made: " << setup_error_;
  }
  static void TearDownTestSuite() {
    delete scratch_;
    scratch_ = nullptr;
  }
  static fs::path scratch() { return scratch_->path(); }
  static fs::path data() { return shared_ / "data"; }
  // Another place: the same kind of trench, dug and photographed otherwise (seed 9).
  static fs::path other_place() {
    const fs::path other = scratch() / "other";
    if (!fs::exists(other / "gcp_list.txt")) test::synth(other, 1, 12, 9);
    return other;
  }

  // A project with unit 101 and layer L1 holding `photos` (no markers).
  static fs::path site_with(const std::string& name, const std::vector<std::string>& photos) {
    const fs::path site = scratch() / name;
    fs::remove_all(site);
    EXPECT_EQ(run_strata({"-q", "init", site.string(), "--crs", "EPSG:32636"}).exit_code, 0);
    EXPECT_EQ(run_strata({"-q", "unit", "add", site.string(), "101"}).exit_code, 0);
    EXPECT_EQ(run_strata({"-q", "layer", "add", site.string(), "L1", "--unit", "101"}).exit_code, 0);
    std::vector<std::string> import = {"-q", "import", "photos", site.string(), "--layer", "L1"};
    import.insert(import.end(), photos.begin(), photos.end());
    const auto r = run_strata(import);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return site;
  }
  // The generator's clicks on L1's photos (its gcp_list: this site's, or `from`), for
  // the markers in `keep` only; `moved` replaces a marker's surveyed line (E N Z).
  static void import_clicks(const fs::path& site, const std::set<std::string>& keep,
                            const std::map<std::string, std::string>& moved = {},
                            const std::map<std::string, double>& scale = {}, const fs::path& from = {}) {
    std::ifstream in(from.empty() ? data() / "gcp_list.txt" : from);
    const fs::path out_path = site.parent_path() / (site.filename().string() + "_gcp_list.txt");
    std::ofstream out(out_path);
    std::string line;
    std::getline(in, line);
    out << line << "\n";
    while (std::getline(in, line)) {
      std::istringstream f(line);
      std::string e, n, z, x, y, image, marker;
      f >> e >> n >> z >> x >> y >> image >> marker;
      if (!keep.count(marker) || image.rfind("L1_", 0) != 0) continue;
      const auto m = moved.find(marker);
      if (const auto s = scale.find(image); s != scale.end()) {  // pixel centres at integers
        x = std::to_string((std::stod(x) + 0.5) * s->second - 0.5);
        y = std::to_string((std::stod(y) + 0.5) * s->second - 0.5);
      }
      out << (m == moved.end() ? e + "\t" + n + "\t" + z : m->second) << "\t" << x << "\t" << y << "\t" << image
          << "\t" << marker << "\n";
    }
    out.close();
    const auto r = run_strata({"-q", "import", "markers", site.string(), out_path.string(), "--layer", "L1"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  // The last line of stderr of a refused command: strata's one error line.
  static std::string error_line(const test::CommandResult& r) {
    const auto at = r.err.rfind("strata: error: ");
    return at == std::string::npos ? std::string() : r.err.substr(at);
  }
  // Writes each photo of L1 through `change` into `dir`; returns the new files.
  template <class F>
  static std::vector<std::string> rewritten(const std::string& dir, F change) {
    fs::create_directories(scratch() / "photos" / dir);
    std::vector<std::string> out;
    int k = 0;
    for (const auto& f : test::layer_photos(data(), "L1")) {
      cv::Mat im = cv::imread(f);
      if (im.empty()) throw std::runtime_error("OpenCV cannot read " + f);
      change(im, k++);
      const fs::path p = scratch() / "photos" / dir / fs::path(f).filename();
      if (!cv::imwrite(p.string(), im)) throw std::runtime_error("OpenCV cannot write " + p.string());
      out.push_back(p.string());
    }
    return out;
  }
  // `process` refused with one line holding every word of `words`, and changed nothing.
  static void expect_refused(const fs::path& site, const std::vector<std::string>& words) {
    const auto before = test::project_state(site);
    const auto r = run_strata({"process", site.string(), "--layer", "L1"});
    EXPECT_EQ(r.exit_code, 1) << "a typed error, not a crash: " << r.err;
    const std::string line = error_line(r);
    EXPECT_EQ(test::line_count(line), 1) << r.err;
    for (const auto& w : words) EXPECT_NE(line.find(w), std::string::npos) << "'" << w << "' in: " << r.err;
    EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
    EXPECT_TRUE(test::project_state(site) == before) << "the refused command recorded something";
  }
  static test::ScratchDir* scratch_;
  static fs::path shared_;
  static std::string setup_error_;
};
test::ScratchDir* Degenerate::scratch_ = nullptr;
fs::path Degenerate::shared_;
std::string Degenerate::setup_error_;

TEST_F(Degenerate, OnePhotoLayerIsRefused) {
  const fs::path site = site_with("one_photo", {test::layer_photos(data(), "L1").front()});
  expect_refused(site, {"layer L1 has 1 photo(s)", "alignment needs at least 2"});
}

TEST_F(Degenerate, TwoMarkersAreRefused) {
  const fs::path site = site_with("two_markers", test::layer_photos(data(), "L1"));
  import_clicks(site, {"GCP1", "GCP3"});
  expect_refused(site, {"georeference needs at least 3 control markers", "GCP1", "GCP3"});
}

TEST_F(Degenerate, CollinearMarkersAreRefused) {
  const fs::path site = site_with("collinear", test::layer_photos(data(), "L1"));
  // GCP2 moved onto the line through GCP1 and GCP3 (a few centimetres: the clicks still agree).
  import_clicks(site, {"GCP1", "GCP2", "GCP3"}, {{"GCP2", "734013.9338\t4174016.69225\t1450.5385"}});
  expect_refused(site, {"collinear", "GCP1", "GCP2", "GCP3"});
}

TEST_F(Degenerate, MarkersNoPhotoSeesAreNamedAndTheLayerStaysLocal) {
  const fs::path site = site_with("unseen_markers", test::layer_photos(data(), "L1"));
  const fs::path survey = scratch() / "unseen_markers.csv";
  std::ofstream(survey) << "name,E,N,Z,sigma,kind\n"
                           "X1,734100.0,4174100.0,1450.0,0.003,control\n"
                           "X2,734104.0,4174100.0,1450.0,0.003,control\n"
                           "X3,734102.0,4174104.0,1450.0,0.003,control\n";
  ASSERT_EQ(run_strata({"-q", "import", "markers", site.string(), survey.string()}).exit_code, 0);
  // The layer aligns in an arbitrary frame (a warning says why); its products then
  // fail naming that cause, and the alignment stays recorded.
  const auto r = run_strata({"process", site.string(), "--layer", "L1"});
  EXPECT_NE(r.err.find("warning: layer L1: no surveyed marker is seen in its photos"), std::string::npos) << r.err;
  if (r.exit_code != 0) {
    EXPECT_EQ(r.exit_code, 1) << r.err;
    const std::string line = error_line(r);
    EXPECT_EQ(test::line_count(line), 1) << r.err;
    EXPECT_NE(line.find("layer L1 is not georeferenced (no surveyed marker is seen in its photos)"),
              std::string::npos)
        << r.err;
  } else {
    EXPECT_NE(r.out.find("NOT georeferenced"), std::string::npos) << r.out;
  }
  const std::string alignments = test::database_rows(site / "project.gpkg", {"reconstructions"});
  EXPECT_GE(test::line_count(alignments), 2) << "the alignment is kept: " << alignments;
  EXPECT_EQ(test::integrity(site / "project.gpkg"), "ok");
}

TEST_F(Degenerate, SamePhotoInTwoLayersIsRefusedNamingTheLayer) {
  const auto photos = test::layer_photos(data(), "L1");
  const fs::path site = site_with("two_layers", photos);
  ASSERT_EQ(run_strata({"-q", "layer", "add", site.string(), "L2", "--unit", "101"}).exit_code, 0);
  const auto before = test::project_state(site);
  const auto r = run_strata({"import", "photos", site.string(), "--layer", "L2", photos[3]});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  const std::string line = error_line(r);
  EXPECT_EQ(test::line_count(line), 1) << r.err;
  EXPECT_NE(line.find("already in layer L1"), std::string::npos) << r.err;
  EXPECT_NE(line.find("nothing was imported"), std::string::npos) << r.err;
  EXPECT_TRUE(test::project_state(site) == before);
}

TEST_F(Degenerate, BlackPhotosAreRefused) {
  const fs::path site = site_with("black", rewritten("black", [](cv::Mat& im, int k) {
    // One grey corner pixel apiece: twelve identical files would import as one photo.
    im.setTo(cv::Scalar::all(0));
    im.at<cv::Vec3b>(0, 0) = cv::Vec3b::all(std::uint8_t(16 * (k + 1)));
  }));
  expect_refused(site, {"layer L1: no two of its 12 photos match", "too little texture", "black"});
}

TEST_F(Degenerate, BlurredPhotosAreRefused) {
  const fs::path site = site_with("blurred", rewritten("blurred", [](cv::Mat& im, int) {
                                    cv::GaussianBlur(im, im, cv::Size(), kBlurSigmaPx);
                                  }));
  expect_refused(site, {"layer L1: no two of its 12 photos match", "too little texture", "blurred"});
}

TEST_F(Degenerate, SeveralCamerasInOneLayerAlign) {
  // Every other photo resized and written without EXIF: another camera (image size,
  // no make or model); its clicks scaled with it.
  const auto originals = test::layer_photos(data(), "L1");
  const auto resized = rewritten("cameras", [](cv::Mat& im, int) {
    const int h = int(std::lround(im.rows * double(kSecondCameraWidth) / im.cols));
    cv::resize(im, im, cv::Size(kSecondCameraWidth, h), 0, 0, cv::INTER_AREA);
  });
  std::vector<std::string> photos;
  std::map<std::string, double> scale;
  for (std::size_t k = 0; k < originals.size(); ++k) {
    photos.push_back(k % 2 ? resized[k] : originals[k]);
    if (k % 2) scale[fs::path(originals[k]).filename().string()] = double(kSecondCameraWidth) / kSynthWidth;
  }
  const fs::path site = site_with("cameras", photos);
  import_clicks(site, {"GCP1", "GCP2", "GCP3", "GCP4", "GCP5", "GCP6", "GCP7", "GCP8"}, {}, scale);
  const auto r = run_strata({"process", site.string(), "--layer", "L1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Both cameras are solved; one photo of the smaller camera may stay out (fewer
  // keypoints at 600 px), but then it is named.
  const bool all = r.out.find("photos aligned      12 / 12") != std::string::npos;
  EXPECT_TRUE(all || r.out.find("photos aligned      11 / 12") != std::string::npos) << r.out;
  if (!all) {
    EXPECT_NE(r.err.find("sfm: 11 of 12 images registered; not registered: L1_"), std::string::npos) << r.err;
  }
  EXPECT_NE(r.out.find("camera 1            800 x 534"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("camera 2            600 x 401"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("NOT georeferenced"), std::string::npos) << r.out;
}

TEST_F(Degenerate, PhotosOfAnotherPlaceWithThisSitesClicksAreRefused) {
  // The wrong folder imported: twelve photos of another trench with the same file names
  // (phones number their photos), and the clicks made on this site's photos. Every photo
  // aligns; the clicks land on other things.
  const fs::path site = site_with("another_place_clicks", test::layer_photos(other_place(), "L1"));
  import_clicks(site, {"GCP1", "GCP2", "GCP3", "GCP4", "GCP5", "GCP6", "GCP7", "GCP8"});
  expect_refused(site, {"georeference: these photos do not fit the survey", "of their spread",
                        "scatter instead of meeting at one point", "the photos show another place",
                        "nothing was recorded"});
}

TEST_F(Degenerate, PhotosOfAnotherPlaceWithItsOwnMarkersAreRefused) {
  // Another trench marked with the same kit of targets (GCP1..GCP8, clicked right in
  // its own photos), georeferenced on this site's survey: the survey can only be met by
  // bending the photos.
  const fs::path site = site_with("another_place_targets", test::layer_photos(other_place(), "L1"));
  std::map<std::string, std::string> survey;  // marker -> this site's "E\tN\tZ"
  {
    std::ifstream in(data() / "gcp_list.txt");
    std::string line, e, n, z, x, y, image, marker;
    std::getline(in, line);
    while (in >> e >> n >> z >> x >> y >> image >> marker) survey[marker] = e + "\t" + n + "\t" + z;
  }
  import_clicks(site, {"GCP1", "GCP2", "GCP3", "GCP4", "GCP5", "GCP6", "GCP7", "GCP8"}, survey, {},
                other_place() / "gcp_list.txt");
  expect_refused(site, {"georeference: these photos do not fit the survey", "bending the photos",
                        "keypoint reprojection RMSE", "the photos show another place", "nothing was recorded"});
}

TEST_F(Degenerate, TwoGroupsOfPhotosAlignTheLargerAndNameTheOther) {
  // The twelve photos of the site and four of another place, named so that they sort last.
  auto photos = test::layer_photos(data(), "L1");
  fs::create_directories(scratch() / "elsewhere");
  const auto other = test::layer_photos(other_place(), "L1");
  for (int i = 0; i < 4; ++i) {
    const fs::path p = scratch() / "elsewhere" / ("X_elsewhere_" + std::to_string(i + 1) + ".jpg");
    fs::copy_file(other[std::size_t(i)], p, fs::copy_options::overwrite_existing);
    photos.push_back(p.string());
  }
  const fs::path site = site_with("two_groups", photos);
  import_clicks(site, {"GCP1", "GCP2", "GCP3", "GCP4", "GCP5", "GCP6", "GCP7", "GCP8"});
  const auto r = run_strata({"process", site.string(), "--layer", "L1"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("photos aligned      12 / 16"), std::string::npos) << r.out << r.err;
  EXPECT_NE(r.err.find("12 photo(s), 12 aligned (L1_0001.jpg"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("groups that no match joins"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not registered: X_elsewhere_1.jpg, X_elsewhere_2.jpg, X_elsewhere_3.jpg, "
                       "X_elsewhere_4.jpg"),
            std::string::npos)
      << r.err;
}

}  // namespace
}  // namespace strata
