#include "support/shared_scene.hpp"

#include "core/hash.hpp"
#include "support/test_support.hpp"

#include <fstream>
#include <stdexcept>
#include <system_error>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace strata::test {
namespace {

// Size and modification time of a file: changes when it is rebuilt (cheaper than
// hashing a large executable in every test process).
std::string identity(const fs::path& file) {
  std::error_code ec;
  const auto size = fs::file_size(file, ec);
  if (ec) return file.string() + ":missing";
  const auto time = fs::last_write_time(file, ec).time_since_epoch().count();
  return file.string() + ":" + std::to_string(size) + ":" + std::to_string(time);
}

// An exclusive lock on a file, released when the object dies (or the process does:
// a builder killed half-way leaves no stale lock).
class FileLock {
 public:
  explicit FileLock(const fs::path& path) : fd_(::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644)) {
    if (fd_ < 0 || ::flock(fd_, LOCK_EX) != 0) throw std::runtime_error("cannot lock " + path.string());
  }
  ~FileLock() { ::close(fd_); }
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;

 private:
  int fd_;
};

}  // namespace

fs::path shared_scene(const std::string& name, const std::string& parameters,
                      const std::function<void(const fs::path&)>& build) {
  const fs::path root = binary_dir() / "scenes";
  const std::string key = sha256_hex(parameters + "\n" + identity("/proc/self/exe") + "\n" +
                                     identity(strata_exe())).substr(0, 16);
  const fs::path dir = root / (name + "-" + key);
  if (fs::exists(dir)) return dir;  // published by rename: complete when it exists

  fs::create_directories(root);
  const FileLock lock(root / (name + ".lock"));
  if (fs::exists(dir)) return dir;  // another process built it while we waited
  // Scenes of this name from earlier builds, and a build killed half-way.
  for (const auto& e : fs::directory_iterator(root)) {
    const std::string f = e.path().filename().string();
    if (e.is_directory() && f.rfind(name + "-", 0) == 0) fs::remove_all(e.path());
  }
  const fs::path tmp = root / (name + "-" + key + ".tmp");
  fs::create_directories(tmp);
  try {
    build(tmp);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  fs::rename(tmp, dir);
  // One line per build: how many times each scene was made (docs/testing.md).
  std::ofstream(root / "builds.log", std::ios::app) << name << " " << key << " " << ::getpid() << "\n";
  return dir;
}

void copy_scene(const fs::path& from, const fs::path& to) {
  fs::create_directories(to.parent_path());
  fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
}

}  // namespace strata::test
