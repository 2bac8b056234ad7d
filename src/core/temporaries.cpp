#include "core/temporaries.hpp"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

namespace strata {
namespace fs = std::filesystem;
namespace {

std::mutex& registry_mutex() {
  static std::mutex m;
  return m;
}
std::vector<const Temporary*>& registry() {
  static std::vector<const Temporary*> r;
  return r;
}

}  // namespace

Temporary::Temporary(fs::path path) : path_(std::move(path)) {
  const std::lock_guard lock(registry_mutex());
  registry().push_back(this);
}

Temporary::~Temporary() {
  const std::lock_guard lock(registry_mutex());
  auto& r = registry();
  r.erase(std::remove(r.begin(), r.end(), this), r.end());
}

int remove_temporaries() {
  // The command's threads go on running meanwhile; the registry's lock is only ever
  // held for a push or an erase, so a short wait gets it.
  std::unique_lock lock(registry_mutex(), std::defer_lock);
  for (int i = 0; i < 200 && !lock.try_lock(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  if (!lock.owns_lock()) return 0;
  int removed = 0;
  for (const Temporary* t : registry()) {
    std::error_code ec;
    if (fs::symlink_status(t->path(), ec).type() == fs::file_type::not_found) continue;
    if (fs::remove_all(t->path(), ec) > 0) ++removed;
  }
  return removed;
}

}  // namespace strata
