#include "core/log.hpp"

#include "core/job_hooks.hpp"
#include "core/progress.hpp"

#include <atomic>
#include <cstdio>
#include <mutex>

namespace strata::log {
namespace {
std::atomic<Level> g_level{Level::info};
std::mutex g_mutex;
LogListener g_listener;  // guarded by g_mutex
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
  if (g_listener) g_listener(l, message);
}

}  // namespace strata::log

namespace strata {
void set_log_listener(LogListener listener) {
  std::lock_guard lock(log::g_mutex);
  log::g_listener = std::move(listener);
}
}  // namespace strata
