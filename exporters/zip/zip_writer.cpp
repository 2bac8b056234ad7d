#include "exporters/zip/zip_writer.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <fmt/format.h>

#include <limits>

namespace strata {

void write_zip(const std::filesystem::path& path, const std::vector<ZipEntry>& entries,
               std::string_view fault_point) {
  write_atomically(path, "writer.zip", [&](const std::filesystem::path& tmp) {
    auto fail = [&](const std::string& what) {
      return IoError(fmt::format("writer.zip: {}: {}: {}", path.string(), what, CPLGetLastErrorMsg()));
    };
    CPLErrorReset();
    void* zip = CPLCreateZip(tmp.c_str(), nullptr);
    if (!zip) throw fail("cannot create the archive");
    bool ok = true;
    std::string failed;
    for (const ZipEntry& e : entries) {
      if (e.data.size() > std::size_t(std::numeric_limits<int>::max())) {
        failed = e.name + " is over 2 GB";
        ok = false;
        break;
      }
      ok = CPLCreateFileInZip(zip, e.name.c_str(), nullptr) == CE_None &&
           CPLWriteFileInZip(zip, e.data.data(), int(e.data.size())) == CE_None &&
           CPLCloseFileInZip(zip) == CE_None;
      if (!ok) {
        failed = "cannot write " + e.name;
        break;
      }
    }
    const bool closed = CPLCloseZip(zip) == CE_None;
    if (!ok) throw fail(failed);
    if (!closed) throw fail("cannot finish the archive");
  }, fault_point);
}

}  // namespace strata
