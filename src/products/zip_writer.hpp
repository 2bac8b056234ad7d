#pragma once
// A minimal ZIP writer (PKWARE APPNOTE 6.3.x): entries stored without compression,
// with their CRC-32. Enough for a QGIS .qgz, which is a zip holding the .qgs.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace strata {

struct ZipEntry {
  std::string name;               // path inside the archive, '/' separated
  std::vector<std::uint8_t> data;
};

// CRC-32 (ISO 3309, reflected polynomial 0xEDB88320), as ZIP and PNG use it.
std::uint32_t crc32(const std::uint8_t* data, std::size_t size);

// Writes the archive through a temporary file and a rename. Throws IoError.
void write_zip_stored(const std::filesystem::path& path, const std::vector<ZipEntry>& entries);

}  // namespace strata
