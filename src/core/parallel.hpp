#pragma once
// strata's one way to run work in parallel: TBB, within the process's thread limit
// (strata --threads, core/resources.hpp). OpenCV on Debian is built on TBB too, so
// its own parallel loops inside the work share the same arena instead of
// oversubscribing the cores.
#include <cstddef>
#include <functional>

namespace strata {

// Runs fn(i) for i in [0, n) on at most `threads` workers (0 = as many as allowed),
// one index at a time per worker (each is seconds of work: a photo, a pair, a view).
// The first exception thrown by fn propagates to the caller.
void parallel_for_index(std::size_t n, int threads, const std::function<void(std::size_t)>& fn);

// Runs fn with every TBB loop inside it limited to `threads` workers (0 = as many as
// allowed).
void with_threads(int threads, const std::function<void()>& fn);

}  // namespace strata
