#include "features/cache_io.hpp"

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"

#include <atomic>
#include <cstring>
#include <fstream>
#include <iterator>
#include <system_error>
#include <unistd.h>

namespace strata::features {
namespace {

// Version 2 ends with the SHA-256 of everything before it, so a damaged file (a bad
// sector, a copy cut short, bytes changed by hand) is told from a good one; a
// version-1 file is stale, recomputed without a warning.
constexpr char kFeaturesMagic[8] = {'S', 'T', 'R', 'F', 'E', 'A', 'T', '2'};
constexpr char kMatchesMagic[8] = {'S', 'T', 'R', 'M', 'T', 'C', 'H', '2'};
constexpr char kFeaturesMagicV1[8] = {'S', 'T', 'R', 'F', 'E', 'A', 'T', '1'};
constexpr char kMatchesMagicV1[8] = {'S', 'T', 'R', 'M', 'T', 'C', 'H', '1'};
constexpr char kEndMagic[4] = {'E', 'N', 'D', '!'};
constexpr std::size_t kDigestBytes = 32;  // SHA-256

void seal(std::string& bytes) {
  Sha256 h;
  h.update(bytes.data(), bytes.size());
  const auto digest = h.digest();
  bytes.append(reinterpret_cast<const char*>(digest.data()), digest.size());
}

// Drops the digest; false when it does not match the rest.
bool unseal(std::string& bytes) {
  if (bytes.size() < kDigestBytes) return false;
  Sha256 h;
  h.update(bytes.data(), bytes.size() - kDigestBytes);
  const auto digest = h.digest();
  if (std::memcmp(digest.data(), bytes.data() + bytes.size() - kDigestBytes, kDigestBytes) != 0) return false;
  bytes.resize(bytes.size() - kDigestBytes);
  return true;
}

bool starts_with(const std::string& bytes, const char (&magic)[8]) {
  return bytes.size() >= sizeof magic && std::memcmp(bytes.data(), magic, sizeof magic) == 0;
}

class ByteWriter {
 public:
  void raw(const void* data, std::size_t size) {
    out_.append(static_cast<const char*>(data), size);
  }
  template <typename T>
  void value(const T& v) {
    raw(&v, sizeof(T));
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

// Reads with bounds checks; ok() turns false on the first overrun.
class ByteReader {
 public:
  explicit ByteReader(const std::string& in) : in_(in) {}
  bool raw(void* data, std::size_t size) {
    if (!ok_ || size > in_.size() - pos_) return ok_ = false;
    std::memcpy(data, in_.data() + pos_, size);
    pos_ += size;
    return true;
  }
  template <typename T>
  bool value(T& v) {
    return raw(&v, sizeof(T));
  }
  bool expect(const char* magic, std::size_t size) {
    std::string got(size, '\0');
    return raw(got.data(), size) && std::memcmp(got.data(), magic, size) == 0;
  }
  std::size_t remaining() const { return in_.size() - pos_; }
  bool ok() const { return ok_; }

 private:
  const std::string& in_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

std::optional<std::string> read_all(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return std::nullopt;
  return bytes;
}

std::filesystem::path sharded(const std::filesystem::path& dir, const std::string& key,
                              const char* extension) {
  const std::string shard = key.size() >= 2 ? key.substr(0, 2) : std::string("00");
  return dir / shard / (key + extension);
}

}  // namespace

std::filesystem::path features_file(const std::filesystem::path& cache_dir,
                                    const std::string& features_key) {
  return sharded(cache_dir / "features", features_key, ".sift");
}

std::filesystem::path matches_file(const std::filesystem::path& cache_dir,
                                   const std::string& match_key) {
  return sharded(cache_dir / "matches", match_key, ".match");
}

void write_features(const std::filesystem::path& path, const StoredFeatures& f) {
  const std::size_t n = f.points.size();
  STRATA_CHECK(f.scales.size() == n && f.colours.size() == 3 * n &&
               f.descriptors.size() == n * kDescriptorDim);
  ByteWriter w;
  w.bytes().reserve(32 + n * (16 + 4 + 3 + kDescriptorDim));
  w.raw(kFeaturesMagic, sizeof kFeaturesMagic);
  w.value(static_cast<std::uint32_t>(n));
  w.value(static_cast<std::uint32_t>(kDescriptorDim));
  for (const auto& p : f.points) {
    w.value(p.x());
    w.value(p.y());
  }
  w.raw(f.scales.data(), n * sizeof(float));
  w.raw(f.colours.data(), f.colours.size());
  w.raw(f.descriptors.data(), f.descriptors.size());
  w.raw(kEndMagic, sizeof kEndMagic);
  seal(w.bytes());
  write_bytes_atomically(path, "features cache", w.bytes(), "process.features.file_temp_written");
}

std::optional<StoredFeatures> read_features(const std::filesystem::path& path) {
  auto bytes = read_all(path);
  if (!bytes || starts_with(*bytes, kFeaturesMagicV1)) return std::nullopt;
  const bool sealed = unseal(*bytes);
  ByteReader r(*bytes);
  std::uint32_t n = 0, dim = 0;
  bool ok = sealed && r.expect(kFeaturesMagic, sizeof kFeaturesMagic) && r.value(n) && r.value(dim) &&
            dim == kDescriptorDim &&
            r.remaining() == n * (16ull + 4 + 3 + kDescriptorDim) + sizeof kEndMagic;
  StoredFeatures f;
  if (ok) {
    f.points.resize(n);
    for (auto& p : f.points) {
      double x = 0, y = 0;
      r.value(x);
      r.value(y);
      p = {x, y};
    }
    f.scales.resize(n);
    f.colours.resize(3 * std::size_t{n});
    f.descriptors.resize(std::size_t{n} * kDescriptorDim);
    r.raw(f.scales.data(), n * sizeof(float));
    r.raw(f.colours.data(), f.colours.size());
    r.raw(f.descriptors.data(), f.descriptors.size());
    ok = r.expect(kEndMagic, sizeof kEndMagic) && r.ok();
  }
  if (!ok) {
    log::warn("features cache: ignoring corrupt file {} (it will be recomputed)",
              path.string());
    return std::nullopt;
  }
  return f;
}

void write_matches(const std::filesystem::path& path, const StoredMatches& m) {
  ByteWriter w;
  w.raw(kMatchesMagic, sizeof kMatchesMagic);
  w.value(static_cast<std::uint32_t>(m.model));
  w.value(static_cast<std::uint32_t>(m.homography_inliers));
  w.value(static_cast<std::uint32_t>(m.putative));
  w.value(static_cast<std::uint32_t>(m.matches.size()));
  for (const auto& [a, b] : m.matches) {
    w.value(static_cast<std::uint32_t>(a));
    w.value(static_cast<std::uint32_t>(b));
  }
  w.raw(kEndMagic, sizeof kEndMagic);
  seal(w.bytes());
  write_bytes_atomically(path, "features cache", w.bytes(), "process.features.file_temp_written");
}

std::optional<StoredMatches> read_matches(const std::filesystem::path& path) {
  auto bytes = read_all(path);
  if (!bytes || starts_with(*bytes, kMatchesMagicV1)) return std::nullopt;
  const bool sealed = unseal(*bytes);
  ByteReader r(*bytes);
  std::uint32_t model = 0, h = 0, putative = 0, n = 0;
  bool ok = sealed && r.expect(kMatchesMagic, sizeof kMatchesMagic) && r.value(model) && r.value(h) &&
            r.value(putative) && r.value(n) &&
            model <= static_cast<std::uint32_t>(TwoViewModel::homography) &&
            r.remaining() == n * 8ull + sizeof kEndMagic;
  StoredMatches m;
  if (ok) {
    m.model = static_cast<TwoViewModel>(model);
    m.homography_inliers = static_cast<int>(h);
    m.putative = static_cast<int>(putative);
    m.matches.resize(n);
    for (auto& [a, b] : m.matches) {
      std::uint32_t ua = 0, ub = 0;
      r.value(ua);
      r.value(ub);
      a = static_cast<int>(ua);
      b = static_cast<int>(ub);
    }
    ok = r.expect(kEndMagic, sizeof kEndMagic) && r.ok();
  }
  if (!ok) {
    log::warn("matches cache: ignoring corrupt file {} (it will be recomputed)",
              path.string());
    return std::nullopt;
  }
  return m;
}

}  // namespace strata::features
