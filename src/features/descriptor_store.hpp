#pragma once
// Internal to the features module (includes OpenCV): descriptors of one image
// read back from the features cache, as float rows ready for FLANN / BFMatcher.
#include "features/types.hpp"

#include <opencv2/core.hpp>

#include <filesystem>

namespace strata::features {

// All descriptors of `image` (rows = keypoints, CV_32F, 128 columns), or only
// the first `max_rows` (the strongest keypoints) when max_rows >= 0.
// Throws ProcessingError when the cache entry is missing or does not match the
// keypoints (extract_features was not run with this cache_dir).
cv::Mat load_descriptors(const std::filesystem::path& cache_dir, const ImageKeypoints& image,
                         int max_rows = -1);

}  // namespace strata::features
