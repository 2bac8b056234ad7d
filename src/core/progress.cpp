#include "core/progress.hpp"

#include "core/job_hooks.hpp"

#include "core/error.hpp"
#include "core/log.hpp"

#include <fmt/format.h>

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <string_view>

namespace strata {
namespace {
std::atomic<bool> g_cancel{false};

// One mutex for everything drawn on stderr by progress bars and log messages, so
// that lines from worker threads never interleave.
std::mutex g_draw_mutex;
// The terminal bar on the screen (guarded by g_draw_mutex): its text, so that a log
// message can clear it and draw it again under itself.
const Progress* g_bar_owner = nullptr;
std::string g_bar_text;
// The host's listener (core/job_hooks.hpp), guarded by g_draw_mutex.
ProgressListener g_listener;
const Progress* g_last_listened = nullptr;  // the stage of the listener's last event, and when
double g_last_listened_s = 0;

constexpr double kRedraw_s = 0.1;      // terminal: at most 10 redraws a second
constexpr double kFirstEstimate_s = 0.5;  // no estimate before this: the rate is noise
constexpr int kBarCells = 30;           // '#' cells of a full-width bar
constexpr int kLabelWidth = 22;         // characters: bars of successive stages line up

// "0:07", "12:45", "1:02:03": fixed layout, so a redrawn bar does not jitter.
std::string clock_time(double s) {
  const long t = std::lround(std::max(0.0, s));
  if (t < 3600) return fmt::format("{}:{:02}", t / 60, t % 60);
  return fmt::format("{}:{:02}:{:02}", t / 3600, (t / 60) % 60, t % 60);
}

int percent(std::size_t done, std::size_t total) {
  if (total == 0) return 100;
  return int(std::min<std::size_t>(100, done * 100 / total));
}

int terminal_width() {
  winsize ws{};
  if (ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0) return ws.ws_col;
  return 80;
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

// ---- formatting -----------------------------------------------------------------

std::optional<double> estimate_remaining_s(std::size_t done, std::size_t total, double elapsed_s) {
  if (done >= total) return 0.0;
  if (done == 0 || !(elapsed_s >= kFirstEstimate_s)) return std::nullopt;
  const double rate = double(done) / elapsed_s;  // items per second, mean so far
  return double(total - done) / rate;
}

std::string format_duration(double seconds) {
  const long t = std::lround(std::max(0.0, seconds));
  if (t < 60) return fmt::format("{} s", t);
  if (t < 3600) return fmt::format("{} min {:02} s", t / 60, t % 60);
  return fmt::format("{} h {:02} min", t / 3600, (t / 60) % 60);
}

std::string format_progress_line(std::string_view label, std::size_t done, std::size_t total, double elapsed_s) {
  std::string s = fmt::format("{}: {}/{} ({} %), {} so far", label, done, total, percent(done, total),
                              format_duration(elapsed_s));
  if (const auto left = estimate_remaining_s(done, total, elapsed_s)) s += ", about " + format_duration(*left) + " left";
  return s;
}

std::string format_progress_done(std::string_view label, std::size_t done, std::size_t total, double elapsed_s) {
  return fmt::format("{}: {}/{} done in {}", label, done, total, format_duration(elapsed_s));
}

std::string format_progress_bar(std::string_view label, std::size_t done, std::size_t total, double elapsed_s,
                                int width) {
  const int max_chars = std::max(20, width - 1);  // never the last column: some terminals wrap there
  const std::string count_width = fmt::format("{}", total);
  const auto left = estimate_remaining_s(done, total, elapsed_s);
  // Fixed-width fields: the bar and the figures stay in place while they change.
  const std::string figures =
      fmt::format(" {:>{}}/{} {:>5}{}", done, count_width.size(), total, clock_time(elapsed_s),
                  done >= total ? std::string("  done      ")
                                : left ? fmt::format("  ~{:>5} left", clock_time(*left)) : std::string(13, ' '));
  std::string name(label.substr(0, std::size_t(kLabelWidth)));
  name.resize(std::size_t(kLabelWidth), ' ');
  const int room = max_chars - int(name.size()) - int(figures.size()) - 3;  // " [" and "]"
  std::string s = name;
  if (room >= 5) {
    const int cells = std::min(kBarCells, room);
    const double fraction = total ? std::min(1.0, double(done) / double(total)) : 1.0;
    const int filled = int(fraction * cells);
    s += " [" + std::string(std::size_t(filled), '#') + std::string(std::size_t(cells - filled), '.') + "]";
  }
  s += figures;
  if (int(s.size()) > max_chars) s.resize(std::size_t(max_chars));
  return s;
}

// ---- output ----------------------------------------------------------------------

ProgressOutput ProgressOutput::standard_error() {
  ProgressOutput o;
  const char* term = std::getenv("TERM");
  o.terminal = isatty(STDERR_FILENO) != 0 && !(term && std::string_view(term) == "dumb");
  o.width = o.terminal ? terminal_width() : 80;
  o.write = [](std::string_view text) {
    std::fwrite(text.data(), 1, text.size(), stderr);
    std::fflush(stderr);
  };
  o.seconds = steady_seconds;
  return o;
}

void write_above_progress(std::string_view text) {
  std::lock_guard lock(g_draw_mutex);
  if (g_bar_owner) std::fputs("\r\x1b[K", stderr);
  std::fwrite(text.data(), 1, text.size(), stderr);
  if (g_bar_owner) std::fputs(g_bar_text.c_str(), stderr);
  std::fflush(stderr);
}

// ---- Progress ----------------------------------------------------------------------

Progress::Progress(std::string label, std::size_t total)
    : Progress(std::move(label), total, ProgressOutput::standard_error()) {}

Progress::Progress(std::string label, std::size_t total, ProgressOutput output)
    : label_(std::move(label)), total_(total), out_(std::move(output)) {
  if (!out_.seconds) out_.seconds = steady_seconds;
  start_s_ = out_.seconds();
  last_draw_s_ = out_.terminal ? -1e300 : start_s_;
}

Progress::~Progress() {
  // A stage that did all its work but did not call finish() still says so; one left
  // by an exception (a failure, a cancel) just ends its bar's line.
  if (!finished_ && std::uncaught_exceptions() == 0 && total_ > 0 && done_.load() >= total_) {
    try {
      finish();
    } catch (...) {
    }
    return;
  }
  std::lock_guard lock(g_draw_mutex);
  if (drawn_ && !finished_ && out_.write) out_.write("\n");
  if (g_bar_owner == this) g_bar_owner = nullptr;
}

void Progress::step(std::size_t n) {
  done_.fetch_add(n);
  draw(false);
}

void Progress::finish() { draw(true); }

void Progress::draw(bool final) {
  std::lock_guard lock(g_draw_mutex);
  if (finished_) return;
  if (final) finished_ = true;
  if (g_listener) {
    const double now = steady_seconds();
    if (final || g_last_listened != this || now - g_last_listened_s >= 1.0 / kProgressEventsPerSecond) {
      g_last_listened = this;
      g_last_listened_s = now;
      g_listener({label_, done_.load(), total_, (out_.seconds ? out_.seconds() : now) - start_s_, final});
    }
  }
  if (log::level() > log::Level::info || !out_.write) return;
  const double now = out_.seconds();
  const double elapsed = now - start_s_;
  const std::size_t done = done_.load();  // read under the lock: the bar never goes back
  if (out_.terminal) {
    if (!final && now - last_draw_s_ < kRedraw_s) return;
    last_draw_s_ = now;
    const std::string bar = format_progress_bar(label_, done, total_, elapsed, out_.width);
    out_.write("\r" + bar + "\x1b[K" + (final ? "\n" : ""));
    drawn_ = !final;
    g_bar_owner = final ? nullptr : this;
    g_bar_text = final ? std::string() : bar;
    return;
  }
  if (final) {
    out_.write(format_progress_done(label_, done, total_, elapsed) + "\n");
    return;
  }
  if (elapsed < kPlainFirstLine_s || done >= total_) return;
  const int decile = total_ ? int(done * 10 / total_) : 10;
  const bool next_step = decile > last_decile_ && now - last_draw_s_ >= kPlainMinGap_s;
  if (!next_step && now - last_draw_s_ < kPlainMaxGap_s) return;
  last_decile_ = std::max(last_decile_, decile);
  last_draw_s_ = now;
  out_.write(format_progress_line(label_, done, total_, elapsed) + "\n");
}

// ---- cancellation ----------------------------------------------------------

void request_cancel() { g_cancel = true; }
void clear_cancel() { g_cancel = false; }

void set_progress_listener(ProgressListener listener) {
  std::lock_guard lock(g_draw_mutex);
  g_listener = std::move(listener);
}
bool cancel_requested() { return g_cancel; }
void check_cancelled() {
  if (g_cancel) throw Cancelled();
}

}  // namespace strata
