#include "support/test_support.hpp"

#include "core/hash.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace strata::test {
namespace {
fs::path env_path(const char* name) {
  if (const char* v = std::getenv(name)) return v;
  const std::string n = name;
  if (n == "STRATA_SOURCE_DIR") return STRATA_SOURCE_DIR;
  if (n == "STRATA_BINARY_DIR") return STRATA_BINARY_DIR;
  if (n == "STRATA_EXE") return STRATA_EXE;
  throw std::runtime_error("unknown test path " + n);
}
std::string slurp_fd(int fd) {
  std::string s;
  char buf[65536];
  ssize_t n;
  while ((n = ::read(fd, buf, sizeof buf)) > 0) s.append(buf, std::size_t(n));
  return s;
}
}  // namespace

ScratchDir::ScratchDir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string test = info ? std::string(info->test_suite_name()) + "." + info->name() : "x";
  // The process id keeps folders apart when ctest runs tests of one suite (and
  // their suite-level fixtures) in parallel processes.
  path_ = env_path("STRATA_BINARY_DIR") / "scratch" / (test + "." + name + "." + std::to_string(::getpid()));
  fs::remove_all(path_);
  fs::create_directories(path_);
}

ScratchDir::~ScratchDir() {
  if (!std::getenv("STRATA_KEEP_SCRATCH")) {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
}

fs::path source_dir() { return env_path("STRATA_SOURCE_DIR"); }
fs::path shared_data_dir() { return source_dir().parent_path() / "shared" / "data"; }
fs::path strata_exe() { return env_path("STRATA_EXE"); }
fs::path binary_dir() { return env_path("STRATA_BINARY_DIR"); }

CommandResult run_strata(const std::vector<std::string>& args) {
  int out_pipe[2], err_pipe[2];
  if (pipe(out_pipe) != 0 || pipe(err_pipe) != 0) throw std::runtime_error("pipe failed");
  const std::string exe = strata_exe().string();
  pid_t pid = fork();
  if (pid == 0) {
    dup2(out_pipe[1], 1);
    dup2(err_pipe[1], 2);
    close(out_pipe[0]);
    close(err_pipe[0]);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(exe.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(exe.c_str(), argv.data());
    _exit(127);
  }
  close(out_pipe[1]);
  close(err_pipe[1]);
  CommandResult r;
  // Read stderr on a helper thread-free basis: stdout first can deadlock if stderr
  // fills, so read both through a poll-free approach with a child that writes
  // little to stderr; large outputs go to stdout.
  r.out = slurp_fd(out_pipe[0]);
  r.err = slurp_fd(err_pipe[0]);
  close(out_pipe[0]);
  close(err_pipe[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

void write_text(const fs::path& path, const std::string& text) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

void write_gcp_lines_of(const fs::path& gcp_list, const std::string& photo_prefix, const fs::path& out) {
  std::ifstream in(gcp_list);
  std::string line, kept;
  std::getline(in, line);
  kept = line + "\n";  // the CRS line
  while (std::getline(in, line)) {
    if (line.find("\t" + photo_prefix) != std::string::npos) kept += line + "\n";
  }
  write_text(out, kept);
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string tree_fingerprint(const fs::path& dir) {
  std::map<std::string, std::string> entries;
  if (fs::exists(dir)) {
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      if (!e.is_regular_file()) continue;
      entries[fs::relative(e.path(), dir).string()] =
          std::to_string(e.file_size()) + " " + sha256_file(e.path());
    }
  }
  std::string s;
  for (const auto& [k, v] : entries) s += k + " " + v + "\n";
  return s;
}

}  // namespace strata::test
