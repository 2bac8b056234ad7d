#include "core/signals.hpp"

#include "core/progress.hpp"
#include "core/temporaries.hpp"

#include <fmt/format.h>

#include <semaphore.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>

namespace strata {
namespace {

sem_t g_signalled;                    // posted by the handler: wakes the stopping thread
std::atomic<int> g_signals{0};        // signals received
constexpr int kExitStopped = 130;     // 128 + SIGINT, as a shell reports Ctrl-C

void say(const char* text) {
  // write(2) is async-signal-safe; a failed write has nowhere else to go.
  std::size_t n = 0;
  while (text[n]) ++n;
  [[maybe_unused]] const ssize_t w = ::write(STDERR_FILENO, text, n);
}

extern "C" void on_stop_signal(int) {
  const int errno_saved = errno;
  request_cancel();
  if (g_signals.fetch_add(1) == 0) {
    say("\nstrata: stopping at the next safe point (a second Ctrl-C stops at once)\n");
    sem_post(&g_signalled);
  } else {
    say("strata: stopped at once; the project keeps its last committed state\n");
    sem_post(&g_signalled);
  }
  errno = errno_saved;
}

double grace_s() {
  if (const char* text = std::getenv("STRATA_STOP_GRACE_S")) {
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end != text && v >= 0 && v <= 3600) return v;
  }
  return kStopGrace_s;
}

// Waits for the first signal, then for the command to end on its own within the
// grace period or a second signal; then removes the temporaries and ends the process.
void enforce_stop() {
  // Signals go to the command's threads (interrupting what waits there), or to the
  // server's own waiting thread (strata serve), never to this one.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  while (sem_wait(&g_signalled) != 0) {
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(grace_s());
  bool second = g_signals.load() > 1;
  while (!second) {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_nsec += 100'000'000;
    if (ts.tv_nsec >= 1'000'000'000) {
      ts.tv_sec += 1;
      ts.tv_nsec -= 1'000'000'000;
    }
    if (sem_timedwait(&g_signalled, &ts) == 0) second = true;
    if (std::chrono::steady_clock::now() >= deadline) break;
  }
  const int removed = remove_temporaries();
  const std::string message =
      second ? fmt::format("strata: stopped; {} temporary file(s) removed\n", removed)
             : fmt::format("strata: no safe point reached within {:g} s of the signal; stopped, {} temporary file(s) "
                           "removed; the project keeps its last committed state\n",
                           grace_s(), removed);
  say(message.c_str());
  std::_Exit(kExitStopped);
}

}  // namespace

void install_cancel_handler() {
  sem_init(&g_signalled, 0, 0);
  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: a read or a wait that blocks returns EINTR
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  std::thread(enforce_stop).detach();
}

}  // namespace strata
