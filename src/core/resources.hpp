#pragma once
// Time and memory figures that every reconstruction records.
#include <chrono>
#include <cstdint>

namespace strata {

// Peak resident set size of this process so far, in bytes (VmHWM).
std::int64_t peak_memory_bytes();

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
