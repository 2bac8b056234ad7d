#include "features/matching.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "features/cache_io.hpp"
#include "features/descriptor_store.hpp"
#include "core/parallel.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>

#include <algorithm>
#include <ctime>
#include <atomic>
#include <memory>
#include <mutex>

namespace strata {
namespace {

// Bump when matching or verification changes its output (cache invalidation).
constexpr int kMatchingVersion = 2;  // 2: FLANN trees from a fixed seed

// The start of the random generator for every FLANN index (any fixed value).
constexpr std::uint64_t kFlannSeed = 0x5eed'f1a2'2026ULL;

// Descriptors of one image plus, for FLANN, a kd-tree index over them, built
// once and queried by every pair the image takes part in.
struct ImageDescriptors {
  cv::Mat descriptors;  // CV_32F; kept alive: the FLANN index points into it
  std::unique_ptr<cv::flann::Index> index;
};

// Best and second-best neighbour of some query rows in the train set.
struct Knn2 {
  std::vector<int> best;        // train row, -1 when fewer than 2 neighbours
  std::vector<float> d1, d2;    // squared L2 distances
};

// rows: the query rows to search (all when empty).
Knn2 knn2(const MatchingOptions& o, const ImageDescriptors& query,
          const ImageDescriptors& train, const std::vector<int>& rows = {}) {
  cv::Mat q = query.descriptors;
  if (!rows.empty()) {
    q = cv::Mat(static_cast<int>(rows.size()), query.descriptors.cols, CV_32F);
    for (std::size_t r = 0; r < rows.size(); ++r)
      query.descriptors.row(rows[r]).copyTo(q.row(static_cast<int>(r)));
  }
  const int n = q.rows;
  Knn2 r;
  r.best.assign(n, -1);
  r.d1.assign(n, 0.f);
  r.d2.assign(n, 0.f);
  if (n == 0 || train.descriptors.rows < 2) return r;
  if (o.matcher == MatchingOptions::Matcher::flann) {
    cv::Mat indices, dists;
    // KD-tree search keeps its heap and visited set per call: concurrent queries
    // on one index are safe.
    train.index->knnSearch(q, indices, dists, 2, cv::flann::SearchParams(o.flann_checks));
    for (int i = 0; i < n; ++i) {
      r.best[i] = indices.at<int>(i, 0);
      r.d1[i] = dists.at<float>(i, 0);  // FLANN L2 reports squared distances
      r.d2[i] = dists.at<float>(i, 1);
    }
  } else {
    cv::BFMatcher matcher(cv::NORM_L2);
    std::vector<std::vector<cv::DMatch>> m;
    matcher.knnMatch(q, train.descriptors, m, 2);
    for (int i = 0; i < n; ++i) {
      if (m[i].size() < 2) continue;
      r.best[i] = m[i][0].trainIdx;
      r.d1[i] = m[i][0].distance * m[i][0].distance;
      r.d2[i] = m[i][1].distance * m[i][1].distance;
    }
  }
  return r;
}

// Ratio test (Lowe 2004, sec. 7.1) in both directions and the mutual check.
std::vector<std::pair<int, int>> putative_matches(const MatchingOptions& o,
                                                  const ImageDescriptors& a,
                                                  const ImageDescriptors& b) {
  const float ratio2 = static_cast<float>(o.ratio * o.ratio);  // distances are squared
  auto passes = [&](const Knn2& k, int i) {
    return k.best[i] >= 0 && k.d1[i] < ratio2 * k.d2[i];
  };
  const Knn2 ab = knn2(o, a, b);
  std::vector<std::pair<int, int>> out;
  for (int i = 0; i < static_cast<int>(ab.best.size()); ++i)
    if (passes(ab, i)) out.emplace_back(i, ab.best[i]);
  if (!o.mutual_check) {
    // Without the mutual check several a may claim one b: keep the closest.
    std::vector<int> owner(b.descriptors.rows, -1);
    for (const auto& [i, j] : out)
      if (owner[j] < 0 || ab.d1[i] < ab.d1[owner[j]]) owner[j] = i;
    std::erase_if(out, [&](const auto& m) { return owner[m.second] != m.first; });
    return out;
  }
  // Reverse search only for the b rows that a claimed (typically a fifth of b):
  // the mutual check needs nothing else, and it halves the matching time.
  if (out.empty()) return out;
  std::vector<int> claimed;
  for (const auto& m : out) claimed.push_back(m.second);
  std::sort(claimed.begin(), claimed.end());
  claimed.erase(std::unique(claimed.begin(), claimed.end()), claimed.end());
  const Knn2 ba = knn2(o, b, a, claimed);
  std::erase_if(out, [&](const auto& m) {
    const int r = static_cast<int>(std::lower_bound(claimed.begin(), claimed.end(), m.second) -
                                   claimed.begin());
    return !(passes(ba, r) && ba.best[r] == m.first);
  });
  return out;
}

std::vector<cv::Point2d> to_cv(const std::vector<Eigen::Vector2d>& p) {
  std::vector<cv::Point2d> out;
  out.reserve(p.size());
  for (const auto& x : p) out.emplace_back(x.x(), x.y());
  return out;
}

bool has_focal(const std::optional<Intrinsics>& k) { return k && k->fx > 0 && k->fy > 0; }

// RANSAC verification (Hartley & Zisserman ch. 11; Nister 2004 for E).
features::StoredMatches verify(const VerificationOptions& o, const ImageKeypoints& a,
                               const ImageKeypoints& b,
                               const std::vector<std::pair<int, int>>& putative,
                               const std::optional<Intrinsics>& ka,
                               const std::optional<Intrinsics>& kb) {
  features::StoredMatches out;
  out.putative = static_cast<int>(putative.size());
  if (out.putative < o.min_inliers) return out;

  std::vector<Eigen::Vector2d> pa, pb;
  pa.reserve(putative.size());
  pb.reserve(putative.size());
  for (const auto& [i, j] : putative) {
    pa.push_back(a.points[i]);
    pb.push_back(b.points[j]);
  }
  const auto cva = to_cv(pa), cvb = to_cv(pb);

  std::vector<std::uint8_t> mask;
  TwoViewModel model = TwoViewModel::none;
  if (has_focal(ka) && has_focal(kb)) {
    std::vector<Eigen::Vector2d> na, nb;
    na.reserve(pa.size());
    nb.reserve(pb.size());
    for (std::size_t m = 0; m < pa.size(); ++m) {
      na.push_back(ka->to_normalised(pa[m]));
      nb.push_back(kb->to_normalised(pb[m]));
    }
    // Pixel threshold to normalised units by the mean focal length.
    const double focal = 0.25 * (ka->fx + ka->fy + kb->fx + kb->fy);
    const cv::Mat E = cv::findEssentialMat(to_cv(na), to_cv(nb), cv::Mat::eye(3, 3, CV_64F),
                                           cv::RANSAC, o.confidence, o.max_error_px / focal,
                                           o.max_iterations, mask);
    if (!E.empty()) model = TwoViewModel::essential;
  } else {
    const int method = o.fundamental_method == VerificationOptions::Method::magsac
                           ? static_cast<int>(cv::USAC_MAGSAC)
                           : static_cast<int>(cv::FM_RANSAC);
    const cv::Mat F = cv::findFundamentalMat(cva, cvb, method, o.max_error_px, o.confidence,
                                             o.max_iterations, mask);
    if (!F.empty()) model = TwoViewModel::fundamental;
  }
  if (model == TwoViewModel::none || mask.size() != putative.size()) return out;

  std::vector<int> inliers;
  for (std::size_t m = 0; m < mask.size(); ++m)
    if (mask[m]) inliers.push_back(static_cast<int>(m));
  if (static_cast<int>(inliers.size()) < o.min_inliers) return out;

  // Homography among the inliers: the planarity / pure-rotation test.
  std::vector<cv::Point2d> ia, ib;
  for (int m : inliers) {
    ia.push_back(cva[m]);
    ib.push_back(cvb[m]);
  }
  std::vector<std::uint8_t> hmask;
  const cv::Mat H = cv::findHomography(ia, ib, cv::RANSAC, o.max_error_px, hmask,
                                       o.max_iterations, o.confidence);
  int h_inliers = 0;
  if (!H.empty() && hmask.size() == inliers.size())
    for (auto v : hmask) h_inliers += v ? 1 : 0;

  if (model == TwoViewModel::fundamental &&
      h_inliers >= o.planar_ratio * static_cast<double>(inliers.size())) {
    // F is not determined by a plane (a 2-parameter family fits): outliers that
    // lie on some epipolar line slip through. The homography is the sound model.
    model = TwoViewModel::homography;
    std::vector<int> kept;
    for (std::size_t m = 0; m < inliers.size(); ++m)
      if (hmask[m]) kept.push_back(inliers[m]);
    inliers.swap(kept);
    if (static_cast<int>(inliers.size()) < o.min_inliers) return out;
  }

  out.model = model;
  out.homography_inliers = h_inliers;
  out.matches.reserve(inliers.size());
  for (int m : inliers) out.matches.push_back(putative[m]);
  return out;
}

}  // namespace

void MatchingOptions::validate() const {
  auto fail = [](const char* field, const std::string& why) {
    throw InputError(fmt::format("matching: option {} {}", field, why));
  };
  if (flann_trees <= 0) fail("flann_trees", fmt::format("must be > 0 (got {})", flann_trees));
  if (flann_checks <= 0)
    fail("flann_checks", fmt::format("must be > 0 (got {})", flann_checks));
  if (!(ratio > 0 && ratio <= 1)) fail("ratio", fmt::format("must be in (0, 1] (got {})", ratio));
  if (num_threads < 0) fail("num_threads", fmt::format("must be >= 0 (got {})", num_threads));
  const auto& v = verification;
  if (!(v.max_error_px > 0))
    fail("verification.max_error_px", fmt::format("must be > 0 pixels (got {})", v.max_error_px));
  if (!(v.confidence > 0 && v.confidence < 1))
    fail("verification.confidence", fmt::format("must be in (0, 1) (got {})", v.confidence));
  if (v.max_iterations <= 0)
    fail("verification.max_iterations", fmt::format("must be > 0 (got {})", v.max_iterations));
  if (v.min_inliers < 8)
    fail("verification.min_inliers",
         fmt::format("must be >= 8, the points an F or H fit needs (got {})", v.min_inliers));
  if (!(v.planar_ratio > 0 && v.planar_ratio <= 1))
    fail("verification.planar_ratio", fmt::format("must be in (0, 1] (got {})", v.planar_ratio));
}

namespace {

void check_pairs(const std::vector<ImagePair>& pairs, int n) {
  for (const auto& [a, b] : pairs) {
    if (a < 0 || b < 0 || a >= n || b >= n || a == b) {
      throw InputError(
          fmt::format("matching: pair ({}, {}) is not two distinct images of {}", a, b, n));
    }
  }
}

// The cache key of a pair's matches: the options, both images' features and their
// calibration priors.
struct PairKeys {
  const MatchingOptions& options;
  const std::vector<ImageKeypoints>& images;
  const std::vector<std::optional<Intrinsics>>& priors;

  // A prior without a focal length is no prior.
  std::optional<Intrinsics> prior(int i) const {
    return i < static_cast<int>(priors.size()) && has_focal(priors[i]) ? priors[i] : std::nullopt;
  }
  std::string key(int a, int b) const {
    return CacheKey(fmt::format("matches v{}", kMatchingVersion))
        .add(options)
        .add(images[a].features_key)
        .add(images[b].features_key)
        .add(prior(a))
        .add(prior(b))
        .hex();
  }
};

// The matches of each pair as far as the cache holds them, and the pairs left to match.
struct CachedPairs {
  std::vector<std::optional<features::StoredMatches>> results;  // per pair
  std::vector<std::size_t> todo;                                 // pairs not in the cache
  std::vector<char> needed;                                      // per image: descriptors needed
};

CachedPairs read_cached_pairs(const std::vector<ImagePair>& pairs, int n, const PairKeys& keys,
                              const std::filesystem::path& cache_dir) {
  CachedPairs c;
  c.results.resize(pairs.size());
  c.needed.assign(n, 0);
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const auto [a, b] = pairs[p];
    c.results[p] = features::read_matches(features::matches_file(cache_dir, keys.key(a, b)));
    if (!c.results[p]) {
      c.todo.push_back(p);
      c.needed[a] = c.needed[b] = 1;
    }
  }
  return c;
}

// The descriptors of the images marked needed, with their FLANN index.
std::vector<ImageDescriptors> load_needed_descriptors(const MatchingOptions& options,
                                                      const std::vector<ImageKeypoints>& images,
                                                      const std::vector<char>& needed,
                                                      const std::filesystem::path& cache_dir) {
  const int n = static_cast<int>(images.size());
  std::vector<int> needed_list;
  for (int i = 0; i < n; ++i)
    if (needed[i]) needed_list.push_back(i);
  std::vector<ImageDescriptors> descriptors(n);
  parallel_for_index(needed_list.size(), options.num_threads, [&](std::size_t k) {
    check_cancelled();
    const int i = needed_list[k];
    auto& d = descriptors[i];
    d.descriptors = features::load_descriptors(cache_dir, images[i]);
    if (options.matcher == MatchingOptions::Matcher::flann && d.descriptors.rows >= 2) {
      // FLANN's randomised kd-trees draw from OpenCV's per-thread generator; which
      // worker builds which image's index (and what it drew before) depends on the
      // scheduling, so without a fixed start the trees, the approximate neighbours
      // and in the end the reconstruction changed from run to run and machine to
      // machine. Every index starts from the same state.
      cv::theRNG() = cv::RNG(kFlannSeed);
      d.index = std::make_unique<cv::flann::Index>(
          d.descriptors, cv::flann::KDTreeIndexParams(options.flann_trees),
          cvflann::FLANN_DIST_L2);
    }
  });
  return descriptors;
}

struct MatchingTimes {
  double matching_seconds = 0, verification_seconds = 0;  // summed over pairs
};

// Matches and verifies the pairs not in the cache, and writes them to it.
MatchingTimes match_uncached(const MatchingOptions& options, const std::vector<ImageKeypoints>& images,
                             const std::vector<ImagePair>& pairs, const PairKeys& keys,
                             const std::vector<ImageDescriptors>& descriptors,
                             const std::filesystem::path& cache_dir, CachedPairs& c) {
  std::mutex time_mutex;
  MatchingTimes times;
  Progress progress("matching", c.todo.size());
  parallel_for_index(c.todo.size(), options.num_threads, [&](std::size_t k) {
    check_cancelled();
    const std::size_t p = c.todo[k];
    const auto [a, b] = pairs[p];
    Stopwatch t_match;
    const auto putative = putative_matches(options, descriptors[a], descriptors[b]);
    const double dt_match = t_match.seconds();
    Stopwatch t_verify;
    auto verified = verify(options.verification, images[a], images[b], putative, keys.prior(a),
                           keys.prior(b));
    const double dt_verify = t_verify.seconds();
    features::write_matches(features::matches_file(cache_dir, keys.key(a, b)), verified);
    fault::point("process.matching.pair_done");
    c.results[p] = std::move(verified);
    {
      std::lock_guard lock(time_mutex);
      times.matching_seconds += dt_match;
      times.verification_seconds += dt_verify;
    }
    progress.step();
  });
  progress.finish();
  return times;
}

// The verified pairs, counted by model in `s`.
std::vector<PairMatches> verified_pairs(const std::vector<ImagePair>& pairs,
                                        std::vector<std::optional<features::StoredMatches>>& results,
                                        MatchingSummary& s) {
  std::vector<PairMatches> out;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    auto& r = *results[p];
    s.putative_matches += static_cast<std::size_t>(r.putative);
    if (r.model == TwoViewModel::none) continue;
    PairMatches m;
    m.image_a = pairs[p].first;
    m.image_b = pairs[p].second;
    m.model = r.model;
    m.homography_inliers = r.homography_inliers;
    m.matches = std::move(r.matches);
    s.inlier_matches += m.matches.size();
    ++s.verified;
    switch (m.model) {
      case TwoViewModel::essential: ++s.essential; break;
      case TwoViewModel::fundamental: ++s.fundamental; break;
      case TwoViewModel::homography: ++s.homography; break;
      case TwoViewModel::none: break;
    }
    out.push_back(std::move(m));
  }
  return out;
}

}  // namespace

std::vector<PairMatches> match_pairs(const MatchingOptions& options,
                                     const std::vector<ImageKeypoints>& images,
                                     const std::vector<ImagePair>& pairs,
                                     const std::vector<std::optional<Intrinsics>>& priors,
                                     const std::filesystem::path& cache_dir,
                                     MatchingSummary* summary) {
  options.validate();
  STRATA_CHECK(!cache_dir.empty(), "match_pairs needs the features cache folder");
  Stopwatch clock;
  const std::clock_t cpu_start = std::clock();
  const int n = static_cast<int>(images.size());
  check_pairs(pairs, n);
  const PairKeys keys{options, images, priors};

  // Cached results first: only the images of uncached pairs need descriptors.
  CachedPairs cached = read_cached_pairs(pairs, n, keys, cache_dir);
  const std::size_t from_cache = pairs.size() - cached.todo.size();
  const std::vector<ImageDescriptors> descriptors = load_needed_descriptors(options, images, cached.needed, cache_dir);
  const MatchingTimes times = match_uncached(options, images, pairs, keys, descriptors, cache_dir, cached);

  MatchingSummary s;
  s.pairs = pairs.size();
  s.from_cache = from_cache;
  s.matching_seconds = times.matching_seconds;
  s.verification_seconds = times.verification_seconds;
  std::vector<PairMatches> out = verified_pairs(pairs, cached.results, s);
  s.seconds = clock.seconds();
  s.cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  log::info("matching: {} pairs ({} from cache), {} verified ({} E, {} F, {} H), {} inliers, "
            "{:.1f} s ({:.1f} s CPU; summed over pairs: {:.1f} s kNN, {:.1f} s RANSAC)",
            s.pairs, s.from_cache, s.verified, s.essential, s.fundamental, s.homography,
            s.inlier_matches, s.seconds, s.cpu_seconds, s.matching_seconds,
            s.verification_seconds);
  if (summary) *summary = s;
  return out;
}

}  // namespace strata
