#include "core/error.hpp"
#include "features/extraction.hpp"
#include "support/test_support.hpp"
#include "unit/features/synthetic_images.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>

namespace strata {
namespace {

// SIFT's quadratic sub-pixel fit on an isotropic blob is accurate to a few
// hundredths of a pixel of the image SIFT runs on; 0.1 px of that image leaves
// room for the pyramid's interpolation and stays far below the errors a wrong
// pixel-centre mapping makes (0.25 px at full size, 2.5 px at 1/4 size).
constexpr double kBlobTolerancePx = 0.1;  // pixels of the image SIFT ran on

// A grey image with Gaussian blobs at known, non-integer centres.
struct BlobImage {
  cv::Mat image;
  std::vector<Eigen::Vector2d> centres;  // pixel-centre convention
};

BlobImage blob_image(int width, int height, double sigma) {
  BlobImage b;
  b.image = cv::Mat(height, width, CV_8UC3, cv::Scalar::all(100));
  cv::Mat f(height, width, CV_32F, cv::Scalar(100));
  const double spacing = 12 * sigma;
  int k = 0;
  for (double y = spacing; y < height - spacing; y += spacing) {
    for (double x = spacing; x < width - spacing; x += spacing, ++k) {
      // Sub-pixel offsets that differ per blob.
      const Eigen::Vector2d c(x + 0.37 * (k % 3) + 0.11, y + 0.29 * (k % 4) + 0.07);
      b.centres.push_back(c);
      for (int v = static_cast<int>(c.y() - 5 * sigma); v <= c.y() + 5 * sigma; ++v) {
        for (int u = static_cast<int>(c.x() - 5 * sigma); u <= c.x() + 5 * sigma; ++u) {
          const double r2 = (u - c.x()) * (u - c.x()) + (v - c.y()) * (v - c.y());
          f.at<float>(v, u) += static_cast<float>(120 * std::exp(-r2 / (2 * sigma * sigma)));
        }
      }
    }
  }
  cv::Mat grey;
  f.convertTo(grey, CV_8U);
  cv::cvtColor(grey, b.image, cv::COLOR_GRAY2BGR);
  return b;
}

// For every blob, the distance to the nearest keypoint.
std::vector<double> blob_errors(const BlobImage& b, const ImageKeypoints& kp) {
  std::vector<double> errors;
  for (const auto& c : b.centres) {
    double best = 1e9;
    for (const auto& p : kp.points) best = std::min(best, (p - c).norm());
    errors.push_back(best);
  }
  return errors;
}

TEST(FeatureExtraction, KeypointsInOriginalPixelsAtFullAndReducedSize) {
  test::ScratchDir dir("blobs");
  const BlobImage b = blob_image(1600, 1200, 8.0);
  test::write_png(dir / "blobs.png", b.image);
  const std::vector<FeatureImage> images = {{"blobs", dir / "blobs.png", ""}};

  for (const int max_size : {0, 800, 400}) {
    SCOPED_TRACE(::testing::Message() << "max_image_size " << max_size);
    FeatureExtractionOptions o;
    o.max_image_size = max_size;
    const auto kp = extract_features(o, images, dir / "cache");
    ASSERT_EQ(kp.size(), 1u);
    const double factor = max_size == 0 ? 1.0 : 1600.0 / max_size;  // photo px per work px
    const auto errors = blob_errors(b, kp[0]);
    ASSERT_GT(errors.size(), 10u);
    for (std::size_t i = 0; i < errors.size(); ++i) {
      EXPECT_LT(errors[i], kBlobTolerancePx * factor)
          << "blob " << i << " at " << b.centres[i].transpose();
    }
  }
}

TEST(FeatureExtraction, CacheReturnsIdenticalKeypointsAndOptionsInvalidateIt) {
  test::ScratchDir dir("cache");
  test::write_png(dir / "a.png", test::noise_texture(900, 700, 1));
  test::write_png(dir / "b.png", test::noise_texture(900, 700, 2));
  const std::vector<FeatureImage> images = {{"a", dir / "a.png", ""}, {"b", dir / "b.png", ""}};
  FeatureExtractionOptions o;
  o.max_image_size = 600;
  o.max_features = 3000;

  FeatureExtractionSummary first, second, changed;
  const auto k1 = extract_features(o, images, dir / "cache", &first);
  EXPECT_EQ(first.extracted, 2u);
  EXPECT_EQ(first.loaded_from_cache, 0u);
  const auto k2 = extract_features(o, images, dir / "cache", &second);
  EXPECT_EQ(second.extracted, 0u);
  EXPECT_EQ(second.loaded_from_cache, 2u);
  ASSERT_EQ(k1.size(), k2.size());
  for (std::size_t i = 0; i < k1.size(); ++i) {
    EXPECT_EQ(k1[i].image, k2[i].image);
    EXPECT_EQ(k1[i].features_key, k2[i].features_key);
    EXPECT_EQ(k1[i].points, k2[i].points);  // bit-identical: stored as f64
    EXPECT_EQ(k1[i].scales, k2[i].scales);
    EXPECT_EQ(k1[i].colours, k2[i].colours);
    EXPECT_GT(k1[i].points.size(), 500u);
    EXPECT_LE(k1[i].points.size(), 3000u);
    EXPECT_EQ(k1[i].colours.size(), 3 * k1[i].points.size());
  }

  o.max_features = 2000;
  const auto k3 = extract_features(o, images, dir / "cache", &changed);
  EXPECT_EQ(changed.extracted, 2u);
  EXPECT_EQ(changed.loaded_from_cache, 0u);
  EXPECT_NE(k3[0].features_key, k1[0].features_key);

  // num_threads does not change the result, so it does not change the key: the
  // features of k3 come from the cache.
  FeatureExtractionOptions threads = o;
  threads.num_threads = 1;
  const auto k4 = extract_features(threads, images, dir / "cache", &changed);
  EXPECT_EQ(changed.loaded_from_cache, 2u);
  EXPECT_EQ(k4[0].features_key, k3[0].features_key);
}

TEST(FeatureExtraction, CorruptCacheFileIsRecomputed) {
  test::ScratchDir dir("corrupt");
  test::write_png(dir / "a.png", test::noise_texture(500, 400, 3));
  const std::vector<FeatureImage> images = {{"a", dir / "a.png", ""}};
  FeatureExtractionOptions o;
  const auto k1 = extract_features(o, images, dir / "cache");
  // Truncate every cache file.
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir / "cache"))
    if (e.is_regular_file()) std::filesystem::resize_file(e.path(), 100);
  FeatureExtractionSummary s;
  const auto k2 = extract_features(o, images, dir / "cache", &s);
  EXPECT_EQ(s.extracted, 1u);
  EXPECT_EQ(k1[0].points, k2[0].points);
}

TEST(FeatureExtraction, RejectsInvalidOptionsNamingTheField) {
  FeatureExtractionOptions o;
  o.max_features = 0;
  try {
    o.validate();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("max_features"), std::string::npos) << e.what();
  }
  o = {};
  o.max_image_size = -5;
  EXPECT_THROW(o.validate(), InputError);
  o = {};
  o.contrast_threshold = 0;
  EXPECT_THROW(o.validate(), InputError);
}

TEST(FeatureExtraction, UnreadablePhotoIsAnIoError) {
  test::ScratchDir dir("unreadable");
  test::write_text(dir / "not_an_image.jpg", "hello");
  EXPECT_THROW(extract_features({}, {{"x", dir / "not_an_image.jpg", ""}}, dir / "cache"),
               IoError);
}

}  // namespace
}  // namespace strata
