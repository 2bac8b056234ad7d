// Cache files of the dense stage: undistorted images and depth maps, raw
// little-endian arrays behind a small header with a version and a content key, and
// a checksum of everything before it. The cache is deletable (design.md): a missing
// or stale file is recomputed; a damaged one too, with a warning.
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "dense/internal.hpp"

#include <fmt/format.h>

#include <array>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <system_error>

namespace strata::dense {
namespace {

// Version 2 adds the checksum; a version-1 file is stale, not damaged.
constexpr std::array<char, 8> kDepthMagic{'S', 'T', 'R', 'D', 'M', 'A', 'P', '2'};
constexpr std::array<char, 8> kImageMagic{'S', 'T', 'R', 'V', 'I', 'M', 'G', '2'};
constexpr std::array<char, 8> kDepthMagicV1{'S', 'T', 'R', 'D', 'M', 'A', 'P', '1'};
constexpr std::array<char, 8> kImageMagicV1{'S', 'T', 'R', 'V', 'I', 'M', 'G', '1'};
constexpr std::uint64_t kChecksumSeed = 0x64656e7365ull;  // "dense"

// A whole cache file built in memory, then written once with its checksum.
class FileBytes {
 public:
  template <typename T>
  void put(const T& v) {
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <typename T>
  void put_array(const std::vector<T>& v) {
    bytes_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void put_raw(const char* data, std::size_t n) { bytes_.append(data, n); }
  void write_sealed(const std::filesystem::path& tmp) {
    const std::uint64_t sum = hash_bytes(bytes_.data(), bytes_.size(), kChecksumSeed);
    put(sum);
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw IoError(fmt::format("dense.cache: {}: cannot write", tmp.string()));
    f.write(bytes_.data(), static_cast<std::streamsize>(bytes_.size()));
    f.close();  // a full disk shows at the flush
    if (!f) throw IoError(fmt::format("dense.cache: {}: write failed: {}", tmp.string(), std::strerror(errno)));
  }

 private:
  std::string bytes_;
};

// Reads a cache file back with bounds checks; ok() turns false on the first overrun.
class FileReader {
 public:
  explicit FileReader(std::string bytes) : bytes_(std::move(bytes)) {}
  template <typename T>
  bool get(T& v) {
    return get_raw(reinterpret_cast<char*>(&v), sizeof(T));
  }
  template <typename T>
  bool get_array(std::vector<T>& v, std::size_t n) {
    // The count comes from the file: it must fit in what the file holds.
    if (!ok_ || n > (bytes_.size() - pos_) / sizeof(T)) return ok_ = false;
    v.resize(n);
    return get_raw(reinterpret_cast<char*>(v.data()), n * sizeof(T));
  }
  bool get_raw(char* out, std::size_t n) {
    if (!ok_ || n > bytes_.size() - pos_) return ok_ = false;
    std::memcpy(out, bytes_.data() + pos_, n);
    pos_ += n;
    return true;
  }
  // True when the last 8 bytes are the checksum of the others; they are dropped.
  bool unseal() {
    std::uint64_t sum = 0;
    if (bytes_.size() < sizeof sum) return false;
    std::memcpy(&sum, bytes_.data() + bytes_.size() - sizeof sum, sizeof sum);
    bytes_.resize(bytes_.size() - sizeof sum);
    return hash_bytes(bytes_.data(), bytes_.size(), kChecksumSeed) == sum;
  }
  bool at_end() const { return ok_ && pos_ == bytes_.size(); }

 private:
  std::string bytes_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

std::optional<std::string> read_file(const std::filesystem::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return std::nullopt;
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) return std::nullopt;
  return bytes;
}

enum class Header { ok, stale, damaged };

// The magic and the content key. A file of another key or an older version is
// stale (recomputed quietly); one that fails its checksum is damaged.
Header read_header(FileReader& r, const std::array<char, 8>& magic, const std::array<char, 8>& old_magic,
                   std::uint64_t key) {
  std::array<char, 8> got{};
  if (!r.get_raw(got.data(), got.size())) return Header::damaged;
  if (got == old_magic) return Header::stale;
  if (got != magic) return Header::damaged;
  std::uint64_t k = 0;
  if (!r.get(k)) return Header::damaged;
  return k == key ? Header::ok : Header::stale;
}

void warn_damaged(const std::filesystem::path& path) {
  log::warn("dense.cache: ignoring corrupt file {} (it will be recomputed)", path.string());
}

}  // namespace

std::uint64_t hash_bytes(const void* data, std::size_t size, std::uint64_t seed) {
  // FNV-1a, 64 bit: finds damage; not a checksum of record (products use SHA-256).
  std::uint64_t h = 0xcbf29ce484222325ull ^ seed;
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

void write_depth_map(const std::filesystem::path& path, const DepthMap& map, std::uint64_t key) {
  write_atomically(path, "dense.cache", [&](const std::filesystem::path& tmp) {
    FileBytes f;
    f.put_raw(kDepthMagic.data(), kDepthMagic.size());
    f.put(key);
    f.put(static_cast<std::int32_t>(map.width));
    f.put(static_cast<std::int32_t>(map.height));
    f.put_array(map.depth);
    f.put_array(map.normal);
    f.put_array(map.confidence);
    f.write_sealed(tmp);
  }, "process.dense.cache_temp_written");
}

bool read_depth_map(const std::filesystem::path& path, std::uint64_t key, DepthMap& out) {
  auto bytes = read_file(path);
  if (!bytes) return false;
  FileReader r(std::move(*bytes));
  const bool sealed = r.unseal();
  const Header h = read_header(r, kDepthMagic, kDepthMagicV1, key);
  if (h == Header::stale && sealed) return false;
  std::int32_t w = 0, h_px = 0;
  if (!sealed || h != Header::ok || !r.get(w) || !r.get(h_px) || w <= 0 || h_px <= 0) {
    if (h != Header::stale) warn_damaged(path);
    return false;
  }
  const auto n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h_px);
  out.width = w;
  out.height = h_px;
  if (!r.get_array(out.depth, n) || !r.get_array(out.normal, 3 * n) || !r.get_array(out.confidence, n) ||
      !r.at_end()) {
    warn_damaged(path);
    return false;
  }
  return true;
}

void write_view_image(const std::filesystem::path& path, const ViewImage& image, std::uint64_t key) {
  write_atomically(path, "dense.cache", [&](const std::filesystem::path& tmp) {
    FileBytes f;
    f.put_raw(kImageMagic.data(), kImageMagic.size());
    f.put(key);
    const auto& c = image.camera;
    f.put(static_cast<std::int32_t>(c.width));
    f.put(static_cast<std::int32_t>(c.height));
    for (double v : {c.fx, c.fy, c.cx, c.cy}) f.put(v);
    f.put_raw(reinterpret_cast<const char*>(c.pose.R.data()), 9 * sizeof(double));
    f.put_raw(reinterpret_cast<const char*>(c.pose.t.data()), 3 * sizeof(double));
    f.put_array(image.gray);
    f.put_array(image.rgb);
    f.write_sealed(tmp);
  }, "process.dense.cache_temp_written");
}

bool read_view_image(const std::filesystem::path& path, std::uint64_t key, ViewImage& out) {
  auto bytes = read_file(path);
  if (!bytes) return false;
  FileReader r(std::move(*bytes));
  const bool sealed = r.unseal();
  const Header h = read_header(r, kImageMagic, kImageMagicV1, key);
  if (h == Header::stale && sealed) return false;
  auto& c = out.camera;
  std::int32_t w = 0, h_px = 0;
  if (!sealed || h != Header::ok || !r.get(w) || !r.get(h_px) || w <= 0 || h_px <= 0) {
    if (h != Header::stale) warn_damaged(path);
    return false;
  }
  c.width = w;
  c.height = h_px;
  const auto n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h_px);
  if (!r.get(c.fx) || !r.get(c.fy) || !r.get(c.cx) || !r.get(c.cy) ||
      !r.get_raw(reinterpret_cast<char*>(c.pose.R.data()), 9 * sizeof(double)) ||
      !r.get_raw(reinterpret_cast<char*>(c.pose.t.data()), 3 * sizeof(double)) || !r.get_array(out.gray, n) ||
      !r.get_array(out.rgb, 3 * n) || !r.at_end()) {
    warn_damaged(path);
    return false;
  }
  return true;
}

}  // namespace strata::dense
