#pragma once
// Internal to the features module: the compact binary cache files for features
// and matches. Format (native little-endian, x86-64 / arm64):
//   features: "STRFEAT1" u32 count u32 dim | count x (f64 x, f64 y) | count x f32 scale
//             | count x 3 u8 RGB | count x dim u8 descriptor | "END!"
//   matches:  "STRMTCH1" u32 model u32 homography_inliers u32 putative u32 count
//             | count x (u32 a, u32 b) | "END!"
// Files are written to a temporary name and renamed, so a crash or a concurrent
// run never leaves a half-written file under the final name.
#include "features/types.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace strata::features {

inline constexpr int kDescriptorDim = 128;  // SIFT

struct StoredFeatures {
  std::vector<Eigen::Vector2d> points;     // original photo pixels
  std::vector<float> scales;               // pixels
  std::vector<std::uint8_t> colours;       // RGB triplets
  std::vector<std::uint8_t> descriptors;   // points.size() x kDescriptorDim
};

struct StoredMatches {
  TwoViewModel model = TwoViewModel::none;  // none: the pair failed verification
  int homography_inliers = 0;
  int putative = 0;                         // matches before verification
  std::vector<std::pair<int, int>> matches; // verified inliers
};

std::filesystem::path features_file(const std::filesystem::path& cache_dir,
                                    const std::string& features_key);
std::filesystem::path matches_file(const std::filesystem::path& cache_dir,
                                   const std::string& match_key);

void write_features(const std::filesystem::path& path, const StoredFeatures& f);
// Empty when the file is missing; a corrupt or truncated file logs a warning and
// also returns empty, so the caller recomputes and overwrites it.
std::optional<StoredFeatures> read_features(const std::filesystem::path& path);

void write_matches(const std::filesystem::path& path, const StoredMatches& m);
std::optional<StoredMatches> read_matches(const std::filesystem::path& path);

}  // namespace strata::features
