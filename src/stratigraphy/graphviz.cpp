#include "stratigraphy/graphviz.hpp"

#include "core/atomic_file.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>

namespace strata {

std::optional<std::string> graphviz_svg(const std::string& dot_text) {
  namespace fs = std::filesystem;
  static std::atomic<unsigned> counter{0};
  const fs::path in = fs::temp_directory_path() / fmt::format("strata-{}-{}.dot", ::getpid(), counter++);
  write_bytes_atomically(in, "graphviz", dot_text);
  std::string svg;
  int status = -1;
  if (std::FILE* pipe = ::popen(fmt::format("dot -Tsvg '{}' 2>/dev/null", in.string()).c_str(), "r")) {
    char buf[4096];
    std::size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) svg.append(buf, n);
    status = ::pclose(pipe);
  }
  std::error_code ec;
  fs::remove(in, ec);
  if (status != 0 || svg.empty()) return std::nullopt;
  return svg;
}

}  // namespace strata
