#include "importers/scans/point_cloud.hpp"

#include "core/error.hpp"
#include "importers/scans/scan_formats.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>

namespace fs = std::filesystem;

namespace strata {

void PointCloud::clear() {
  positions.clear();
  colours.clear();
  intensities.clear();
  normals.clear();
}

namespace scan_formats {

std::string FilePosition::text() const {
  return fmt::format("{} {}", kind == Kind::line ? "line" : "byte", at);
}

ChunkBuilder::ChunkBuilder(const char* stage, fs::path file, const PointChunkSink& sink, std::size_t chunk_points)
    : SourceFile(stage, std::move(file)), sink_(sink), chunk_points_(chunk_points) {
  STRATA_CHECK(chunk_points_ > 0, "ReadOptions::chunk_points must be > 0");
  info_.min = Eigen::Vector3d::Constant(HUGE_VAL);
  info_.max = Eigen::Vector3d::Constant(-HUGE_VAL);
}

void ChunkBuilder::declare(bool colour, bool intensity, bool normals) {
  info_.has_colour = colour;
  info_.has_intensity = intensity;
  info_.has_normals = normals;
}

void ChunkBuilder::add(const ScanPoint& p, const FilePosition& at) {
  static constexpr const char* kAxis[] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(p.position[a])) {
      throw error(at, fmt::format("point {}: coordinate {} is {}", count_, kAxis[a], p.position[a]));
    }
  }
  chunk_.positions.push_back(p.position);
  if (info_.has_colour) chunk_.colours.push_back(p.colour);
  if (info_.has_intensity) chunk_.intensities.push_back(p.intensity);
  if (info_.has_normals) chunk_.normals.push_back(p.normal);
  info_.min = info_.min.cwiseMin(p.position);
  info_.max = info_.max.cwiseMax(p.position);
  ++count_;
  if (chunk_.size() >= chunk_points_) flush();
}

void ChunkBuilder::flush() {
  if (chunk_.size() == 0) return;
  sink_(chunk_, count_ - chunk_.size());
  chunk_.clear();
}

PointCloudInfo ChunkBuilder::finish(std::string format) {
  if (count_ == 0) throw error("the file holds no points (an empty cloud)");
  flush();
  info_.format = std::move(format);
  info_.points = count_;
  return info_;
}

InputError SourceFile::error(const FilePosition* at, const std::string& what) const {
  if (!at) return InputError(fmt::format("{}: {}: {}", stage_, file_.string(), what));
  return InputError(fmt::format("{}: {}: {}: {}", stage_, file_.string(), at->text(), what));
}

bool TextLines::next() {
  while (std::getline(in_, text_)) {
    ++line_;
    fields_.clear();
    std::string_view rest(text_);
    const auto first = rest.find_first_not_of(" \t\r");
    if (first == std::string_view::npos || rest[first] == '#') continue;
    std::size_t i = 0;
    while (i < rest.size()) {
      while (i < rest.size() && (std::isspace(static_cast<unsigned char>(rest[i])) || rest[i] == ',')) ++i;
      const std::size_t start = i;
      while (i < rest.size() && !std::isspace(static_cast<unsigned char>(rest[i])) && rest[i] != ',') ++i;
      if (i > start) fields_.push_back(rest.substr(start, i - start));
    }
    return true;
  }
  return false;
}

double parse_number(std::string_view field, const char* what, const SourceFile& source, const FilePosition& at) {
  std::string_view digits = field;
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);  // from_chars takes no '+'
  double v = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (digits.empty() || ec != std::errc() || end != digits.data() + digits.size()) {
    throw source.error(at, fmt::format("{} '{}' is not a number", what, field));
  }
  return v;
}

std::uint8_t parse_channel(std::string_view field, const char* what, const SourceFile& source,
                           const FilePosition& at) {
  const double v = parse_number(field, what, source, at);
  if (!(v >= 0 && v <= 255) || v != std::floor(v)) {
    throw source.error(at, fmt::format("{} '{}' is not a colour value 0-255", what, field));
  }
  return std::uint8_t(v);
}

InputError unsupported_format_error(const std::string& format, const fs::path& file) {
  const bool laz = format == "LAZ";
  return InputError(fmt::format(
      "{}: {}: {} is not read by strata (no Debian 12 package provides a library for it); {} and import that",
      kStage, file.string(), laz ? "LAZ (compressed LAS)" : format,
      laz ? "decompress it to LAS with laszip, PDAL or CloudCompare (e.g. 'pdal translate scan.laz scan.las')"
          : "convert it to LAS or PLY with CloudCompare or PDAL (e.g. 'pdal translate scan.e57 scan.las')"));
}

}  // namespace scan_formats

namespace {

using namespace scan_formats;

enum class Format { ply, pts, xyz, las, e57, laz, unknown };

std::string lower_extension(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

// The file's first bytes decide when they are a format's signature; the extension
// decides for the text formats, which have none.
Format detect_format(const fs::path& file, const std::string& head) {
  const std::string ext = lower_extension(file);
  if (head.rfind("ASTM-E57", 0) == 0 || ext == ".e57") return Format::e57;
  if (ext == ".laz") return Format::laz;
  if (head.rfind("ply\n", 0) == 0 || head.rfind("ply\r\n", 0) == 0 || ext == ".ply") return Format::ply;
  if (head.rfind("LASF", 0) == 0 || ext == ".las") return Format::las;
  if (ext == ".pts") return Format::pts;
  if (ext == ".xyz" || ext == ".txt" || ext == ".asc" || ext == ".csv") return Format::xyz;
  return Format::unknown;
}

}  // namespace

PointCloudInfo read_point_cloud_chunks(const fs::path& file, const PointChunkSink& sink, const ReadOptions& options) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: {}: cannot be opened for reading", kStage, file.string()));
  std::string head(16, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));
  in.clear();
  in.seekg(0);
  switch (detect_format(file, head)) {
    case Format::ply: {
      ChunkBuilder out(kPlyStage, file, sink, options.chunk_points);
      return out.finish(read_ply(in, out));
    }
    case Format::pts: {
      ChunkBuilder out(kPtsStage, file, sink, options.chunk_points);
      return out.finish(read_pts(in, out));
    }
    case Format::xyz: {
      ChunkBuilder out(kXyzStage, file, sink, options.chunk_points);
      return out.finish(read_xyz(in, out));
    }
    case Format::las: {
      ChunkBuilder out(kLasStage, file, sink, options.chunk_points);
      return out.finish(read_las(in, fs::file_size(file), out));
    }
    case Format::e57:
      throw unsupported_format_error("E57", file);
    case Format::laz:
      throw unsupported_format_error("LAZ", file);
    case Format::unknown:
      break;
  }
  throw InputError(fmt::format("{}: {}: not a point cloud strata reads (PLY, LAS, or by extension .pts, .xyz, "
                               ".txt, .asc, .csv)",
                               kStage, file.string()));
}

PointCloud read_point_cloud(const fs::path& file, PointCloudInfo* info) {
  PointCloud cloud;
  auto append = [&cloud](const PointCloud& chunk, std::uint64_t) {
    cloud.positions.insert(cloud.positions.end(), chunk.positions.begin(), chunk.positions.end());
    cloud.colours.insert(cloud.colours.end(), chunk.colours.begin(), chunk.colours.end());
    cloud.intensities.insert(cloud.intensities.end(), chunk.intensities.begin(), chunk.intensities.end());
    cloud.normals.insert(cloud.normals.end(), chunk.normals.begin(), chunk.normals.end());
  };
  const PointCloudInfo read = read_point_cloud_chunks(file, append);
  if (info) *info = read;
  return cloud;
}

}  // namespace strata
