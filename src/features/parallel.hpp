#pragma once
// Internal to the features module: run fn(i) for i in [0, n) on a bounded number
// of TBB worker threads (within strata --threads). OpenCV on Debian is built on TBB
// too, so its own parallel loops inside fn share the same arena instead of
// oversubscribing. The first exception thrown by fn propagates to the caller.
#include "core/resources.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cstddef>

namespace strata::features {

template <typename Fn>
void parallel_for_index(std::size_t n, int num_threads, Fn&& fn) {
  if (n == 0) return;
  tbb::task_arena arena(allowed_threads(num_threads));
  arena.execute([&] {
    // grain 1: one image or one pair is already seconds of work.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) fn(i);
                      });
  });
}

}  // namespace strata::features
