#include "core/vdb_uuid.hpp"

#include "core/error.hpp"
#include "core/hash.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cstring>
#include <fstream>
#include <vector>

namespace strata {
namespace {

// The header: magic (8 bytes), file version (4), library major and minor (4 + 4),
// "has grid offsets" (1), then the UUID as 36 ASCII characters (file version >= 220).
constexpr std::size_t kUuidOffset = 21;
constexpr std::size_t kUuidSize = 36;
constexpr unsigned char kMagic[4] = {0x20, 0x42, 0x44, 0x56};  // 0x56444220, little-endian

bool is_uuid_text(const std::vector<char>& b) {
  for (std::size_t i = 0; i < kUuidSize; ++i) {
    const char c = b[kUuidOffset + i];
    const bool dash = i == 8 || i == 13 || i == 18 || i == 23;
    if (dash ? c != '-' : !std::isxdigit(static_cast<unsigned char>(c))) return false;
  }
  return true;
}

}  // namespace

void make_vdb_uuid_from_content(const std::filesystem::path& path) {
  std::vector<char> bytes;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(fmt::format("{}: cannot read the OpenVDB file", path.string()));
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  if (bytes.size() < kUuidOffset + kUuidSize || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0 ||
      !is_uuid_text(bytes)) {
    throw IoError(fmt::format("{}: not an OpenVDB file with a UUID in its header", path.string()));
  }
  // The hash of the file with the UUID's bytes zeroed, without a second copy of it.
  const char zeros[kUuidSize] = {};
  Sha256 h;
  h.update(bytes.data(), kUuidOffset);
  h.update(zeros, kUuidSize);
  h.update(bytes.data() + kUuidOffset + kUuidSize, bytes.size() - kUuidOffset - kUuidSize);
  const std::string hex = h.hex_digest();
  // 32 hex digits as 8-4-4-4-12, version 4 and the RFC 4122 variant, like the UUID it replaces.
  std::string uuid = hex.substr(0, 8) + "-" + hex.substr(8, 4) + "-4" + hex.substr(13, 3) + "-" +
                     "89ab"[std::stoi(hex.substr(16, 1), nullptr, 16) & 3] + hex.substr(17, 3) + "-" +
                     hex.substr(20, 12);
  std::fstream out(path, std::ios::binary | std::ios::in | std::ios::out);
  out.seekp(std::streamoff(kUuidOffset));
  out.write(uuid.data(), std::streamsize(uuid.size()));
  out.close();
  if (!out) throw IoError(fmt::format("{}: cannot write the OpenVDB file's UUID", path.string()));
}

}  // namespace strata
