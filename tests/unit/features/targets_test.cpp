#include "core/error.hpp"
#include "features/targets.hpp"
#include "support/test_support.hpp"
#include "unit/features/synthetic_images.hpp"

#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <Eigen/Geometry>

namespace strata {
namespace {

// Sub-pixel corner refinement on blurred, noisy edges locates corners to about
// 0.1 px; the centre (intersection of diagonals) averages four of them. 0.3 px
// is the accuracy a GCP observation needs (well under the 0.5 px SfM residual).
constexpr double kCentreTolerancePx = 0.3;
constexpr double kCornerTolerancePx = 0.5;
constexpr double kBlurSigmaPx = 1.0;   // lens / motion blur
constexpr double kNoiseSigma = 4.0;    // grey levels of sensor noise

struct Placed {
  int id;
  Eigen::Vector2d corner;  // top-left pixel of the drawn marker, canvas pixels
};

struct TargetScene {
  cv::Mat image;
  std::map<int, std::vector<Eigen::Vector2d>> true_corners;  // photo pixels
  std::map<int, Eigen::Vector2d> true_centres;
};

// Markers drawn on a light canvas, warped by H (perspective), blurred, noisy.
TargetScene target_scene(cv::aruco::PREDEFINED_DICTIONARY_NAME dict, int width, int height,
                         int side, const std::vector<Placed>& placed,
                         const Eigen::Matrix3d& H) {
  cv::Mat canvas(height, width, CV_8U, cv::Scalar(215));
  const auto dictionary = cv::aruco::getPredefinedDictionary(dict);
  TargetScene s;
  for (const auto& p : placed) {
    cv::Mat marker;
    cv::aruco::drawMarker(dictionary, p.id, side, marker, 1);
    const int x0 = static_cast<int>(p.corner.x()), y0 = static_cast<int>(p.corner.y());
    marker.copyTo(canvas(cv::Rect(x0, y0, side, side)));
    // The drawn square covers pixels x0 .. x0+side-1: its outer corners are
    // half a pixel outside those pixel centres.
    const double l = x0 - 0.5, t = y0 - 0.5, r = x0 + side - 0.5, b = y0 + side - 0.5;
    for (const auto& c : {Eigen::Vector2d(l, t), Eigen::Vector2d(r, t), Eigen::Vector2d(r, b),
                          Eigen::Vector2d(l, b)})
      s.true_corners[p.id].push_back(test::apply(H, c));
    s.true_centres[p.id] = test::apply(H, Eigen::Vector2d(0.5 * (l + r), 0.5 * (t + b)));
  }
  cv::Mat warped = test::warp(canvas, H, width, height);
  cv::GaussianBlur(warped, warped, cv::Size(0, 0), kBlurSigmaPx);
  cv::Mat noise(warped.size(), CV_16S);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::NORMAL, 0, kNoiseSigma);
  cv::Mat noisy;
  warped.convertTo(noisy, CV_16S);
  noisy += noise;
  noisy.convertTo(s.image, CV_8U);
  return s;
}

// A strong perspective: the far side of the marker field is visibly smaller.
Eigen::Matrix3d perspective(double scale) {
  Eigen::Matrix3d H;
  H << 0.95, 0.12, 40 * scale, -0.08, 0.9, 60 * scale, 0.00012 / scale, 0.00008 / scale, 1;
  return H;
}

void expect_detections(const TargetScene& s, const std::vector<TargetDetection>& found) {
  ASSERT_EQ(found.size(), s.true_centres.size());
  for (const auto& d : found) {
    ASSERT_TRUE(s.true_centres.count(d.id)) << "unexpected id " << d.id;
    const Eigen::Vector2d truth = s.true_centres.at(d.id);
    EXPECT_LT((d.centre - truth).norm(), kCentreTolerancePx)
        << "id " << d.id << " centre " << d.centre.transpose() << " truth " << truth.transpose();
    ASSERT_EQ(d.corners.size(), 4u);
    for (int c = 0; c < 4; ++c)
      EXPECT_LT((d.corners[c] - s.true_corners.at(d.id)[c]).norm(), kCornerTolerancePx)
          << "id " << d.id << " corner " << c;
  }
}

TEST(Targets, ArucoIdsAndSubPixelCentresUnderPerspective) {
  test::ScratchDir dir("aruco");
  const std::vector<Placed> placed = {
      {0, {150, 150}}, {7, {700, 180}}, {23, {220, 650}}, {42, {800, 620}}};
  const auto scene =
      target_scene(cv::aruco::DICT_4X4_50, 1400, 1000, 140, placed, perspective(1.0));
  test::write_png(dir / "targets.png", scene.image);
  TargetSummary summary;
  const auto found = detect_targets({}, dir / "targets.png", &summary);
  EXPECT_FALSE(summary.downscaled);
  expect_detections(scene, found);
  EXPECT_EQ(found.front().id, 0);  // sorted by id
  EXPECT_EQ(found.back().id, 42);
}

TEST(Targets, LargePhotoIsSearchedDownscaledAndRefinedAtFullResolution) {
  test::ScratchDir dir("large");
  const std::vector<Placed> placed = {{3, {600, 500}}, {19, {2600, 700}}, {31, {1500, 1900}}};
  const auto scene =
      target_scene(cv::aruco::DICT_4X4_50, 4000, 3000, 300, placed, perspective(3.0));
  test::write_png(dir / "large.png", scene.image);
  TargetOptions o;
  o.max_detection_size = 1500;
  TargetSummary summary;
  const auto found = detect_targets(o, dir / "large.png", &summary);
  EXPECT_TRUE(summary.downscaled);
  expect_detections(scene, found);
}

TEST(Targets, AprilTagByName) {
  test::ScratchDir dir("april");
  const std::vector<Placed> placed = {{5, {200, 200}}, {300, {750, 400}}};
  const auto scene =
      target_scene(cv::aruco::DICT_APRILTAG_36h11, 1200, 900, 200, placed, perspective(1.0));
  test::write_png(dir / "april.png", scene.image);
  TargetOptions o;
  o.dictionary = "tag36h11";
  expect_detections(scene, detect_targets(o, dir / "april.png"));
  o.dictionary = "DICT_APRILTAG_36h11";
  EXPECT_EQ(detect_targets(o, dir / "april.png").size(), 2u);
}

TEST(Targets, OptionsAreValidated) {
  TargetOptions o;
  o.dictionary = "DICT_9X9_5";
  try {
    o.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("dictionary"), std::string::npos);
  }
  o = {};
  o.max_detection_size = 100;
  EXPECT_THROW(o.validate(), InputError);
}

TEST(TargetNamingRules, RuleAndExplicitMapping) {
  TargetNaming naming;
  EXPECT_EQ(target_name(naming, 7), "GCP7");
  naming.rule = "T{id:03}";
  EXPECT_EQ(target_name(naming, 7), "T007");
  EXPECT_EQ(target_name(naming, 1234), "T1234");
  naming.names = parse_target_names(" 3=North peg, 7 = GCP_A ,");
  EXPECT_EQ(naming.names.size(), 2u);
  EXPECT_EQ(target_name(naming, 3), "North peg");
  EXPECT_EQ(target_name(naming, 7), "GCP_A");  // explicit wins over the rule
  EXPECT_EQ(target_name(naming, 8), "T008");
  naming.rule.clear();  // only mapped ids have names
  EXPECT_EQ(target_name(naming, 8), "");
  EXPECT_NO_THROW(naming.validate());
}

TEST(TargetNamingRules, BadRulesAndMappingsAreInputErrors) {
  TargetNaming naming;
  naming.rule = "GCP";  // every target would get the same name
  EXPECT_THROW(naming.validate(), InputError);
  naming.rule = "GCP{name}";
  EXPECT_THROW(naming.validate(), InputError);
  naming.rule = "GCP{id:x}";
  EXPECT_THROW(naming.validate(), InputError);
  naming.rule = "GCP{id";
  EXPECT_THROW(naming.validate(), InputError);
  EXPECT_THROW(parse_target_names("3=A,x=B"), InputError);
  EXPECT_THROW(parse_target_names("3=A,3=B"), InputError);
  EXPECT_THROW(parse_target_names("3"), InputError);
  EXPECT_THROW(parse_target_names("3="), InputError);
  EXPECT_TRUE(parse_target_names("").empty());
}

}  // namespace
}  // namespace strata
