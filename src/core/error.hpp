#pragma once
// Two tiers of errors (see docs/architecture.md):
//  - STRATA_CHECK: a broken precondition, i.e. a bug; the message carries file:line.
//  - typed errors derived from strata::Error: what users can cause (bad files,
//    bad values, unknown CRS). The CLI catches them once and prints one line.
#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace strata {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Bad user input: a value, a file's content, a command-line argument.
class InputError : public Error {
 public:
  using Error::Error;
};

// A coordinate reference system that is unknown or unsuitable.
class CrsError : public Error {
 public:
  using Error::Error;
};

// A file or database that cannot be read or written.
class IoError : public Error {
 public:
  using Error::Error;
};

// A processing stage that could not produce a result from valid input
// (e.g. too few photos overlap). Not a bug, not bad syntax.
class ProcessingError : public Error {
 public:
  using Error::Error;
};

// The user asked to stop (Ctrl-C); the current transaction rolls back.
class Cancelled : public Error {
 public:
  Cancelled() : Error("cancelled by user") {}
};

// A violated internal invariant. Not caught by the CLI's error mapping.
class InternalError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

[[noreturn]] void throw_check_failure(const char* expr, const char* file, int line,
                                      const std::string& message);

}  // namespace strata

#define STRATA_CHECK(cond, ...)                                                   \
  do {                                                                            \
    if (!(cond)) {                                                                \
      ::strata::throw_check_failure(#cond, __FILE__, __LINE__,                    \
                                    ::fmt::format("" __VA_ARGS__));               \
    }                                                                             \
  } while (false)
