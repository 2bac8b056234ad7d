#include "project/project_lock.hpp"

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <sstream>
#include <thread>

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr auto kPollInterval = std::chrono::milliseconds(200);  // how often a waiting writer retries
constexpr double kWaitReportS = 30;  // seconds between "still waiting" lines

std::string this_host() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "unknown";
  return name;
}

// The lock file's text: one "key=value" per line.
std::string format_holder(const LockHolder& h) {
  return fmt::format("pid={}\nhost={}\nstarted={}\ncommand={}\n", h.pid, h.host, h.started, h.command);
}

std::optional<LockHolder> parse_holder(const std::string& text) {
  LockHolder h;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = line.substr(0, eq), value = line.substr(eq + 1);
    try {
      if (key == "pid") h.pid = std::stol(value);
      if (key == "started") h.started = std::stoll(value);
    } catch (const std::exception&) {
      return std::nullopt;  // not written by strata, or cut short
    }
    if (key == "host") h.host = value;
    if (key == "command") h.command = value;
  }
  if (h.pid <= 0) return std::nullopt;
  return h;
}

std::string read_all(int fd) {
  std::string text;
  char buf[1024];
  off_t at = 0;
  for (;;) {
    const ssize_t n = pread(fd, buf, sizeof buf, at);
    if (n <= 0) break;
    text.append(buf, std::size_t(n));
    at += n;
  }
  return text;
}

void write_holder(int fd, const LockHolder& h, const fs::path& file) {
  const std::string text = format_holder(h);
  if (ftruncate(fd, 0) != 0 || pwrite(fd, text.data(), text.size(), 0) != ssize_t(text.size())) {
    throw IoError(fmt::format("{}: cannot write the project's lock file: {}", file.string(), std::strerror(errno)));
  }
}

std::string busy_message(int fd, const fs::path& file, double waited_s) {
  const auto h = parse_holder(read_all(fd));
  const std::string who = h ? h->describe() : "another strata command (starting)";
  const std::string waited = waited_s > 0 ? fmt::format(" after waiting {:.0f} s", waited_s) : "";
  return fmt::format("project is busy: {} is changing it ({}){}; wait until it ends, or add --wait SECONDS",
                     who, file.string(), waited);
}

}  // namespace

std::string LockHolder::describe() const {
  const std::time_t t = std::time_t(started);
  std::tm start{}, today{};
  localtime_r(&t, &start);
  const std::time_t now = std::time(nullptr);
  localtime_r(&now, &today);
  char when[32];
  const bool same_day = start.tm_year == today.tm_year && start.tm_yday == today.tm_yday;
  std::strftime(when, sizeof when, same_day ? "%H:%M" : "%Y-%m-%d %H:%M", &start);
  const std::string where = host == this_host() ? "" : " on " + host;
  return fmt::format("`{}` (pid {}{}, since {})", command, pid, where, when);
}

void ProjectLockOptions::validate() const {
  if (!(std::isfinite(wait_s) && wait_s >= 0)) {
    throw InputError(fmt::format("--wait: {} is not a number of seconds (0 or more)", wait_s));
  }
}

ProjectLock::ProjectLock(const fs::path& dir, const ProjectLockOptions& options) {
  options.validate();
  // A folder without a project has nothing to protect: Project::open refuses it
  // with its own message, and no lock file is left in a folder that is not a project.
  if (!fs::exists(dir / "project.gpkg")) return;
  const fs::path file = dir / kFileName;
  fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    const int err = errno;
    if (err == EROFS || err == EACCES || err == EPERM) {
      throw IoError(fmt::format("{}: the project folder cannot be written ({}): commands that change the project "
                                "cannot run; reading ones (info, markers, report, export) can",
                                dir.string(), std::strerror(err)));
    }
    throw IoError(fmt::format("{}: cannot open the project's lock file: {}", file.string(), std::strerror(err)));
  }
  const auto start = std::chrono::steady_clock::now();
  auto seconds_waited = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  double next_report = 0;
  for (;;) {
    if (flock(fd_, LOCK_EX | LOCK_NB) == 0) break;
    const int err = errno;
    if (err == ENOLCK || err == EOPNOTSUPP || err == ENOSYS) {
      // Some network file systems cannot lock: carry on as before there was a lock.
      log::warn("{}: this file system cannot lock files ({}); do not run two strata commands on this project at once",
                file.string(), std::strerror(err));
      ::close(fd_);
      fd_ = -1;
      return;
    }
    if (err != EWOULDBLOCK && err != EINTR) {
      const std::string msg = std::strerror(err);
      ::close(fd_);
      fd_ = -1;
      throw IoError(fmt::format("{}: cannot lock the project: {}", file.string(), msg));
    }
    const double waited = seconds_waited();
    if (waited >= options.wait_s) {
      const std::string msg = busy_message(fd_, file, waited);
      ::close(fd_);
      fd_ = -1;
      throw IoError(msg);
    }
    if (waited >= next_report) {
      const auto h = parse_holder(read_all(fd_));
      log::info("project is busy: {}; waiting (up to {:.0f} s, {:.0f} s so far)",
                h ? h->describe() : "another strata command", options.wait_s, waited);
      next_report += kWaitReportS;
    }
    try {
      check_cancelled();
    } catch (...) {
      ::close(fd_);
      fd_ = -1;
      throw;
    }
    std::this_thread::sleep_for(kPollInterval);
  }
  if (seconds_waited() > kPollInterval.count() / 1000.0) log::info("project free after {:.0f} s", seconds_waited());
  // A holder recorded but no lock held: that command ended without its destructor
  // (SIGKILL, a crash, a power cut). Its open transaction was rolled back by SQLite.
  if (const auto previous = parse_holder(read_all(fd_))) {
    log::warn("the last command that changed this project, {}, did not finish (killed or crashed); "
              "its unfinished step was not recorded",
              previous->describe());
  }
  LockHolder me;
  me.pid = long(getpid());
  me.host = this_host();
  me.command = options.command;
  me.started = std::int64_t(std::time(nullptr));
  try {
    write_holder(fd_, me, file);
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

ProjectLock::~ProjectLock() {
  if (fd_ < 0) return;
  // An empty file says "free"; closing the last descriptor drops the flock.
  if (ftruncate(fd_, 0) != 0) {
    // The lock is dropped all the same; the next writer reports a stale holder.
  }
  ::close(fd_);
}

std::optional<LockHolder> ProjectLock::holder(const fs::path& dir) {
  const int fd = ::open((dir / kFileName).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::nullopt;
  auto h = parse_holder(read_all(fd));
  ::close(fd);
  // A holder on this machine whose process is gone was killed; it holds nothing.
  if (h && h->host == this_host() && kill(pid_t(h->pid), 0) != 0 && errno == ESRCH) return std::nullopt;
  return h;
}

}  // namespace strata
