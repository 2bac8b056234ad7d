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

// The descriptors of the `count` keypoints of largest scale (all when fewer), as
// CV_32F rows. Large-scale keypoints are the most repeatable across viewpoints
// (Wu 2013), which is what a preview of a pair needs. Keypoints without scales:
// the first (strongest) rows. Same errors as load_descriptors().
cv::Mat load_largest_scale_descriptors(const std::filesystem::path& cache_dir,
                                       const ImageKeypoints& image, int count);

}  // namespace strata::features
