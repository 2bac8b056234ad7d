#pragma once
// Union-find over 0..n-1 with path halving; a union hangs the larger root under the
// smaller, so the roots do not depend on the order of unions and no rank array is
// needed (one index per element: the fused band numbers tens of millions of voxels).
#include <cstddef>
#include <numeric>
#include <utility>
#include <vector>

namespace strata {

template <class Index = std::size_t>
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), Index{0}); }

  Index find(Index x) {
    while (parent_[static_cast<std::size_t>(x)] != x) {
      auto& p = parent_[static_cast<std::size_t>(x)];
      p = parent_[static_cast<std::size_t>(p)];
      x = p;
    }
    return x;
  }

  // True when a and b were in different sets.
  bool unite(Index a, Index b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (b < a) std::swap(a, b);
    parent_[static_cast<std::size_t>(b)] = a;
    return true;
  }

  std::size_t size() const { return parent_.size(); }

 private:
  std::vector<Index> parent_;
};

}  // namespace strata
