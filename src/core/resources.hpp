#pragma once
// Time and memory figures that every reconstruction records, and the cores it may use.
#include <chrono>
#include <cstdint>

namespace strata {

// Peak resident set size of this process so far, in bytes (VmHWM).
std::int64_t peak_memory_bytes();

// The most threads this process runs at once (strata --threads): every TBB loop, the
// stages' worker pools and the bundle adjustments keep within it. 0 lifts the limit
// (all cores). Throws InputError below 0.
void set_thread_limit(int threads);
// `requested` threads (0 = as many as allowed), within the limit; without a limit, 0
// means the number of hardware threads (at least 1).
int allowed_threads(int requested);

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace strata
