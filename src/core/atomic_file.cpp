#include "core/atomic_file.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/temporaries.hpp"

#include <fmt/format.h>

#include <fstream>
#include <mutex>
#include <optional>
#include <set>
#include <string>

namespace strata {

namespace fs = std::filesystem;

namespace {

// <stem>.tmp<extension>: writers that choose a format by the extension (GDAL,
// OpenVDB) still see it, and a rerun after a crash writes over the temporary the
// crash left. Two writers of one file in this process at once (two photos with the
// same content) take <stem>.tmp<k><extension>; other processes are kept out of the
// project by its lock.
class TemporaryName {
 public:
  explicit TemporaryName(const fs::path& path) {
    const std::lock_guard<std::mutex> lock(mutex());
    for (int k = 0;; ++k) {
      path_ = path;
      path_.replace_filename(fmt::format("{}.tmp{}{}", path.stem().string(), k ? std::to_string(k) : "",
                                         path.extension().string()));
      if (busy().insert(path_).second) break;
    }
    held_.emplace(path_);
  }
  TemporaryName(const TemporaryName&) = delete;
  TemporaryName& operator=(const TemporaryName&) = delete;
  ~TemporaryName() {
    const std::lock_guard<std::mutex> lock(mutex());
    busy().erase(path_);
  }
  const fs::path& path() const { return path_; }

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static std::set<fs::path>& busy() {
    static std::set<fs::path> b;
    return b;
  }
  fs::path path_;
  std::optional<Temporary> held_;  // removed by a stop that cannot wait (core/signals.hpp)
};

}  // namespace

void write_atomically(const fs::path& path, std::string_view what, const std::function<void(const fs::path& tmp)>& write,
                      std::string_view fault_point) {
  std::error_code ec;
  if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
  if (ec) throw IoError(fmt::format("{}: {}: cannot create the folder: {}", what, path.parent_path().string(), ec.message()));
  const TemporaryName name(path);
  const fs::path& tmp = name.path();
  try {
    write(tmp);
    if (!fault_point.empty()) fault::point(fault_point);
    fs::rename(tmp, path, ec);
    if (ec) throw IoError(fmt::format("{}: {}: cannot rename the temporary file over it: {}", what, path.string(), ec.message()));
  } catch (...) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw;
  }
}

void write_bytes_atomically(const fs::path& path, std::string_view what, std::string_view bytes,
                            std::string_view fault_point) {
  write_atomically(
      path, what,
      [&](const fs::path& tmp) {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        out.close();  // the flush can fail (a full disk) as well as the write
        if (!out) throw IoError(fmt::format("{}: {}: cannot write", what, path.string()));
      },
      fault_point);
}

void copy_atomically(const fs::path& source, const fs::path& path, std::string_view what, std::string_view fault_point) {
  write_atomically(
      path, what,
      [&](const fs::path& tmp) {
        std::error_code ec;
        fs::copy_file(source, tmp, fs::copy_options::overwrite_existing, ec);
        if (ec) throw IoError(fmt::format("{}: {}: cannot copy {} there: {}", what, path.string(), source.string(), ec.message()));
      },
      fault_point);
}

}  // namespace strata
