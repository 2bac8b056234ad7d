#include "core/log.hpp"

#include "core/progress.hpp"

#include <atomic>
#include <cstdio>
#include <mutex>

namespace strata::log {
namespace {
std::atomic<Level> g_level{Level::info};
std::mutex g_mutex;
}  // namespace

void set_level(Level l) { g_level = l; }
Level level() { return g_level; }

void write(Level l, std::string_view message) {
  if (l < g_level.load()) return;
  const char* prefix = "";
  switch (l) {
    case Level::warning: prefix = "warning: "; break;
    case Level::error: prefix = "error: "; break;
    case Level::debug: prefix = "debug: "; break;
    case Level::info:
    case Level::quiet: break;
  }
  std::lock_guard lock(g_mutex);
  // Above a progress bar being drawn, if any, which is redrawn under the message.
  write_above_progress(fmt::format("{}{}\n", prefix, message));
}

}  // namespace strata::log
