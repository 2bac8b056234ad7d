#pragma once
// The readers behind read_point_cloud_chunks(), one per format, and what they share
// (internal to importers/scans).
#include "core/error.hpp"
#include "importers/scans/point_cloud.hpp"

#include <bit>
#include <cstring>
#include <iosfwd>
#include <type_traits>
#include <string_view>

namespace strata::scan_formats {

constexpr const char* kStage = "importer.scans";
constexpr const char* kPlyStage = "importer.scans.ply";
constexpr const char* kPtsStage = "importer.scans.pts";
constexpr const char* kXyzStage = "importer.scans.xyz";
constexpr const char* kLasStage = "importer.scans.las";

// Where something is in a file, for messages: a line of a text file or a byte offset.
struct FilePosition {
  enum class Kind { line, byte } kind = Kind::line;
  std::uint64_t at = 0;  // 1-based line, or 0-based byte offset
  static FilePosition line(std::uint64_t n) { return {Kind::line, n}; }
  static FilePosition byte(std::uint64_t n) { return {Kind::byte, n}; }
  std::string text() const;  // "line 12", "byte 4096"
};

// One point as a reader decodes it; attributes the file lacks are ignored.
struct ScanPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Rgb8 colour{};
  float intensity = 0.0f;
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
};

// The file being read and the stage reading it, for messages.
class SourceFile {
 public:
  SourceFile(const char* stage, std::filesystem::path file) : stage_(stage), file_(std::move(file)) {}
  const char* stage() const { return stage_; }
  const std::filesystem::path& file() const { return file_; }
  // "importer.scans.ply: scan.ply: line 12: what" (no position when `at` is null).
  InputError error(const FilePosition* at, const std::string& what) const;
  InputError error(const FilePosition& at, const std::string& what) const { return error(&at, what); }
  InputError error(const std::string& what) const { return error(nullptr, what); }

 private:
  const char* stage_;
  std::filesystem::path file_;
};

// Gathers a reader's points into chunks for the sink, refusing coordinates that are
// not finite, and keeps the count and bounding box.
class ChunkBuilder : public SourceFile {
 public:
  ChunkBuilder(const char* stage, std::filesystem::path file, const PointChunkSink& sink, std::size_t chunk_points);

  // Which attributes the file has; set by the reader before its first point.
  void declare(bool colour, bool intensity, bool normals);
  void add(const ScanPoint& p, const FilePosition& at);
  std::uint64_t count() const { return count_; }
  // Hands over the last chunk; refuses a file without points.
  PointCloudInfo finish(std::string format);

 private:
  void flush();
  const PointChunkSink& sink_;
  std::size_t chunk_points_;
  PointCloud chunk_;
  PointCloudInfo info_;
  std::uint64_t count_ = 0;
};

// The lines of a text file split into fields at whitespace and commas, skipping
// blank lines and '#' comments.
class TextLines {
 public:
  explicit TextLines(std::istream& in, std::uint64_t lines_before = 0) : in_(in), line_(lines_before) {}
  bool next();  // false at the end of the file
  std::uint64_t line_number() const { return line_; }
  FilePosition position() const { return FilePosition::line(line_); }
  const std::vector<std::string_view>& fields() const { return fields_; }

 private:
  std::istream& in_;
  std::uint64_t line_;
  std::string text_;
  std::vector<std::string_view> fields_;
};

// A whole field as a number ("nan" and "inf" are numbers here: the point check
// names them); throws `source.error` naming the field otherwise.
double parse_number(std::string_view field, const char* what, const SourceFile& source, const FilePosition& at);
// A colour channel 0-255.
std::uint8_t parse_channel(std::string_view field, const char* what, const SourceFile& source,
                           const FilePosition& at);

// A value of type T stored at p with the other byte order than this machine's when
// `swap` (PLY's binary_big_endian on x86; LAS is little-endian).
template <typename T>
T load(const unsigned char* p, bool swap) {
  using Bits = std::conditional_t<sizeof(T) == 1, std::uint8_t,
               std::conditional_t<sizeof(T) == 2, std::uint16_t,
               std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;
  Bits b;
  std::memcpy(&b, p, sizeof b);
  if (swap) {
    Bits r = 0;
    for (std::size_t i = 0; i < sizeof b; ++i) r = Bits((r << 8) | ((b >> (8 * i)) & 0xFF));
    b = r;
  }
  return std::bit_cast<T>(b);
}

// The refusal of a format no Debian 12 package gives a library for, with what to
// convert it to.
InputError unsupported_format_error(const std::string& format, const std::filesystem::path& file);

// Each reader reads `in` from its start and returns the format's description.
std::string read_ply(std::istream& in, ChunkBuilder& out);
std::string read_pts(std::istream& in, ChunkBuilder& out);
std::string read_xyz(std::istream& in, ChunkBuilder& out);
std::string read_las(std::istream& in, std::uint64_t file_size, ChunkBuilder& out);

}  // namespace strata::scan_formats
