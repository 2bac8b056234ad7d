// Cache files of the dense stage: undistorted images and depth maps, raw
// little-endian arrays behind a small header with a version and a content key.
// The cache is deletable (design.md): a missing or stale file is recomputed.
#include "core/error.hpp"
#include "core/fault.hpp"
#include "dense/internal.hpp"

#include <fmt/format.h>

#include <array>
#include <cstring>
#include <fstream>
#include <system_error>

namespace strata::dense {
namespace {

constexpr std::array<char, 8> kDepthMagic{'S', 'T', 'R', 'D', 'M', 'A', 'P', '1'};
constexpr std::array<char, 8> kImageMagic{'S', 'T', 'R', 'V', 'I', 'M', 'G', '1'};

template <typename T>
void put(std::ofstream& f, const T& v) {
  f.write(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <typename T>
void put_array(std::ofstream& f, const std::vector<T>& v) {
  f.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
}
template <typename T>
bool get(std::ifstream& f, T& v) {
  return static_cast<bool>(f.read(reinterpret_cast<char*>(&v), sizeof(T)));
}
template <typename T>
bool get_array(std::ifstream& f, std::vector<T>& v, std::size_t n) {
  v.resize(n);
  return static_cast<bool>(
      f.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(n * sizeof(T))));
}

}  // namespace

std::uint64_t hash_bytes(const void* data, std::size_t size, std::uint64_t seed) {
  // FNV-1a, 64 bit: a cache key, not a checksum of record (products use SHA-256).
  std::uint64_t h = 0xcbf29ce484222325ull ^ seed;
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

void write_file_atomically(const std::filesystem::path& path, const std::string& stage,
                           const std::function<void(const std::filesystem::path& tmp)>& write) {
  std::error_code ec;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  if (ec) {
    throw IoError(fmt::format("{}: {}: cannot create folder: {}", stage,
                              path.parent_path().string(), ec.message()));
  }
  const std::filesystem::path tmp = path.string() + ".tmp";
  try {
    write(tmp);
  } catch (...) {
    std::filesystem::remove(tmp, ec);
    throw;
  }
  fault::point(stage == "dense.cache" ? "process.dense.cache_temp_written" : "process.dense.product_temp_written");
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw IoError(fmt::format("{}: {}: cannot rename the temporary file", stage, path.string()));
  }
}

void write_depth_map(const std::filesystem::path& path, const DepthMap& map, std::uint64_t key) {
  write_file_atomically(path, "dense.cache", [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw IoError(fmt::format("dense.cache: {}: cannot write", tmp.string()));
    f.write(kDepthMagic.data(), kDepthMagic.size());
    put(f, key);
    put(f, static_cast<std::int32_t>(map.width));
    put(f, static_cast<std::int32_t>(map.height));
    put_array(f, map.depth);
    put_array(f, map.normal);
    put_array(f, map.confidence);
    if (!f) throw IoError(fmt::format("dense.cache: {}: write failed", tmp.string()));
  });
}

bool read_depth_map(const std::filesystem::path& path, std::uint64_t key, DepthMap& out) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  std::array<char, 8> magic{};
  std::uint64_t k = 0;
  std::int32_t w = 0, h = 0;
  if (!f.read(magic.data(), magic.size()) || magic != kDepthMagic) return false;
  if (!get(f, k) || k != key || !get(f, w) || !get(f, h) || w <= 0 || h <= 0) return false;
  const auto n = static_cast<std::size_t>(w) * h;
  out.width = w;
  out.height = h;
  return get_array(f, out.depth, n) && get_array(f, out.normal, 3 * n) &&
         get_array(f, out.confidence, n);
}

void write_view_image(const std::filesystem::path& path, const ViewImage& image, std::uint64_t key) {
  write_file_atomically(path, "dense.cache", [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw IoError(fmt::format("dense.cache: {}: cannot write", tmp.string()));
    f.write(kImageMagic.data(), kImageMagic.size());
    put(f, key);
    const auto& c = image.camera;
    put(f, static_cast<std::int32_t>(c.width));
    put(f, static_cast<std::int32_t>(c.height));
    for (double v : {c.fx, c.fy, c.cx, c.cy}) put(f, v);
    f.write(reinterpret_cast<const char*>(c.pose.R.data()), 9 * sizeof(double));
    f.write(reinterpret_cast<const char*>(c.pose.t.data()), 3 * sizeof(double));
    put_array(f, image.gray);
    put_array(f, image.rgb);
    if (!f) throw IoError(fmt::format("dense.cache: {}: write failed", tmp.string()));
  });
}

bool read_view_image(const std::filesystem::path& path, std::uint64_t key, ViewImage& out) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  std::array<char, 8> magic{};
  std::uint64_t k = 0;
  std::int32_t w = 0, h = 0;
  if (!f.read(magic.data(), magic.size()) || magic != kImageMagic) return false;
  if (!get(f, k) || k != key || !get(f, w) || !get(f, h) || w <= 0 || h <= 0) return false;
  auto& c = out.camera;
  c.width = w;
  c.height = h;
  if (!get(f, c.fx) || !get(f, c.fy) || !get(f, c.cx) || !get(f, c.cy)) return false;
  if (!f.read(reinterpret_cast<char*>(c.pose.R.data()), 9 * sizeof(double))) return false;
  if (!f.read(reinterpret_cast<char*>(c.pose.t.data()), 3 * sizeof(double))) return false;
  const auto n = static_cast<std::size_t>(w) * h;
  return get_array(f, out.gray, n) && get_array(f, out.rgb, 3 * n);
}

}  // namespace strata::dense
