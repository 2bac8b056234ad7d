#include "features/descriptor_store.hpp"

#include "core/error.hpp"
#include "features/cache_io.hpp"

#include <algorithm>
#include <numeric>

namespace strata::features {

cv::Mat load_descriptors(const std::filesystem::path& cache_dir, const ImageKeypoints& image,
                         int max_rows) {
  if (image.features_key.empty()) {
    throw ProcessingError(fmt::format(
        "matching: image {} has no features cache key (run extract_features first)",
        image.image));
  }
  const auto file = features_file(cache_dir, image.features_key);
  const auto stored = read_features(file);
  if (!stored || stored->points.size() != image.points.size()) {
    throw ProcessingError(fmt::format(
        "matching: the features cache entry {} of image {} is missing or stale (run "
        "extract_features with the same cache folder)",
        file.string(), image.image));
  }
  int rows = static_cast<int>(stored->points.size());
  if (max_rows >= 0) rows = std::min(rows, max_rows);
  cv::Mat bytes(rows, kDescriptorDim, CV_8U,
                const_cast<std::uint8_t*>(stored->descriptors.data()));
  cv::Mat out;
  bytes.convertTo(out, CV_32F);  // copies: `stored` dies here
  return out;
}

cv::Mat load_largest_scale_descriptors(const std::filesystem::path& cache_dir,
                                       const ImageKeypoints& image, int count) {
  const std::size_t n = image.points.size();
  if (image.scales.size() != n) return load_descriptors(cache_dir, image, count);
  const cv::Mat all = load_descriptors(cache_dir, image);
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  const std::size_t keep = std::min<std::size_t>(n, static_cast<std::size_t>(std::max(count, 0)));
  // Ties keep the stored (strongest first) order: deterministic.
  std::partial_sort(order.begin(), order.begin() + keep, order.end(), [&](int a, int b) {
    return image.scales[a] != image.scales[b] ? image.scales[a] > image.scales[b] : a < b;
  });
  cv::Mat out(static_cast<int>(keep), all.cols, CV_32F);
  for (std::size_t r = 0; r < keep; ++r) all.row(order[r]).copyTo(out.row(static_cast<int>(r)));
  return out;
}

}  // namespace strata::features
