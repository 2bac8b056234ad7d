#pragma once
// Feature extraction: SIFT keypoints (Lowe 2004) with RootSIFT descriptors
// (Arandjelović & Zisserman 2012) for every photo of a layer, cached on disk.
//
// Public surface: FeatureExtractionOptions, FeatureExtractionSummary and
// extract_features(). No OpenCV types here; OpenCV stays inside the .cpp files.
#include "core/cache_key.hpp"
#include "features/types.hpp"

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

// One photo to process.
struct FeatureImage {
  std::string name;             // unique within the layer; copied to ImageKeypoints::image
  std::filesystem::path path;   // the photo file (never modified)
  std::string sha256;           // lower-case hex SHA-256 of the file; computed when empty
};

struct FeatureExtractionOptions {
  // Long side of the image SIFT runs on, in pixels. Larger photos are downscaled
  // (area averaging) first; keypoints are mapped back to original photo pixels.
  // 0 = always the full resolution.
  int max_image_size = 2000;
  // Strongest keypoints kept per image (by DoG response). > 0.
  int max_features = 8000;
  // SIFT peak threshold in OpenCV's units (contrastThreshold; divided by the
  // number of octave layers internally). Lower finds more keypoints on weakly
  // textured soil. OpenCV's default is 0.04; COLMAP's equivalent is 0.02.
  double contrast_threshold = 0.02;
  // SIFT edge threshold: ratio of principal curvatures (Lowe's r), unitless, > 1.
  double edge_threshold = 10.0;
  // Scale-space levels per octave, >= 1.
  int octave_layers = 3;
  // Convert descriptors to RootSIFT (L1-normalise, square root); matches better
  // with Euclidean distance. Stored as uint8 (x 512, as COLMAP does).
  bool root_sift = true;
  // Worker threads over images; 0 = all hardware threads.
  Unkeyed<int> num_threads = 0;

  // Throws InputError naming the first invalid field.
  void validate() const;
};

struct FeatureExtractionSummary {
  std::size_t images = 0;
  std::size_t extracted = 0;          // computed in this run
  std::size_t loaded_from_cache = 0;  // read back from cache_dir
  std::size_t keypoints = 0;          // total over all images
  double seconds = 0;                 // wall time of the whole stage
  double cpu_seconds = 0;             // process CPU time over the stage (all threads)
};

// Extracts (or loads from cache) the keypoints of every image, in input order.
// cache_dir: the project's cache folder (required: descriptors live there and
// match_pairs() reads them); files go to cache_dir/features/<sha[0:2]>/.
// Throws IoError for an unreadable photo or cache folder, InputError for bad options.
std::vector<ImageKeypoints> extract_features(const FeatureExtractionOptions& options,
                                             const std::vector<FeatureImage>& images,
                                             const std::filesystem::path& cache_dir,
                                             FeatureExtractionSummary* summary = nullptr);

}  // namespace strata
