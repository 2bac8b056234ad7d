// importer.scans.las: ASPRS LAS 1.2-1.4 (R13/R14 specifications), uncompressed,
// point data formats 0-3 and 6-8: coordinates as integers times the header's scale
// plus its offset, intensity, and RGB where the format has it. Extra bytes after a
// record's standard fields (record length larger than the format's) are skipped.
// The whole header is checked, and the file's size against the declared points,
// before a point is read; then records are read a chunk at a time.
#include "importers/scans/scan_formats.hpp"

#include <array>
#include <cmath>
#include <istream>
#include <optional>

namespace strata::scan_formats {
namespace {

constexpr bool kSwap = std::endian::native == std::endian::big;  // LAS is little-endian
constexpr std::size_t kRecordsPerRead = 1 << 16;

// Byte offsets in the public header block (LAS 1.4 R14, table 3).
constexpr std::size_t kVersionMajor = 24, kHeaderSize = 94, kPointOffset = 96, kPointFormat = 104,
                      kRecordLength = 105, kLegacyCount = 107, kScale = 131, kOffset = 155, kCount14 = 247;
constexpr std::size_t kHeaderRead = 375;  // the 1.4 header, the longest

std::size_t header_size_of(int minor) { return minor == 2 ? 227 : minor == 3 ? 235 : 375; }

struct PointLayout {
  std::size_t length = 0;  // bytes of the standard fields
  int rgb_at = -1;         // offset of red, green, blue (uint16 each), -1 when none
};

// The formats read: 0 and 1 (1.2 and later), 2 and 3 (with RGB), 6-8 (1.4 only).
std::optional<PointLayout> layout_of(int format) {
  switch (format) {
    case 0: return PointLayout{20, -1};
    case 1: return PointLayout{28, -1};
    case 2: return PointLayout{26, 20};
    case 3: return PointLayout{34, 28};
    case 6: return PointLayout{30, -1};
    case 7: return PointLayout{36, 30};
    case 8: return PointLayout{38, 30};
    default: return std::nullopt;
  }
}

struct LasHeader {
  int minor = 0;
  int format = 0;
  PointLayout layout;
  std::uint64_t point_offset = 0;
  std::size_t record_length = 0;
  std::uint64_t count = 0;
  Eigen::Vector3d scale, offset;
};

LasHeader read_header(std::istream& in, std::uint64_t file_size, const std::filesystem::path& file,
                      const ChunkBuilder& out) {
  std::array<unsigned char, kHeaderRead> h{};
  in.read(reinterpret_cast<char*>(h.data()), std::streamsize(h.size()));
  const std::size_t got = std::size_t(in.gcount());
  auto at = [](std::size_t byte) { return FilePosition::byte(byte); };
  if (got < 4 || std::memcmp(h.data(), "LASF", 4) != 0) {
    throw out.error(at(0), "not a LAS file: it must start with 'LASF'");
  }
  LasHeader l;
  const int major = h[kVersionMajor];
  l.minor = h[kVersionMajor + 1];
  if (got < header_size_of(2)) {
    throw out.error(at(got), "the file ends inside the LAS header (truncated)");
  }
  if (major != 1 || l.minor < 2 || l.minor > 4) {
    throw out.error(at(kVersionMajor), fmt::format("LAS version {}.{} is not read (1.2, 1.3 or 1.4)", major, l.minor));
  }
  const std::size_t header_size = load<std::uint16_t>(&h[kHeaderSize], kSwap);
  if (header_size < header_size_of(l.minor)) {
    throw out.error(at(kHeaderSize), fmt::format("header size {} is less than LAS 1.{}'s {} bytes", header_size,
                                                 l.minor, header_size_of(l.minor)));
  }
  if (got < header_size_of(l.minor)) throw out.error(at(got), "the file ends inside the LAS header (truncated)");
  const int format_byte = h[kPointFormat];
  // LASzip marks compressed points by setting bit 7 (and 6) of the format number.
  if (format_byte & 0xC0) throw unsupported_format_error("LAZ", file);
  l.format = format_byte;
  const auto layout = layout_of(l.format);
  if (!layout || (l.format >= 6 && l.minor < 4)) {
    throw out.error(at(kPointFormat), fmt::format("point data format {} is not read in LAS 1.{} (formats 0-3, and "
                                                  "6-8 in LAS 1.4)",
                                                  l.format, l.minor));
  }
  l.layout = *layout;
  l.record_length = load<std::uint16_t>(&h[kRecordLength], kSwap);
  if (l.record_length < l.layout.length) {
    throw out.error(at(kRecordLength), fmt::format("point record length {} is less than point format {}'s {} bytes",
                                                   l.record_length, l.format, l.layout.length));
  }
  l.point_offset = load<std::uint32_t>(&h[kPointOffset], kSwap);
  if (l.point_offset < header_size) {
    throw out.error(at(kPointOffset), fmt::format("the points start at byte {}, inside the {}-byte header",
                                                  l.point_offset, header_size));
  }
  l.count = load<std::uint32_t>(&h[kLegacyCount], kSwap);
  if (l.minor == 4) {
    const std::uint64_t count64 = load<std::uint64_t>(&h[kCount14], kSwap);
    if (count64 != 0) l.count = count64;
  }
  for (int a = 0; a < 3; ++a) {
    l.scale[a] = load<double>(&h[kScale + 8 * std::size_t(a)], kSwap);
    l.offset[a] = load<double>(&h[kOffset + 8 * std::size_t(a)], kSwap);
    if (!std::isfinite(l.scale[a]) || l.scale[a] == 0 || !std::isfinite(l.offset[a])) {
      throw out.error(at(kScale + 8 * std::size_t(a)), fmt::format("the {} scale {} or offset {} is not usable",
                                                                 "xyz"[a], l.scale[a], l.offset[a]));
    }
  }
  // Complete records the file holds (no overflow for a damaged, huge count).
  const std::uint64_t complete = file_size < l.point_offset ? 0 : (file_size - l.point_offset) / l.record_length;
  if (complete < l.count) {
    throw out.error(at(file_size), fmt::format("the file ends inside point {} of the {} declared ({} bytes each "
                                               "from byte {}; truncated)",
                                               complete, l.count, l.record_length, l.point_offset));
  }
  return l;
}

}  // namespace

std::string read_las(std::istream& in, std::uint64_t file_size, ChunkBuilder& out) {
  const LasHeader l = read_header(in, file_size, out.file(), out);
  const bool rgb = l.layout.rgb_at >= 0;
  out.declare(rgb, true, false);
  in.clear();
  in.seekg(std::streamoff(l.point_offset));
  std::vector<unsigned char> buffer;
  for (std::uint64_t first = 0; first < l.count; first += kRecordsPerRead) {
    const std::size_t n = std::size_t(std::min<std::uint64_t>(kRecordsPerRead, l.count - first));
    buffer.resize(n * l.record_length);
    in.read(reinterpret_cast<char*>(buffer.data()), std::streamsize(buffer.size()));
    const std::uint64_t start = l.point_offset + first * l.record_length;
    if (std::size_t(in.gcount()) != buffer.size()) {  // the size was checked: the file shrank, or a read error
      throw out.error(FilePosition::byte(start + std::uint64_t(in.gcount())), "cannot read the points (truncated)");
    }
    for (std::size_t i = 0; i < n; ++i) {
      const unsigned char* r = buffer.data() + i * l.record_length;
      ScanPoint p;
      for (int a = 0; a < 3; ++a) {
        p.position[a] = double(load<std::int32_t>(r + 4 * a, kSwap)) * l.scale[a] + l.offset[a];
      }
      p.intensity = float(load<std::uint16_t>(r + 12, kSwap));
      if (rgb) {
        // LAS colour is 16 bits a channel; 8-bit viewers take the high byte.
        for (int c = 0; c < 3; ++c) p.colour[std::size_t(c)] = std::uint8_t(load<std::uint16_t>(r + l.layout.rgb_at + 2 * c, kSwap) >> 8);
      }
      out.add(p, FilePosition::byte(start + i * l.record_length));
    }
  }
  return fmt::format("las 1.{} point format {}", l.minor, l.format);
}

}  // namespace strata::scan_formats
