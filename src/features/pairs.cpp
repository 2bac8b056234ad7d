// Pair selection. Small layers: every pair. Large layers: capture-order
// neighbours plus a vocabulary-free image retrieval in which the strongest
// descriptors of every photo vote, through one shared kd-tree, for the photos
// holding their nearest neighbours (a flat "bag of nearest neighbours"; cost
// about n k log(n k) for n photos of k descriptors, so nearly linear in n).
#include "features/matching.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "core/resources.hpp"
#include "features/descriptor_store.hpp"
#include "core/parallel.hpp"

#include <opencv2/core.hpp>
#include <opencv2/flann.hpp>

#include <algorithm>
#include <limits>
#include <numeric>
#include <set>

namespace strata {
namespace {

ImagePair ordered(int a, int b) { return a < b ? ImagePair{a, b} : ImagePair{b, a}; }

// Symmetric similarity between photos from descriptor votes (n x n, row-major).
std::vector<float> retrieval_scores(const PairSelectionOptions& o,
                                    const std::vector<ImageKeypoints>& images,
                                    const std::filesystem::path& cache_dir) {
  const int n = static_cast<int>(images.size());
  std::vector<cv::Mat> subsets(n);
  parallel_for_index(n, o.num_threads, [&](std::size_t i) {
    check_cancelled();
    // Keypoints are stored strongest first: the first rows are the subset.
    subsets[i] = features::load_descriptors(cache_dir, images[i], o.retrieval_features);
  });
  cv::Mat all;
  std::vector<int> owner;  // image of each row of `all`
  for (int i = 0; i < n; ++i) {
    if (subsets[i].empty()) continue;
    all.push_back(subsets[i]);
    owner.insert(owner.end(), subsets[i].rows, i);
  }
  std::vector<float> score(static_cast<std::size_t>(n) * n, 0.f);
  if (all.rows < 2) return score;
  cv::flann::Index index(all, cv::flann::KDTreeIndexParams(4), cvflann::FLANN_DIST_L2);
  // +1: every descriptor finds itself first.
  const int k = std::min(o.retrieval_knn + 1, all.rows);

  parallel_for_index(n, o.num_threads, [&](std::size_t i) {
    check_cancelled();
    if (subsets[i].empty()) return;
    cv::Mat indices, dists;
    index.knnSearch(subsets[i], indices, dists, k, cv::flann::SearchParams(64));
    std::vector<int> hits;
    for (int r = 0; r < indices.rows; ++r) {
      hits.clear();
      for (int c = 0; c < k; ++c) {
        const int row = indices.at<int>(r, c);
        if (row < 0 || row >= static_cast<int>(owner.size())) continue;
        const int j = owner[row];
        if (j != static_cast<int>(i) && std::find(hits.begin(), hits.end(), j) == hits.end())
          hits.push_back(j);
      }
      // A descriptor whose neighbours spread over many photos (repetitive
      // texture: gravel, sieved soil) says less about any one of them.
      const float w = hits.empty() ? 0.f : 1.f / static_cast<float>(hits.size());
      for (int j : hits) score[i * n + j] += w;  // row i belongs to this task only
    }
  });
  std::vector<float> sym(score.size());
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) sym[i * n + j] = score[i * n + j] + score[j * n + i];
  return sym;
}

// Descriptors of one photo for the preview, with their squared norms.
struct PreviewSet {
  cv::Mat descriptors;  // CV_32F rows
  std::vector<float> norm2;
};

// Mutual nearest neighbours passing the ratio test between two small descriptor
// sets, exactly: one matrix product gives every squared distance
// |a|^2 + |b|^2 - 2 a.b.
int preview_matches(const PreviewSet& a, const PreviewSet& b, float ratio2) {
  const int na = a.descriptors.rows, nb = b.descriptors.rows;
  if (na < 2 || nb < 2) return 0;
  cv::Mat dot;
  cv::gemm(a.descriptors, b.descriptors, 1.0, cv::noArray(), 0.0, dot, cv::GEMM_2_T);
  constexpr float kInf = std::numeric_limits<float>::max();
  std::vector<float> col_d1(nb, kInf), col_d2(nb, kInf);
  std::vector<int> col_best(nb, -1);
  std::vector<float> row_d1(na, kInf), row_d2(na, kInf);
  std::vector<int> row_best(na, -1);
  for (int i = 0; i < na; ++i) {
    const float* g = dot.ptr<float>(i);
    for (int j = 0; j < nb; ++j) {
      const float d = a.norm2[i] + b.norm2[j] - 2.f * g[j];
      if (d < row_d1[i]) {
        row_d2[i] = row_d1[i];
        row_d1[i] = d;
        row_best[i] = j;
      } else if (d < row_d2[i]) {
        row_d2[i] = d;
      }
      if (d < col_d1[j]) {
        col_d2[j] = col_d1[j];
        col_d1[j] = d;
        col_best[j] = i;
      } else if (d < col_d2[j]) {
        col_d2[j] = d;
      }
    }
  }
  int count = 0;
  for (int i = 0; i < na; ++i) {
    const int j = row_best[i];
    if (j < 0 || col_best[j] != i) continue;
    if (row_d1[i] < ratio2 * row_d2[i] && col_d1[j] < ratio2 * col_d2[j]) ++count;
  }
  return count;
}

// Of the pairs in `passed`, those among the k with the most preview matches of
// either of their photos (ties: the lower photo index first, so the choice does not
// depend on thread timing).
std::set<ImagePair> best_per_photo(const std::vector<ImagePair>& list, const std::vector<int>& counts,
                                   const std::set<ImagePair>& passed, int n, int k) {
  std::vector<std::vector<std::pair<int, int>>> of(n);  // per photo: (count, other photo)
  for (std::size_t p = 0; p < list.size(); ++p) {
    if (!passed.count(list[p])) continue;
    of[list[p].first].push_back({counts[p], list[p].second});
    of[list[p].second].push_back({counts[p], list[p].first});
  }
  std::set<ImagePair> kept;
  for (int i = 0; i < n; ++i) {
    auto& v = of[i];
    const std::size_t keep = std::min<std::size_t>(k, v.size());
    std::partial_sort(v.begin(), v.begin() + keep, v.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    for (std::size_t r = 0; r < keep; ++r) kept.insert(ordered(i, v[r].second));
  }
  return kept;
}

// Keeps the candidate pairs whose preview finds enough matches.
std::set<ImagePair> preview_pairs(const PairSelectionOptions& o,
                                  const std::vector<ImageKeypoints>& images,
                                  const std::filesystem::path& cache_dir,
                                  const std::set<ImagePair>& candidates, std::size_t* passed) {
  const int n = static_cast<int>(images.size());
  std::vector<PreviewSet> sets(n);
  parallel_for_index(n, o.num_threads, [&](std::size_t i) {
    check_cancelled();
    auto& s = sets[i];
    s.descriptors =
        features::load_largest_scale_descriptors(cache_dir, images[i], o.preview_features);
    s.norm2.resize(s.descriptors.rows);
    for (int r = 0; r < s.descriptors.rows; ++r) {
      const cv::Mat row = s.descriptors.row(r);
      s.norm2[r] = static_cast<float>(row.dot(row));
    }
  });
  const std::vector<ImagePair> list(candidates.begin(), candidates.end());
  std::vector<int> counts(list.size(), 0);
  const float ratio2 = static_cast<float>(o.preview_ratio * o.preview_ratio);
  parallel_for_index(list.size(), o.num_threads, [&](std::size_t p) {
    if (p % 64 == 0) check_cancelled();
    counts[p] = preview_matches(sets[list[p].first], sets[list[p].second], ratio2);
  });
  std::set<ImagePair> kept;
  for (std::size_t p = 0; p < list.size(); ++p)
    if (counts[p] >= o.preview_min_matches) kept.insert(list[p]);
  *passed = kept.size();
  if (o.preview_best_per_photo > 0) kept = best_per_photo(list, counts, kept, n, o.preview_best_per_photo);
  return kept;
}

}  // namespace

void PairSelectionOptions::validate() const {
  auto fail = [](const char* field, const std::string& why) {
    throw InputError(fmt::format("pair selection: option {} {}", field, why));
  };
  if (exhaustive_limit < 2)
    fail("exhaustive_limit", fmt::format("must be >= 2 (got {})", exhaustive_limit));
  if (sequence_neighbours < 0)
    fail("sequence_neighbours", fmt::format("must be >= 0 (got {})", sequence_neighbours));
  if (retrieval_neighbours < 0)
    fail("retrieval_neighbours", fmt::format("must be >= 0 (got {})", retrieval_neighbours));
  if (sequence_neighbours == 0 && retrieval_neighbours == 0)
    fail("sequence_neighbours",
         "and retrieval_neighbours are both 0: large layers would get no pairs");
  if (retrieval_features <= 0)
    fail("retrieval_features", fmt::format("must be > 0 (got {})", retrieval_features));
  if (retrieval_knn <= 0) fail("retrieval_knn", fmt::format("must be > 0 (got {})", retrieval_knn));
  if (preview_min_images < 2)
    fail("preview_min_images", fmt::format("must be >= 2 (got {})", preview_min_images));
  if (preview_features < 0)
    fail("preview_features", fmt::format("must be >= 0 (got {})", preview_features));
  if (preview_min_matches < 1)
    fail("preview_min_matches", fmt::format("must be >= 1 (got {})", preview_min_matches));
  if (preview_best_per_photo < 0)
    fail("preview_best_per_photo", fmt::format("must be >= 0 (got {})", preview_best_per_photo));
  if (!(preview_ratio > 0 && preview_ratio <= 1))
    fail("preview_ratio", fmt::format("must be in (0, 1] (got {})", preview_ratio));
  if (num_threads < 0) fail("num_threads", fmt::format("must be >= 0 (got {})", num_threads));
}

std::vector<ImagePair> select_pairs(const PairSelectionOptions& options,
                                    const std::vector<ImageKeypoints>& images,
                                    const std::filesystem::path& cache_dir,
                                    const std::vector<double>& capture_times,
                                    PairSelectionSummary* summary) {
  options.validate();
  Stopwatch clock;
  const int n = static_cast<int>(images.size());
  if (!capture_times.empty() && capture_times.size() != images.size()) {
    throw InputError(fmt::format("pair selection: {} capture times for {} images",
                                 capture_times.size(), images.size()));
  }
  PairSelectionSummary s;
  s.images = images.size();
  std::set<ImagePair> pairs;

  if (n <= options.exhaustive_limit) {
    for (int a = 0; a < n; ++a)
      for (int b = a + 1; b < n; ++b) pairs.insert({a, b});
  } else {
    s.exhaustive = false;
    // Capture order (stable: equal times keep input order).
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    if (!capture_times.empty()) {
      std::stable_sort(order.begin(), order.end(),
                       [&](int a, int b) { return capture_times[a] < capture_times[b]; });
    }
    for (int p = 0; p < n; ++p)
      for (int q = p + 1; q <= std::min(n - 1, p + options.sequence_neighbours); ++q)
        pairs.insert(ordered(order[p], order[q]));
    s.sequence_pairs = pairs.size();

    if (options.retrieval_neighbours > 0) {
      STRATA_CHECK(!cache_dir.empty(), "retrieval needs the features cache folder");
      const std::vector<float> score = retrieval_scores(options, images, cache_dir);
      std::vector<int> candidates;
      for (int i = 0; i < n; ++i) {
        candidates.clear();
        for (int j = 0; j < n; ++j)
          if (j != i && score[i * n + j] > 0) candidates.push_back(j);
        const int keep = std::min<int>(options.retrieval_neighbours, candidates.size());
        std::partial_sort(candidates.begin(), candidates.begin() + keep, candidates.end(),
                          [&](int a, int b) {
                            const float sa = score[i * n + a], sb = score[i * n + b];
                            return sa != sb ? sa > sb : a < b;
                          });
        for (int r = 0; r < keep; ++r) pairs.insert(ordered(i, candidates[r]));
      }
      s.retrieval_pairs = pairs.size() - s.sequence_pairs;
    }
  }
  s.candidate_pairs = pairs.size();
  if (options.preview_features > 0 && n >= options.preview_min_images) {
    STRATA_CHECK(!cache_dir.empty(), "the pair preview needs the features cache folder");
    Stopwatch preview_clock;
    pairs = preview_pairs(options, images, cache_dir, pairs, &s.preview_passed);
    s.previewed = true;
    s.preview_seconds = preview_clock.seconds();
    log::info("pair preview: {} of {} candidate pairs share >= {} of their {} largest-scale "
              "features{}, {:.1f} s",
              s.preview_passed, s.candidate_pairs, options.preview_min_matches, options.preview_features,
              options.preview_best_per_photo > 0
                  ? fmt::format("; {} among the {} best of a photo", pairs.size(), options.preview_best_per_photo)
                  : std::string(),
              s.preview_seconds);
  }
  std::vector<ImagePair> out(pairs.begin(), pairs.end());
  s.pairs = out.size();
  s.seconds = clock.seconds();
  log::info("pair selection: {} images, {} pairs ({}), {:.1f} s", s.images, s.pairs,
            s.exhaustive ? "exhaustive"
                         : fmt::format("{} by capture order, {} by retrieval", s.sequence_pairs,
                                       s.retrieval_pairs),
            s.seconds);
  if (summary) *summary = s;
  return out;
}

}  // namespace strata
