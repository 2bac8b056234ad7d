#include "core/parallel.hpp"

#include "core/resources.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace strata {

void parallel_for_index(std::size_t n, int threads, const std::function<void(std::size_t)>& fn) {
  if (n == 0) return;
  with_threads(threads, [&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) fn(i);
    });
  });
}

void with_threads(int threads, const std::function<void()>& fn) {
  tbb::task_arena arena(allowed_threads(threads));
  arena.execute(fn);
}

}  // namespace strata
