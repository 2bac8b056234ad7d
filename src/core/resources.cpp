#include "core/resources.hpp"

#include "core/error.hpp"

#include <fmt/format.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

namespace strata {

std::int64_t peak_memory_bytes() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      std::int64_t kib = 0;
      status >> kib;
      return kib * 1024;
    }
    std::getline(status, key);
  }
  return 0;
}

namespace {

int hardware_threads() {
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : static_cast<int>(hw);
}

// Set once by the command line, before any parallel work starts.
int g_thread_limit = 0;
std::unique_ptr<tbb::global_control> g_tbb_limit;

int thread_limit() { return g_thread_limit > 0 ? g_thread_limit : hardware_threads(); }

}  // namespace

void set_thread_limit(int threads) {
  if (threads < 0) throw InputError(fmt::format("--threads must be 0 (all cores) or more, not {}", threads));
  g_thread_limit = threads;
  g_tbb_limit.reset();
  if (threads > 0) {
    g_tbb_limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                        static_cast<std::size_t>(threads));
  }
}

int allowed_threads(int requested) {
  return requested > 0 ? std::min(requested, thread_limit()) : thread_limit();
}

}  // namespace strata
