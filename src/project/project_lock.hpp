#pragma once
// One writer per project (docs/reliability.md, "Two processes, one project").
//
// A command that changes a project holds an exclusive flock(2) on DIR/project.lock
// for as long as it runs. The file names the holder (pid, host, command, start
// time), so a second writer can say who it is waiting for. The kernel drops a
// flock when its process ends, however it ends: the lock of a killed or crashed
// command never blocks the next one. Reading commands take no lock: SQLite's WAL
// gives them the last committed state while a writer works.
#include <chrono>
#include <filesystem>
#include <optional>
#include <string>

namespace strata {

// Who holds (or last held) a project's write lock.
struct LockHolder {
  long pid = 0;
  std::string host;
  std::string command;       // e.g. "strata process --layer L2"
  std::int64_t started = 0;  // seconds since the epoch

  // "`strata process --layer L2` (pid 4711, since 08:14)"; the host and the date
  // are added when they are not this machine's or today.
  std::string describe() const;
};

struct ProjectLockOptions {
  std::string command;  // what this process is doing, as the user typed it
  double wait_s = 0;    // seconds to wait for a busy project; 0 = refuse at once

  void validate() const;
};

class ProjectLock {
 public:
  static constexpr const char* kFileName = "project.lock";

  // Takes the write lock of the project folder `dir`, waiting up to options.wait_s.
  // Throws IoError "project is busy: ..." when another command holds it, and
  // IoError naming the folder when it cannot be written (read-only media).
  ProjectLock(const std::filesystem::path& dir, const ProjectLockOptions& options);
  ~ProjectLock();
  ProjectLock(const ProjectLock&) = delete;
  ProjectLock& operator=(const ProjectLock&) = delete;

  // The holder of the lock of `dir` now; empty when no command holds it.
  static std::optional<LockHolder> holder(const std::filesystem::path& dir);

 private:
  int fd_ = -1;
};

}  // namespace strata
