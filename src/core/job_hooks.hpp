#pragma once
// What a long-lived host of the controllers (the field station's server) needs of
// the progress, the log and the cancellation that the terminal uses: the same
// figures the terminal bar draws and the same messages it prints, handed to a
// listener, and a stop request that can be cleared for the next job.
//
// One listener of each kind at a time: the server runs one writing job at a time
// (the project lock), so a process-wide listener is the job's listener.
#include "core/log.hpp"

#include <cstddef>
#include <functional>
#include <string>
#include <string_view>

namespace strata {

// A Progress as the terminal bar shows it.
struct ProgressEvent {
  std::string stage;      // the bar's label, e.g. "matching"
  std::size_t done = 0;   // steps done
  std::size_t total = 0;  // steps in all
  double elapsed_s = 0;   // since the stage began
  bool final = false;     // the stage's last event
};

// Called from any thread, at most kProgressEventsPerSecond times a second per stage
// and once when a stage ends. Empty: none.
using ProgressListener = std::function<void(const ProgressEvent&)>;
inline constexpr double kProgressEventsPerSecond = 5;
void set_progress_listener(ProgressListener listener);

// Called for every log message at or above the log level, from any thread. Empty: none.
using LogListener = std::function<void(log::Level, std::string_view)>;
void set_log_listener(LogListener listener);

// Clears a stop request (request_cancel, SIGINT) once the job it was meant for ended.
void clear_cancel();

}  // namespace strata
