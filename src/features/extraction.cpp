#include "features/extraction.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "features/cache_io.hpp"
#include "core/parallel.hpp"

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <ctime>
#include <atomic>
#include <cmath>
#include <numeric>

namespace strata {
namespace {

// Bump when the extraction code changes its output, so old cache files are
// not reused (they become unreachable and `cache/` can be deleted at will).
constexpr int kExtractionVersion = 1;

// OpenCV's SIFT doubles the image first (first octave -1) with a resize that
// follows the pixel-centre convention: pixel 2k of the doubled image lies at
// k - 0.25 of the input. It reports pt = (doubled pixel) / 2, i.e. 0.25 px too
// far right and down, at every octave. We remove that offset.
constexpr double kSiftUpsampleOffset = 0.25;  // pixels of the image SIFT ran on

features::StoredFeatures compute_features(const FeatureExtractionOptions& o,
                                          const FeatureImage& image) {
  // IGNORE_ORIENTATION: keypoints live in the stored pixel grid, the grid the
  // camera's intrinsics describe, whatever the EXIF orientation flag says.
  const cv::Mat colour =
      cv::imread(image.path.string(), cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  if (colour.empty()) {
    throw IoError(fmt::format("features: cannot read image {}", image.path.string()));
  }
  const int width = colour.cols, height = colour.rows;
  const int long_side = std::max(width, height);

  cv::Mat work = colour;
  if (o.max_image_size > 0 && long_side > o.max_image_size) {
    const double s = static_cast<double>(o.max_image_size) / long_side;
    const cv::Size size(std::max(1, static_cast<int>(std::lround(width * s))),
                        std::max(1, static_cast<int>(std::lround(height * s))));
    cv::resize(colour, work, size, 0, 0, cv::INTER_AREA);
  }
  // Exact per-axis factors from work pixels to photo pixels (rounding of the size
  // makes them differ slightly from 1/s).
  const double fx = static_cast<double>(width) / work.cols;
  const double fy = static_cast<double>(height) / work.rows;

  cv::Mat grey;
  cv::cvtColor(work, grey, cv::COLOR_BGR2GRAY);

  auto sift = cv::SIFT::create(o.max_features, o.octave_layers, o.contrast_threshold,
                               o.edge_threshold, 1.6, CV_32F);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  sift->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);

  // OpenCV may return a few more than nfeatures on ties, and its parallel
  // detection makes the order run-dependent: sort by response (strongest first,
  // ties by position) so results and cache files are deterministic.
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const auto& ka = keypoints[a];
    const auto& kb = keypoints[b];
    if (ka.response != kb.response) return ka.response > kb.response;
    if (ka.pt.y != kb.pt.y) return ka.pt.y < kb.pt.y;
    if (ka.pt.x != kb.pt.x) return ka.pt.x < kb.pt.x;
    return ka.size > kb.size;
  });
  if (order.size() > static_cast<std::size_t>(o.max_features)) order.resize(o.max_features);

  const std::size_t n = order.size();
  features::StoredFeatures out;
  out.points.resize(n);
  out.scales.resize(n);
  out.colours.resize(3 * n);
  out.descriptors.resize(n * features::kDescriptorDim);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = keypoints[order[i]];
    const double xw = kp.pt.x - kSiftUpsampleOffset;  // work-image pixels
    const double yw = kp.pt.y - kSiftUpsampleOffset;
    // Pixel centres: work pixel u covers photo [u*f, (u+1)*f) in corner
    // coordinates, so centre-based photo x = (u + 0.5) * f - 0.5.
    out.points[i] = {(xw + 0.5) * fx - 0.5, (yw + 0.5) * fy - 0.5};
    out.scales[i] = static_cast<float>(kp.size * 0.5 * (fx + fy));

    const int u = std::clamp(static_cast<int>(std::lround(xw)), 0, work.cols - 1);
    const int v = std::clamp(static_cast<int>(std::lround(yw)), 0, work.rows - 1);
    const cv::Vec3b bgr = work.at<cv::Vec3b>(v, u);
    out.colours[3 * i + 0] = bgr[2];
    out.colours[3 * i + 1] = bgr[1];
    out.colours[3 * i + 2] = bgr[0];

    const float* d = descriptors.ptr<float>(order[i]);
    std::uint8_t* q = out.descriptors.data() + i * features::kDescriptorDim;
    if (o.root_sift) {
      // RootSIFT: Hellinger kernel as Euclidean distance; sqrt of the
      // L1-normalised descriptor has unit L2 norm, scaled by 512 into uint8.
      double l1 = 0;
      for (int k = 0; k < features::kDescriptorDim; ++k) l1 += std::abs(d[k]);
      l1 = std::max(l1, 1e-12);
      for (int k = 0; k < features::kDescriptorDim; ++k) {
        const double v = 512.0 * std::sqrt(std::abs(d[k]) / l1);
        q[k] = static_cast<std::uint8_t>(std::min(255.0, std::round(v)));
      }
    } else {
      // OpenCV's SIFT values are already integers in [0, 255].
      for (int k = 0; k < features::kDescriptorDim; ++k) {
        q[k] = static_cast<std::uint8_t>(std::clamp(std::round(d[k]), 0.0f, 255.0f));
      }
    }
  }
  return out;
}

}  // namespace

void FeatureExtractionOptions::validate() const {
  auto fail = [](const char* field, const std::string& why) {
    throw InputError(fmt::format("features: option {} {}", field, why));
  };
  if (max_image_size < 0)
    fail("max_image_size", fmt::format("must be >= 0 pixels (got {})", max_image_size));
  if (max_image_size > 0 && max_image_size < 64)
    fail("max_image_size", fmt::format("must be 0 or >= 64 pixels (got {})", max_image_size));
  if (max_features <= 0)
    fail("max_features", fmt::format("must be > 0 (got {})", max_features));
  if (!(contrast_threshold > 0 && contrast_threshold < 1))
    fail("contrast_threshold", fmt::format("must be in (0, 1) (got {})", contrast_threshold));
  if (!(edge_threshold > 1))
    fail("edge_threshold", fmt::format("must be > 1 (got {})", edge_threshold));
  if (octave_layers < 1 || octave_layers > 10)
    fail("octave_layers", fmt::format("must be in [1, 10] (got {})", octave_layers));
  if (num_threads < 0)
    fail("num_threads", fmt::format("must be >= 0 (got {})", num_threads));
}

std::vector<ImageKeypoints> extract_features(const FeatureExtractionOptions& options,
                                             const std::vector<FeatureImage>& images,
                                             const std::filesystem::path& cache_dir,
                                             FeatureExtractionSummary* summary) {
  options.validate();
  STRATA_CHECK(!cache_dir.empty(), "extract_features needs a cache folder");
  Stopwatch clock;
  const std::clock_t cpu_start = std::clock();
  const std::string fingerprint =
      CacheKey(fmt::format("features v{}", kExtractionVersion)).add(options).hex().substr(0, 16);

  std::vector<ImageKeypoints> result(images.size());
  std::atomic<std::size_t> extracted{0}, cached{0};
  Progress progress("features", images.size());

  parallel_for_index(images.size(), options.num_threads, [&](std::size_t i) {
    check_cancelled();
    const FeatureImage& image = images[i];
    const std::string sha = image.sha256.empty() ? sha256_file(image.path) : image.sha256;
    ImageKeypoints& kp = result[i];
    kp.image = image.name;
    kp.features_key = sha + "-" + fingerprint;
    const auto file = features::features_file(cache_dir, kp.features_key);

    std::optional<features::StoredFeatures> stored = features::read_features(file);
    if (stored) {
      ++cached;
    } else {
      stored = compute_features(options, image);
      features::write_features(file, *stored);
      fault::point("process.features.image_done");
      ++extracted;
    }
    kp.points = std::move(stored->points);
    kp.scales = std::move(stored->scales);
    kp.colours = std::move(stored->colours);
    progress.step();
  });
  progress.finish();

  FeatureExtractionSummary s;
  s.images = images.size();
  s.extracted = extracted;
  s.loaded_from_cache = cached;
  for (const auto& kp : result) s.keypoints += kp.points.size();
  s.seconds = clock.seconds();
  s.cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  log::info("features: {} images ({} extracted, {} from cache), {} keypoints, {:.1f} s",
            s.images, s.extracted, s.loaded_from_cache, s.keypoints, s.seconds);
  if (summary) *summary = s;
  return result;
}

}  // namespace strata
