#include "core/progress.hpp"

#include "core/error.hpp"
#include "core/log.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string_view>
#include <mutex>
#include <unistd.h>

namespace strata {
namespace {
std::atomic<bool> g_cancel{false};
std::mutex g_draw_mutex;

extern "C" void on_signal(int) { g_cancel = true; }

std::string format_seconds(double s) {
  if (s < 60) return fmt::format("{:.0f}s", s);
  return fmt::format("{:.0f}m{:02.0f}s", s / 60 - 0.5, std::fmod(s, 60.0));
}
}  // namespace

void install_cancel_handler() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}
void request_cancel() { g_cancel = true; }
bool cancel_requested() { return g_cancel; }
void check_cancelled() {
  if (g_cancel) throw Cancelled();
}

void fault_point(const char* name) {
  const char* at = std::getenv("STRATA_FAULT_AT");
  if (at && std::string_view(at) == name) std::raise(SIGKILL);
}

Progress::Progress(std::string label, std::size_t total)
    : label_(std::move(label)),
      total_(total),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_),
      tty_(isatty(fileno(stderr)) != 0) {}

Progress::~Progress() {
  if (!finished_ && done_ > 0 && tty_) std::fputc('\n', stderr);
}

void Progress::step(std::size_t n) {
  const std::size_t done = done_.fetch_add(n) + n;
  draw(done, false);
}

void Progress::finish() {
  if (finished_) return;
  draw(done_.load(), true);
  finished_ = true;
}

void Progress::draw(std::size_t done, bool final) {
  if (log::level() > log::Level::info) return;
  const auto now = std::chrono::steady_clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double fraction = total_ ? std::min(1.0, double(done) / double(total_)) : 1.0;
  std::lock_guard lock(g_draw_mutex);
  if (tty_) {
    if (!final && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    const int width = 30;
    const int filled = int(fraction * width);
    std::string eta = fraction > 0.02 && !final
                          ? fmt::format(" ~{} left", format_seconds(elapsed / fraction * (1 - fraction)))
                          : "";
    fmt::print(stderr, "\r{:<22} [{}{}] {}/{} {}{}\x1b[K", label_, std::string(filled, '#'),
               std::string(width - filled, '.'), done, total_, format_seconds(elapsed), eta);
    if (final) std::fputc('\n', stderr);
  } else {
    const int decile = int(fraction * 10);
    if (final) {
      fmt::print(stderr, "{}: {}/{} done in {}\n", label_, done, total_, format_seconds(elapsed));
    } else if (decile > last_decile_.load() && decile < 10) {
      last_decile_ = decile;
      fmt::print(stderr, "{}: {}/{} ({}%)\n", label_, done, total_, decile * 10);
    }
  }
}

}  // namespace strata
