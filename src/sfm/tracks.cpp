#include "sfm/tracks.hpp"

#include "core/disjoint_sets.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <iterator>
#include <numeric>
#include <unordered_map>

namespace strata {
namespace {

}  // namespace

namespace {

using Edge = std::pair<std::size_t, std::size_t>;

// Groups the matched nodes by component; a component is consistent when no image
// appears twice in it. Nodes are visited in (image, keypoint) order, so every
// component comes out sorted by image.
void collect_components(DisjointSets<>& sets, const std::vector<char>& active,
                        const std::vector<std::size_t>& offset,
                        std::vector<std::vector<TrackElement>>& consistent,
                        std::vector<std::vector<std::size_t>>& inconsistent) {
  std::unordered_map<std::size_t, std::size_t> index_of_root;
  std::vector<std::vector<std::size_t>> components;
  for (std::size_t node = 0; node < active.size(); ++node) {
    if (!active[node]) continue;
    const auto [it, inserted] = index_of_root.try_emplace(sets.find(node), components.size());
    if (inserted) components.emplace_back();
    components[it->second].push_back(node);
  }
  for (auto& c : components) {
    std::vector<TrackElement> t;
    bool ok = c.size() >= 2;
    for (std::size_t node : c) {
      const int image = int(std::upper_bound(offset.begin(), offset.end(), node) - offset.begin()) - 1;
      if (!t.empty() && t.back().image == image) ok = false;
      t.push_back({image, int(node - offset[image])});
    }
    if (ok) {
      consistent.push_back(std::move(t));
    } else {
      inconsistent.push_back(std::move(c));
    }
  }
}

}  // namespace

std::vector<std::vector<TrackElement>> build_tracks(const std::vector<ImageKeypoints>& keypoints,
                                                    const std::vector<PairMatches>& matches,
                                                    TrackStatistics* stats) {
  std::vector<std::size_t> offset(keypoints.size() + 1, 0);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    offset[i + 1] = offset[i] + keypoints[i].points.size();
  }
  DisjointSets<> sets(offset.back());
  std::vector<char> matched(offset.back(), 0);
  std::vector<Edge> edges;
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
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  }

  std::vector<std::vector<TrackElement>> kept;
  std::vector<std::vector<std::size_t>> conflicts;
  collect_components(sets, matched, offset, kept, conflicts);
  TrackStatistics local;
  const std::size_t first_pass = kept.size();

  // Repair: a conflicting component is usually several true tracks glued together by
  // a few wrong matches. A true match in a track seen by n images closes n - 2
  // triangles of the match graph; a wrong one closes almost none. Keep only the
  // edges of conflicting components that close at least one triangle and split again;
  // what still conflicts is dropped.
  if (!conflicts.empty()) {
    std::vector<char> in_conflict(offset.back(), 0);
    for (const auto& c : conflicts) {
      for (std::size_t node : c) in_conflict[node] = 1;
    }
    std::unordered_map<std::size_t, std::vector<std::size_t>> adjacent;
    std::vector<Edge> candidate;
    for (const auto& e : edges) {
      if (!in_conflict[e.first]) continue;
      adjacent[e.first].push_back(e.second);
      adjacent[e.second].push_back(e.first);
      candidate.push_back(e);
    }
    for (auto& [node, list] : adjacent) {
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
    }
    DisjointSets<> repaired(offset.back());
    std::vector<char> active(offset.back(), 0);
    std::vector<std::size_t> common;
    for (const auto& [a, b] : candidate) {
      const auto& la = adjacent[a];
      const auto& lb = adjacent[b];
      common.clear();
      std::set_intersection(la.begin(), la.end(), lb.begin(), lb.end(), std::back_inserter(common));
      if (common.empty()) continue;
      repaired.unite(a, b);
      active[a] = active[b] = 1;
    }
    std::vector<std::vector<std::size_t>> still;
    collect_components(repaired, active, offset, kept, still);
    local.repaired_tracks = kept.size() - first_pass;
    local.inconsistent_tracks = conflicts.size();
  }
  for (const auto& t : kept) local.observations += t.size();
  local.tracks = kept.size();
  if (stats) *stats = local;
  return kept;
}

}  // namespace strata
