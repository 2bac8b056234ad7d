#pragma once
// Progress of long work. A controller creates a Progress per stage; the maths
// calls step() from any thread.
//
// On a terminal it redraws one bar in place (at most 10 times a second, clipped to
// the terminal width so it never wraps) with the time so far and an estimate of
// the time left from the mean rate so far. Log messages written meanwhile appear
// above the bar, which is redrawn under them.
// Otherwise (a pipe, a log file, TERM=dumb) it prints plain lines: none for a stage
// that ends within kPlainFirstLine_s, then one per 10 % step at most every
// kPlainMinGap_s (or after kPlainMaxGap_s of silence), each with the time left, and
// a final "done in" line.
// Nothing is drawn below log level info (-q); stdout (--json) is never touched.
//
// Cancellation: a SIGINT handler (core/signals.hpp) sets a flag that check_cancelled() turns into
// strata::Cancelled, so transactions roll back cleanly.
#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace strata {

// Where a Progress writes and how it reads the time. The default is stderr, the
// steady clock, and terminal mode when stderr is a terminal (and TERM is not dumb).
struct ProgressOutput {
  bool terminal = false;
  int width = 80;                                 // characters; terminal mode only
  std::function<void(std::string_view)> write;    // text as is (may hold \r, no newline added)
  std::function<double()> seconds;                // monotonic, seconds
  static ProgressOutput standard_error();
};

// Plain-line pacing (seconds).
inline constexpr double kPlainFirstLine_s = 2.0;  // a stage quicker than this prints only its final line
inline constexpr double kPlainMinGap_s = 2.0;     // at most one line per 10 % step and this gap
inline constexpr double kPlainMaxGap_s = 60.0;    // a slow stage says where it is at least this often

// The estimate of the time left, from the mean rate so far (seconds); none before
// anything is done or in the first half second (too noisy to be useful).
std::optional<double> estimate_remaining_s(std::size_t done, std::size_t total, double elapsed_s);
// "7 s", "3 min 05 s", "1 h 02 min".
std::string format_duration(double seconds);
// "matching: 7/14 (50 %), 3 s so far, about 3 s left"
std::string format_progress_line(std::string_view label, std::size_t done, std::size_t total, double elapsed_s);
// "matching: 14/14 done in 3 s"
std::string format_progress_done(std::string_view label, std::size_t done, std::size_t total, double elapsed_s);
// "matching            [#######.......]  7/14  0:03  ~0:03 left", at most `width` characters.
std::string format_progress_bar(std::string_view label, std::size_t done, std::size_t total, double elapsed_s,
                                int width);

class Progress {
 public:
  Progress(std::string label, std::size_t total);
  Progress(std::string label, std::size_t total, ProgressOutput output);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void step(std::size_t n = 1);  // thread-safe
  void finish();

 private:
  void draw(bool final);

  std::string label_;
  std::size_t total_;
  ProgressOutput out_;
  std::atomic<std::size_t> done_{0};
  double start_s_ = 0;
  double last_draw_s_ = -1e300;   // terminal: last redraw; plain: last line printed
  int last_decile_ = 0;           // plain: the 10 % step of the last line
  bool drawn_ = false;            // terminal: a bar is on the screen
  bool finished_ = false;
};

// Writes a log message (ending in a newline) on stderr above the terminal bar
// being drawn, if any, and redraws the bar under it. Used by log::write.
void write_above_progress(std::string_view text);

// SIGINT/SIGTERM request cancellation through request_cancel() (core/signals.hpp).
void request_cancel();
bool cancel_requested();
// Throws strata::Cancelled when a stop was requested.
void check_cancelled();

}  // namespace strata
