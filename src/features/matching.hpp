#pragma once
// Pair selection, descriptor matching and geometric verification.
//
//   select_pairs()  which image pairs to match (exhaustive for small layers,
//                   retrieval + capture-order neighbours for large ones)
//   match_pairs()   kNN matching with Lowe's ratio test and a mutual check, then
//                   RANSAC verification (essential / fundamental / homography);
//                   results cached under cache_dir/matches/.
//
// No OpenCV types here; OpenCV stays inside the .cpp files.
#include "core/cache_key.hpp"
#include "features/types.hpp"
#include "geometry/camera.hpp"

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace strata {

// An unordered pair of images to match, as indices into the layer's image list
// (first < second).
using ImagePair = std::pair<int, int>;

struct PairSelectionOptions {
  // Layers with at most this many photos are matched exhaustively (n(n-1)/2
  // pairs). Above it the scalable scheme below is used. >= 2.
  int exhaustive_limit = 60;
  // Scalable scheme, part 1: each photo is paired with the next
  // `sequence_neighbours` photos in capture order (a hand-held sweep overlaps
  // its neighbours). 0 disables.
  int sequence_neighbours = 8;
  // Scalable scheme, part 2: each photo is paired with the `retrieval_neighbours`
  // photos that share the most descriptor votes (see docs/features.md). 0 disables.
  int retrieval_neighbours = 15;
  // Descriptors per photo that take part in retrieval (the strongest keypoints).
  int retrieval_features = 400;
  // Nearest neighbours looked up per retrieval descriptor (each votes for the
  // photo it belongs to).
  int retrieval_knn = 8;
  // Preview (pre-emptive matching, Wu 2013 "Towards linear-time incremental
  // structure from motion"): in layers of at least `preview_min_images` photos
  // every candidate pair is first matched on the `preview_features` largest-scale
  // keypoints of each photo (ratio test + mutual check, exact), and goes on to
  // full matching only with >= `preview_min_matches` such matches. Pairs that do
  // not overlap (most of them in a large layer) cost a few milliseconds instead
  // of a full match. Smaller layers match every candidate fully.
  int preview_min_images = 20;
  int preview_features = 300;   // per photo; 0 disables the preview
  int preview_min_matches = 4;  // >= 1
  double preview_ratio = 0.8;   // Lowe's ratio on distances, in (0, 1]
  // After the preview, each photo keeps its `preview_best_per_photo` pairs with the
  // most preview matches; a pair goes on to full matching when either of its photos
  // keeps it. Bounds the pairs to about n k (linear in the photo count) where a
  // compact layer's photos all overlap. 0 keeps every pair that passes the preview.
  int preview_best_per_photo = 0;
  Unkeyed<int> num_threads = 0;  // 0 = all hardware threads

  void validate() const;  // throws InputError naming the field
};

struct PairSelectionSummary {
  std::size_t images = 0;
  std::size_t pairs = 0;
  bool exhaustive = true;         // false: sequence + retrieval scheme
  std::size_t sequence_pairs = 0; // pairs contributed by capture order
  std::size_t retrieval_pairs = 0;// pairs contributed by retrieval (not already sequence)
  bool previewed = false;         // the preview ran (see PairSelectionOptions)
  std::size_t candidate_pairs = 0;// pairs before the preview
  std::size_t preview_passed = 0; // pairs with enough preview matches (before preview_best_per_photo)
  double preview_seconds = 0;     // wall time of the preview
  double seconds = 0;
};

// Chooses the pairs to match. `images` is the output of extract_features();
// for the scalable scheme its features_key must point into cache_dir.
// capture_times (seconds, any epoch; optional, else input order is capture order)
// orders the photos for sequence neighbours. Returns sorted, unique pairs.
std::vector<ImagePair> select_pairs(const PairSelectionOptions& options,
                                    const std::vector<ImageKeypoints>& images,
                                    const std::filesystem::path& cache_dir,
                                    const std::vector<double>& capture_times = {},
                                    PairSelectionSummary* summary = nullptr);

struct VerificationOptions {
  enum class Method { ransac, magsac };
  // Robust estimator for the fundamental matrix (essential always uses RANSAC
  // with the 5-point solver): magsac = OpenCV USAC_MAGSAC (MAGSAC++).
  Method fundamental_method = Method::magsac;
  // Inlier threshold, in pixels of the original photo: Sampson/epipolar distance
  // for E and F, transfer error for H. For E it is divided by the focal length.
  double max_error_px = 4.0;
  double confidence = 0.9999;  // RANSAC confidence, in (0, 1)
  int max_iterations = 10000;  // RANSAC iterations cap, > 0
  // A verified pair needs at least this many inliers.
  int min_inliers = 30;
  // Without a focal prior: when a homography explains at least this fraction of
  // the fundamental-matrix inliers, F is ill-determined (planar scene or pure
  // rotation), the pair is recorded as `homography` and keeps the H inliers.
  double planar_ratio = 0.9;
};

struct MatchingOptions {
  enum class Matcher { flann, brute_force };
  // flann: randomised kd-trees (Muja & Lowe 2009), approximate but fast;
  // brute_force: exact L2, slower by about an order of magnitude.
  Matcher matcher = Matcher::flann;
  int flann_trees = 4;    // kd-trees in each index, > 0
  // Leaves visited per query, > 0: accuracy vs time. On 8000-keypoint photos 32
  // finds ~93 % of the inliers of 128, 64 ~97 %; a layer's pairs share hundreds of
  // inliers, and 32 left every camera figure of the full-size example and of
  // Strecha as it was in 0.72 x the matching time (docs/features.md).
  int flann_checks = 32;
  // Lowe's ratio test: keep a match when nearest distance < ratio x second
  // nearest (distances, not squared). In (0, 1].
  double ratio = 0.8;
  // Keep a match a->b only when b's best match in a is a (mutual nearest).
  bool mutual_check = true;
  VerificationOptions verification;
  Unkeyed<int> num_threads = 0;  // 0 = all hardware threads

  void validate() const;  // throws InputError naming the field
};

struct MatchingSummary {
  std::size_t pairs = 0;              // pairs requested
  std::size_t from_cache = 0;         // pairs whose result was read from the cache
  std::size_t verified = 0;           // pairs returned (>= min_inliers)
  std::size_t putative_matches = 0;   // after ratio + mutual check, over all pairs
  std::size_t inlier_matches = 0;     // over the returned pairs
  std::size_t essential = 0, fundamental = 0, homography = 0;  // returned pairs by model
  double seconds = 0;                 // wall time of the stage
  double cpu_seconds = 0;             // process CPU time over the stage (all threads)
  double matching_seconds = 0;        // wall time summed over pairs: kNN + filters
  double verification_seconds = 0;   // wall time summed over pairs: RANSAC
};

// Matches and verifies the given pairs. `images` must come from
// extract_features() with the same cache_dir (descriptors are read from it).
// priors[i] (optional, may be empty or shorter than images): calibration of
// image i; when both images of a pair have one with fx > 0, the essential
// matrix is estimated on undistorted normalised coordinates.
// Returns only the verified pairs, in the order of `pairs`.
std::vector<PairMatches> match_pairs(const MatchingOptions& options,
                                     const std::vector<ImageKeypoints>& images,
                                     const std::vector<ImagePair>& pairs,
                                     const std::vector<std::optional<Intrinsics>>& priors,
                                     const std::filesystem::path& cache_dir,
                                     MatchingSummary* summary = nullptr);

}  // namespace strata
