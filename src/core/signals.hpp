#pragma once
// SIGINT and SIGTERM on the command line (docs/reliability.md, "Stopping a command").
//
// The first signal asks the command to stop at its next safe point
// (check_cancelled(), core/progress.hpp): the running transaction rolls back, its
// staged files are removed, the project lock is released, exit status 130. System
// calls that wait (a read, a lock) are interrupted rather than restarted. A command
// that does not reach a safe point within the grace period (kStopGrace_s, or the
// environment variable STRATA_STOP_GRACE_S), or a second signal, ends it at once:
// its temporaries (core/temporaries.hpp) are removed, the kernel drops the project
// lock, and SQLite's journal undoes the uncommitted transaction at the next open,
// as after a crash (the crash matrix shows that this loses nothing committed).
namespace strata {

inline constexpr double kStopGrace_s = 10;

// Installs the handlers and starts the thread that enforces the grace period.
// Once, in main(), before any other thread starts.
void install_cancel_handler();

}  // namespace strata
