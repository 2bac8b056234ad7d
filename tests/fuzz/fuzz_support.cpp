#include "fuzz/fuzz_support.hpp"

#include <fmt/format.h>

#include <cstdlib>
#include <fstream>
#include <system_error>

namespace fs = std::filesystem;

namespace strata::fuzz {
namespace {

void remove_scratch() {
  std::error_code ec;
  fs::remove_all(scratch_dir(), ec);
}

}  // namespace

const fs::path& scratch_dir() {
  static const fs::path dir = [] {
    std::string tmpl = (fs::temp_directory_path() / "strata-fuzz-XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw FuzzFailure("cannot make a scratch folder under " + tmpl);
    std::atexit(remove_scratch);
    return fs::path(tmpl);
  }();
  return dir;
}

fs::path write_input(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const fs::path path = scratch_dir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  if (!out.flush()) throw FuzzFailure("cannot write the input to " + path.string());
  return path;
}

void require_names_file(const std::exception& e, std::string_view file_name) {
  const std::string_view message = e.what();
  if (message.find(file_name) == std::string_view::npos) {
    throw FuzzFailure(fmt::format("the refusal does not name the file {}: {}", file_name, message));
  }
}

}  // namespace strata::fuzz
