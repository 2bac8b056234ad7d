#pragma once
// Progress of long work. A controller creates a Progress per stage; the maths
// calls step() from any thread. On a terminal it draws a bar with an estimate of
// the time left; otherwise it prints a plain line every 10 %.
// Cancellation: a SIGINT handler sets a flag that check_cancelled() turns into
// strata::Cancelled, so transactions roll back cleanly.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <string>

namespace strata {

class Progress {
 public:
  Progress(std::string label, std::size_t total);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void step(std::size_t n = 1);  // thread-safe
  void finish();

 private:
  void draw(std::size_t done, bool final);

  std::string label_;
  std::size_t total_;
  std::atomic<std::size_t> done_{0};
  std::atomic<int> last_decile_{-1};
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  bool tty_;
  bool finished_ = false;
};

// Installs a SIGINT/SIGTERM handler that requests cancellation.
void install_cancel_handler();
void request_cancel();
bool cancel_requested();
// Throws strata::Cancelled when a stop was requested.
void check_cancelled();

// Fault injection for the resume tests: when the environment variable
// STRATA_FAULT_AT names this point, the process kills itself with SIGKILL there,
// exactly as a crash or a pulled plug would (no destructors, no rollback code).
void fault_point(const char* name);

}  // namespace strata
