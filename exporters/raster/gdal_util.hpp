#pragma once
// GDAL plumbing shared by the .cpp files that write through GDAL (an internal
// header: it includes GDAL, so it stays out of the public headers).
#include <cpl_string.h>
#include <gdal_priv.h>

#include <filesystem>
#include <memory>
#include <mutex>
#include <string>

namespace strata::gdal_detail {

// Registers GDAL's drivers once per process.
inline void init_gdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

// True when GDAL's last error since CPLErrorReset() is a failure: how a write that
// fails only on its flush at close (a full disk) shows.
inline bool gdal_failed() {
  const CPLErr e = CPLGetLastErrorType();
  return e == CE_Failure || e == CE_Fatal;
}

// GDAL's last error message, or "unknown GDAL error".
std::string last_gdal_error();
// Why writing `tmp` failed: a full disk named as such ("No space left on device (N KiB
// free on ...)"; GDAL reports it as whatever libtiff met first), else GDAL's message.
// Call with errno and GDAL's error state as the failed write left them.
std::string write_failure(const std::filesystem::path& tmp);

// Owned list of "KEY=VALUE" creation options.
class Options {
 public:
  Options() = default;
  ~Options() { CSLDestroy(list_); }
  Options(const Options&) = delete;
  Options& operator=(const Options&) = delete;
  void set(const char* key, const std::string& value) { list_ = CSLSetNameValue(list_, key, value.c_str()); }
  char** get() const { return list_; }

 private:
  char** list_ = nullptr;
};

}  // namespace strata::gdal_detail
