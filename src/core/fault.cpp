#include "core/fault.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <string>
#include <thread>

namespace strata::fault {
namespace {

struct Arming {
  std::string name;  // empty: no point armed
  long hit = 1;      // kill at this hit (1 = the first)
  bool stall = false;  // STRATA_STALL_AT: hang there instead (a step that never reaches a safe point)
};

// STRATA_CRASH_AT=<name>[:<n>], read once. A malformed count arms nothing rather
// than killing somewhere unintended.
// STRATA_STALL_AT=<name>[:<n>] the same, but the process hangs there without ever
// checking for cancellation, as a step stuck in a system call or a library would:
// the test of the stop that cannot wait (core/signals.hpp, docs/reliability.md).
Arming read_arming() {
  Arming r;
  const char* env = std::getenv("STRATA_CRASH_AT");
  if (!env || !*env) {
    env = std::getenv("STRATA_STALL_AT");
    r.stall = true;
  }
  if (!env || !*env) return r;
  std::string spec = env;
  const auto colon = spec.rfind(':');
  if (colon != std::string::npos) {
    char* end = nullptr;
    const long n = std::strtol(spec.c_str() + colon + 1, &end, 10);
    if (end == spec.c_str() + colon + 1 || *end != '\0' || n < 1) return r;
    r.hit = n;
    spec.resize(colon);
  }
  r.name = spec;
  return r;
}

const Arming& arming() {
  static const Arming a = read_arming();
  return a;
}

std::atomic<long> g_hits{0};  // passes of the armed point so far

bool registered(std::string_view name) {
  return std::any_of(std::begin(kCrashPoints), std::end(kCrashPoints),
                     [&](const CrashPoint& p) { return p.name == name; });
}

}  // namespace

void point(std::string_view name) {
  const Arming& a = arming();
  if (a.name.empty()) return;
  // Checked only while armed: the crash matrix arms every point, so every point a
  // command reaches is checked against the registry by it.
  if (!registered(name)) {
    throw InternalError(fmt::format("crash point '{}' is not in kCrashPoints (core/fault.hpp)", name));
  }
  if (name == a.name && g_hits.fetch_add(1) + 1 == a.hit) {
    if (!a.stall) std::raise(SIGKILL);
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
  }
}

std::string_view armed() { return arming().name; }

}  // namespace strata::fault
