#include "exporters/raster/gdal_util.hpp"

#include <cpl_error.h>
#include <fmt/format.h>

#include <cerrno>
#include <cstdint>

namespace fs = std::filesystem;

namespace strata::gdal_detail {

std::string last_gdal_error() {
  const char* m = CPLGetLastErrorMsg();
  return m && *m ? m : "unknown GDAL error";
}

// GDAL reports a full disk as whatever libtiff met first ("TIFFAppendToStrip: Seek
// error"), so a file system left with almost no room, or errno ENOSPC, is named as such.
std::string write_failure(const fs::path& tmp) {
  const int saved_errno = errno;
  std::error_code ec;
  const auto space = fs::space(tmp.parent_path(), ec);
  constexpr std::uintmax_t kNearlyFull = 1u << 20;
  if (saved_errno == ENOSPC || (!ec && space.available < kNearlyFull)) {
    return fmt::format("No space left on device ({} KiB free on the file system of {}; GDAL said: {})",
                       ec ? 0 : space.available / 1024, tmp.parent_path().string(), last_gdal_error());
  }
  return last_gdal_error();
}

}  // namespace strata::gdal_detail
