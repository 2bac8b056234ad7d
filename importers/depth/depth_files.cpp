#include "importers/depth/depth_files.hpp"

#include "core/error.hpp"
#include "importers/scans/scan_formats.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <functional>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <set>

namespace fs = std::filesystem;

namespace strata {
namespace {

using scan_formats::FilePosition;
using scan_formats::SourceFile;

constexpr const char* kPngStage = "importer.depth.png";
constexpr const char* kColourStage = "importer.depth.colour";
constexpr const char* kIntrinsicsStage = "importer.depth.intrinsics";
constexpr const char* kPosesStage = "importer.depth.poses";

constexpr std::array<unsigned char, 8> kPngSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
// A chunk's length is at most 2^31 - 1 bytes (PNG specification, 5.3).
constexpr std::uint64_t kMaxChunkLength = 0x7FFFFFFFull;
// A unit quaternion as a text file writes it: 9 decimals are usual, 4 still pass.
constexpr double kQuaternionNormTolerance = 1e-3;
constexpr int kMaxImageSide = 20000;  // pixels: no depth camera comes near

// CRC-32 of ISO 3309 / ITU-T V.42 as PNG uses it (PNG specification, annex D).
std::uint32_t crc32(const unsigned char* data, std::size_t n, std::uint32_t crc = 0xFFFFFFFFu) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ data[i]) & 0xFF] ^ (crc >> 8);
  return crc;
}

std::uint32_t big_endian32(const unsigned char* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | std::uint32_t(p[3]);
}

std::vector<unsigned char> read_bytes(const fs::path& file, const char* stage) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: {}: cannot be opened for reading", stage, file.string()));
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

const char* colour_type_name(int t) {
  switch (t) {
    case 0: return "grey";
    case 2: return "RGB";
    case 3: return "palette";
    case 4: return "grey + alpha";
    case 6: return "RGBA";
    default: return "unknown";
  }
}

PngHeader check_png_bytes(const std::vector<unsigned char>& b, const SourceFile& source) {
  const auto at = [](std::uint64_t byte) { return FilePosition::byte(byte); };
  if (b.size() < kPngSignature.size() || !std::equal(kPngSignature.begin(), kPngSignature.end(), b.begin()))
    throw source.error(at(0), "not a PNG file (its first 8 bytes are not the PNG signature)");
  PngHeader h;
  bool header = false, end = false;
  std::uint64_t o = kPngSignature.size();
  while (o < b.size()) {
    if (end) throw source.error(at(o), "data after the IEND chunk (two files joined?)");
    if (b.size() - o < 8) throw source.error(at(o), "the file ends inside a chunk header (truncated)");
    const std::uint64_t length = big_endian32(&b[o]);
    const std::string type(reinterpret_cast<const char*>(&b[o + 4]), 4);
    if (length > kMaxChunkLength)
      throw source.error(at(o), fmt::format("chunk '{}' declares {} bytes, more than PNG allows", type, length));
    if (b.size() - o < 12 + length) {
      throw source.error(at(o), fmt::format("the file ends inside chunk '{}' ({} bytes declared, {} present; "
                                            "truncated)",
                                            type, length, b.size() - o - std::min<std::uint64_t>(b.size() - o, 8)));
    }
    const std::uint32_t stored = big_endian32(&b[o + 8 + length]);
    const std::uint32_t computed = crc32(&b[o + 4], 4 + length) ^ 0xFFFFFFFFu;
    if (stored != computed) {
      throw source.error(at(o), fmt::format("chunk '{}' fails its CRC check (stored {:08x}, computed {:08x}): the "
                                            "file is damaged",
                                            type, stored, computed));
    }
    if (!header) {
      if (type != "IHDR" || length != 13)
        throw source.error(at(o), fmt::format("the first chunk is '{}', not the 13-byte IHDR header", type));
      const unsigned char* d = &b[o + 8];
      h.width = int(std::min<std::uint32_t>(big_endian32(d), kMaxImageSide + 1));
      h.height = int(std::min<std::uint32_t>(big_endian32(d + 4), kMaxImageSide + 1));
      h.bit_depth = d[8];
      h.colour_type = d[9];
      if (h.width < 1 || h.height < 1 || h.width > kMaxImageSide || h.height > kMaxImageSide) {
        throw source.error(at(o + 8), fmt::format("image size {} x {} pixels is out of range (1..{})",
                                                  big_endian32(d), big_endian32(d + 4), kMaxImageSide));
      }
      header = true;
    } else if (type == "IEND") {
      end = true;
    }
    o += 12 + length;
  }
  if (!end) throw source.error(at(o), "the file ends without its IEND chunk (truncated)");
  return h;
}

cv::Mat decode(const std::vector<unsigned char>& bytes, int flags, const SourceFile& source) {
  cv::Mat image;
  try {
    image = cv::imdecode(cv::Mat(1, int(bytes.size()), CV_8UC1, const_cast<unsigned char*>(bytes.data())), flags);
  } catch (const cv::Exception& e) {
    throw source.error(fmt::format("its image data cannot be decoded ({})", e.what()));
  }
  if (image.empty()) throw source.error("its image data cannot be decoded (a damaged compressed stream)");
  return image;
}

void require_size(const PngHeader& h, const DepthIntrinsics& k, const SourceFile& source) {
  if (h.width != k.width || h.height != k.height) {
    throw source.error(FilePosition::byte(16), fmt::format("{} x {} pixels, but the intrinsics say {} x {}",
                                                           h.width, h.height, k.width, k.height));
  }
}

// A number of a key's line that must be a whole number of pixels.
int whole_pixels(double v, const char* key, const SourceFile& source, const FilePosition& at) {
  if (!(v >= 1 && v <= kMaxImageSide && v == std::floor(v)))
    throw source.error(at, fmt::format("{} {} must be a whole number of pixels, 1..{}", key, v, kMaxImageSide));
  return int(v);
}

}  // namespace

PngHeader check_png(const fs::path& file, const char* stage) {
  return check_png_bytes(read_bytes(file, stage), SourceFile(stage, file));
}

DepthImage read_depth_png(const fs::path& file, const DepthIntrinsics& intrinsics) {
  const SourceFile source(kPngStage, file);
  const std::vector<unsigned char> bytes = read_bytes(file, kPngStage);
  const PngHeader h = check_png_bytes(bytes, source);
  if (h.bit_depth != 16 || h.colour_type != 0) {
    throw source.error(FilePosition::byte(24), fmt::format("{}-bit {}: a depth frame is a 16-bit greyscale PNG",
                                                           h.bit_depth, colour_type_name(h.colour_type)));
  }
  require_size(h, intrinsics, source);
  const cv::Mat image = decode(bytes, cv::IMREAD_ANYDEPTH, source);
  STRATA_CHECK(image.type() == CV_16UC1 && image.cols == h.width && image.rows == h.height,
               "{}: decoded as type {} {} x {}", file.string(), image.type(), image.cols, image.rows);
  DepthImage out;
  out.width = image.cols;
  out.height = image.rows;
  out.values.resize(std::size_t(out.width) * std::size_t(out.height));
  for (int r = 0; r < image.rows; ++r) {
    const auto* row = image.ptr<std::uint16_t>(r);
    std::copy(row, row + image.cols, out.values.begin() + std::ptrdiff_t(r) * image.cols);
  }
  for (auto v : out.values) out.valid += v != 0;
  if (out.valid == 0) throw source.error("the frame holds no depth (every pixel is 0)");
  return out;
}

void check_colour_png(const fs::path& file, const DepthIntrinsics& intrinsics) {
  const SourceFile source(kColourStage, file);
  const std::vector<unsigned char> bytes = read_bytes(file, kColourStage);
  const PngHeader h = check_png_bytes(bytes, source);
  if (h.bit_depth != 8 || !(h.colour_type == 0 || h.colour_type == 2 || h.colour_type == 6)) {
    throw source.error(FilePosition::byte(24), fmt::format("{}-bit {}: a colour frame is an 8-bit grey, RGB or "
                                                           "RGBA PNG",
                                                           h.bit_depth, colour_type_name(h.colour_type)));
  }
  require_size(h, intrinsics, source);
  decode(bytes, cv::IMREAD_COLOR, source);
}

DepthIntrinsics read_depth_intrinsics(const fs::path& file) {
  const SourceFile source(kIntrinsicsStage, file);
  std::ifstream in(file);
  if (!in) throw IoError(fmt::format("{}: {}: cannot be opened for reading", kIntrinsicsStage, file.string()));
  static const std::set<std::string> kKeys = {"width", "height", "fx", "fy", "cx", "cy"};
  std::map<std::string, std::pair<double, FilePosition>> values;
  scan_formats::TextLines lines(in);
  while (lines.next()) {
    const auto& f = lines.fields();
    const std::string key(f[0]);
    if (!kKeys.count(key)) {
      throw source.error(lines.position(), fmt::format("unknown key '{}' (width, height, fx, fy, cx, cy)", key));
    }
    if (f.size() != 2) throw source.error(lines.position(), fmt::format("'{}' takes one number", key));
    if (values.count(key)) {
      throw source.error(lines.position(), fmt::format("'{}' given twice (first on {})", key,
                                                       values.at(key).second.text()));
    }
    const double v = scan_formats::parse_number(f[1], key.c_str(), source, lines.position());
    if (!std::isfinite(v)) throw source.error(lines.position(), fmt::format("{} is not finite", key));
    values.emplace(key, std::make_pair(v, lines.position()));
  }
  for (const auto& k : kKeys)
    if (!values.count(k)) throw source.error(fmt::format("no '{}' line (width, height, fx, fy, cx, cy are needed)", k));
  DepthIntrinsics out;
  out.width = whole_pixels(values.at("width").first, "width", source, values.at("width").second);
  out.height = whole_pixels(values.at("height").first, "height", source, values.at("height").second);
  out.fx = values.at("fx").first;
  out.fy = values.at("fy").first;
  out.cx = values.at("cx").first;
  out.cy = values.at("cy").first;
  for (const auto& [key, v] : {std::pair{"fx", out.fx}, std::pair{"fy", out.fy}})
    if (!(v > 0)) throw source.error(values.at(key).second, fmt::format("{} {} must be > 0 pixels", key, v));
  if (!(out.cx >= -0.5 && out.cx <= out.width - 0.5))
    throw source.error(values.at("cx").second, fmt::format("cx {} lies outside the image (-0.5..{})", out.cx,
                                                           out.width - 0.5));
  if (!(out.cy >= -0.5 && out.cy <= out.height - 0.5))
    throw source.error(values.at("cy").second, fmt::format("cy {} lies outside the image (-0.5..{})", out.cy,
                                                           out.height - 0.5));
  return out;
}

std::vector<std::pair<std::string, Eigen::Isometry3d>> read_depth_poses(const fs::path& file) {
  const SourceFile source(kPosesStage, file);
  std::ifstream in(file);
  if (!in) throw IoError(fmt::format("{}: {}: cannot be opened for reading", kPosesStage, file.string()));
  std::vector<std::pair<std::string, Eigen::Isometry3d>> out;
  std::map<std::string, FilePosition> seen;
  scan_formats::TextLines lines(in);
  static const char* kFields[] = {"tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  while (lines.next()) {
    const auto& f = lines.fields();
    if (f.size() != 8) {
      throw source.error(lines.position(), fmt::format("{} fields; a pose line is 'file tx ty tz qx qy qz qw'",
                                                       f.size()));
    }
    const std::string name(f[0]);
    if (auto it = seen.find(name); it != seen.end())
      throw source.error(lines.position(), fmt::format("a second pose of '{}' (the first on {})", name,
                                                       it->second.text()));
    seen.emplace(name, lines.position());
    double v[7];
    for (int i = 0; i < 7; ++i) {
      v[i] = scan_formats::parse_number(f[std::size_t(i + 1)], kFields[i], source, lines.position());
      if (!std::isfinite(v[i])) throw source.error(lines.position(), fmt::format("{} is not finite", kFields[i]));
    }
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1) > kQuaternionNormTolerance)
      throw source.error(lines.position(), fmt::format("the quaternion's norm is {:.6f}, not 1", q.norm()));
    q.normalize();
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = q.toRotationMatrix();
    pose.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    out.emplace_back(name, pose);
  }
  if (out.empty()) throw source.error("the file holds no pose");
  return out;
}

}  // namespace strata
