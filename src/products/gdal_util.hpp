#pragma once
// GDAL plumbing shared by the products module's .cpp files (internal header:
// it includes GDAL, so it stays out of the public headers).
#include <gdal_priv.h>

#include <memory>
#include <mutex>

namespace strata::products_detail {

// Registers GDAL's drivers once per process.
inline void init_gdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

}  // namespace strata::products_detail
