#pragma once
// ZIP archives through GDAL's writer (CPLCreateZip, DEFLATE): a QGIS .qgz is a zip
// holding the .qgs.
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace strata {

struct ZipEntry {
  std::string name;  // path inside the archive, '/' separated
  std::string data;
};

// Writes the archive through a temporary file and a rename; `fault_point` as in
// write_atomically. Throws IoError.
void write_zip(const std::filesystem::path& path, const std::vector<ZipEntry>& entries,
               std::string_view fault_point = {});

}  // namespace strata
