#include "sfm/tracks.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <numeric>
#include <unordered_map>

namespace strata {
namespace {

// Union-find with path halving and union by size.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : parent_(n), size_(n, 1) {
    std::iota(parent_.begin(), parent_.end(), std::size_t{0});
  }
  std::size_t find(std::size_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void unite(std::size_t a, std::size_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (size_[a] < size_[b]) std::swap(a, b);
    parent_[b] = a;
    size_[a] += size_[b];
  }

 private:
  std::vector<std::size_t> parent_;
  std::vector<std::size_t> size_;
};

}  // namespace

std::vector<std::vector<TrackElement>> build_tracks(const std::vector<ImageKeypoints>& keypoints,
                                                    const std::vector<PairMatches>& matches,
                                                    TrackStatistics* stats) {
  std::vector<std::size_t> offset(keypoints.size() + 1, 0);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    offset[i + 1] = offset[i] + keypoints[i].points.size();
  }
  DisjointSets sets(offset.back());
  std::vector<char> matched(offset.back(), 0);
  const int n_images = int(keypoints.size());
  for (const auto& pair : matches) {
    STRATA_CHECK(pair.image_a >= 0 && pair.image_a < n_images && pair.image_b >= 0 &&
                     pair.image_b < n_images && pair.image_a != pair.image_b,
                 "pair ({}, {}) out of range for {} images", pair.image_a, pair.image_b,
                 n_images);
    const int na = int(keypoints[pair.image_a].points.size());
    const int nb = int(keypoints[pair.image_b].points.size());
    for (const auto& [ka, kb] : pair.matches) {
      STRATA_CHECK(ka >= 0 && ka < na && kb >= 0 && kb < nb,
                   "match ({}, {}) out of range in pair ({}, {})", ka, kb, pair.image_a,
                   pair.image_b);
      const std::size_t a = offset[pair.image_a] + std::size_t(ka);
      const std::size_t b = offset[pair.image_b] + std::size_t(kb);
      sets.unite(a, b);
      matched[a] = matched[b] = 1;
    }
  }

  std::unordered_map<std::size_t, std::size_t> track_of_root;
  std::vector<std::vector<TrackElement>> tracks;
  for (int image = 0; image < n_images; ++image) {
    for (std::size_t k = 0; k < keypoints[image].points.size(); ++k) {
      const std::size_t node = offset[image] + k;
      if (!matched[node]) continue;
      const auto [it, inserted] = track_of_root.try_emplace(sets.find(node), tracks.size());
      if (inserted) tracks.emplace_back();
      tracks[it->second].push_back({image, int(k)});
    }
  }
  // Nodes were visited in image order, so each track is sorted by image already.
  TrackStatistics local;
  std::vector<std::vector<TrackElement>> kept;
  kept.reserve(tracks.size());
  for (auto& t : tracks) {
    bool consistent = t.size() >= 2;
    for (std::size_t i = 1; i < t.size() && consistent; ++i) {
      consistent = t[i].image != t[i - 1].image;
    }
    if (!consistent) {
      ++local.inconsistent_tracks;
      continue;
    }
    local.observations += t.size();
    kept.push_back(std::move(t));
  }
  local.tracks = kept.size();
  if (stats) *stats = local;
  return kept;
}

}  // namespace strata
