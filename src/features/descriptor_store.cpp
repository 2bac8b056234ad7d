#include "features/descriptor_store.hpp"

#include "core/error.hpp"
#include "features/cache_io.hpp"

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

}  // namespace strata::features
