#pragma once
// What every fuzz target shares: the input written to a file in this process's own
// scratch folder, and the one verdict on a parser's answer. A parser may accept the
// bytes or refuse them with strata's typed error (strata::Error) naming the file;
// anything else (another exception, a crash, a sanitizer report) is a bug. A
// violation is thrown as FuzzFailure, which no target catches: libFuzzer aborts on
// it and keeps the input, the replay test reports it.
#include "core/error.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace strata::fuzz {

class FuzzFailure : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

// A folder unique to this process under $TMPDIR, made on first use and removed at exit.
const std::filesystem::path& scratch_dir();

// Writes the input to scratch_dir()/name (replacing it) and returns the path.
std::filesystem::path write_input(const std::string& name, const std::uint8_t* data, std::size_t size);

// Throws FuzzFailure unless the error's message names `file_name`.
void require_names_file(const std::exception& e, std::string_view file_name);

// Runs parse(). Returns true when it returned, false when it refused the input with
// a strata::Error whose message names `file_name` (the file the user would have to
// fix). Throws FuzzFailure for a refusal that does not name it; every other
// exception passes through.
template <typename Parse>
bool accepts(Parse&& parse, std::string_view file_name) {
  try {
    parse();
    return true;
  } catch (const Error& e) {
    require_names_file(e, file_name);
    return false;
  }
}

}  // namespace strata::fuzz
