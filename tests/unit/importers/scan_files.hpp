#pragma once
// Point clouds written by the tests themselves, to read back: PLY (ascii, both
// binary byte orders), PTS, XYZ and LAS (1.2-1.4, point formats 0-3 and 6-8), from
// a list of points with known attributes.
#include "importers/scans/point_cloud.hpp"
#include "support/test_support.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace strata::test {

struct TestPoint {
  Eigen::Vector3d position;
  Rgb8 colour;
  float intensity;
  Eigen::Vector3f normal;
};

// `n` points of a scan of a trench side in UTM 36N coordinates: millimetre values
// (exact in LAS with scale 0.001), distinct colours, intensities and unit normals.
inline std::vector<TestPoint> sample_points(int n) {
  std::vector<TestPoint> out;
  for (int i = 0; i < n; ++i) {
    TestPoint p;
    p.position = {734012.125 + 0.25 * i, 4174018.5 - 0.125 * i, 1450.0 + 0.001 * i * i};
    p.colour = {std::uint8_t(10 + 20 * i), std::uint8_t(200 - 15 * i), std::uint8_t(7 * i)};
    p.intensity = float(100 + 37 * i);
    const Eigen::Vector3f nrm(float(i), 1.0f, 2.0f);
    p.normal = nrm.normalized();
    out.push_back(p);
  }
  return out;
}

// Appends v in little- or big-endian byte order.
template <typename T>
void put(std::string& out, T v, bool big_endian = false) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  out.append(reinterpret_cast<const char*>(b), sizeof(T));
}

inline void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

enum class PlyEncoding { ascii, binary_little_endian, binary_big_endian };

struct PlyLayout {
  PlyEncoding encoding = PlyEncoding::binary_little_endian;
  bool doubles = true;  // x y z as double, else float
  bool colour = true, intensity = true, normals = true;
  const char* intensity_name = "intensity";
  // Another element before the vertices, an unknown uchar and a list property in
  // each vertex, faces after: all to be skipped by the reader.
  bool extras = false;
};

inline std::string ply_bytes(const std::vector<TestPoint>& points, const PlyLayout& l) {
  const bool big = l.encoding == PlyEncoding::binary_big_endian;
  const bool ascii = l.encoding == PlyEncoding::ascii;
  const char* names[] = {"ascii", "binary_little_endian", "binary_big_endian"};
  std::string out = fmt::format("ply\nformat {} 1.0\ncomment written by strata's tests\n", names[int(l.encoding)]);
  if (l.extras) out += "element station 1\nproperty int id\n";
  out += fmt::format("element vertex {}\n", points.size());
  for (const char* axis : {"x", "y", "z"}) out += fmt::format("property {} {}\n", l.doubles ? "double" : "float", axis);
  if (l.extras) out += "property uchar quality\n";
  if (l.colour) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (l.intensity) out += fmt::format("property float {}\n", l.intensity_name);
  if (l.normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (l.extras) out += "property list uchar int refs\nelement face 1\nproperty list uchar int vertex_indices\n";
  out += "end_header\n";
  if (l.extras) {
    if (ascii) out += "7\n";
    else put<std::int32_t>(out, 7, big);
  }
  for (const auto& p : points) {
    if (ascii) {
      for (int a = 0; a < 3; ++a) {
        out += l.doubles ? fmt::format("{:.17g} ", p.position[a]) : fmt::format("{:.9g} ", float(p.position[a]));
      }
      if (l.extras) out += "3 ";
      if (l.colour) out += fmt::format("{} {} {} ", p.colour[0], p.colour[1], p.colour[2]);
      if (l.intensity) out += fmt::format("{:.9g} ", p.intensity);
      if (l.normals) out += fmt::format("{:.9g} {:.9g} {:.9g} ", p.normal.x(), p.normal.y(), p.normal.z());
      if (l.extras) out += "2 11 12";
      out += "\n";
      continue;
    }
    for (int a = 0; a < 3; ++a) {
      if (l.doubles) put<double>(out, p.position[a], big);
      else put<float>(out, float(p.position[a]), big);
    }
    if (l.extras) put<std::uint8_t>(out, 3);
    if (l.colour) out.append(reinterpret_cast<const char*>(p.colour.data()), 3);
    if (l.intensity) put<float>(out, p.intensity, big);
    if (l.normals)
      for (int a = 0; a < 3; ++a) put<float>(out, p.normal[a], big);
    if (l.extras) {
      put<std::uint8_t>(out, 2);
      put<std::int32_t>(out, 11, big);
      put<std::int32_t>(out, 12, big);
    }
  }
  if (l.extras) {
    if (ascii) out += "3 0 1 2\n";
    else {
      put<std::uint8_t>(out, 3);
      for (std::int32_t k = 0; k < 3; ++k) put<std::int32_t>(out, k, big);
    }
  }
  return out;
}

// fields: 3 (x y z), 4 (and intensity) or 7 (and r g b).
inline std::string pts_text(const std::vector<TestPoint>& points, int fields) {
  std::string out = fmt::format("{}\n", points.size());
  for (const auto& p : points) {
    out += fmt::format("{:.17g} {:.17g} {:.17g}", p.position.x(), p.position.y(), p.position.z());
    if (fields >= 4) out += fmt::format(" {}", p.intensity);
    if (fields == 7) out += fmt::format(" {} {} {}", p.colour[0], p.colour[1], p.colour[2]);
    out += "\n";
  }
  return out;
}

inline std::string xyz_text(const std::vector<TestPoint>& points, bool colour, const char* sep) {
  std::string out = "# x y z r g b, written by strata's tests\n";
  for (const auto& p : points) {
    out += fmt::format("{:.17g}{}{:.17g}{}{:.17g}", p.position.x(), sep, p.position.y(), sep, p.position.z());
    if (colour) out += fmt::format("{}{}{}{}{}{}", sep, p.colour[0], sep, p.colour[1], sep, p.colour[2]);
    out += "\n";
  }
  return out;
}

// LAS coordinates are integers times the scale plus the offset.
constexpr double kLasScale = 0.001;  // metres
inline const Eigen::Vector3d kLasOffset(734000.0, 4174000.0, 1400.0);

// A fixed-size, NUL-padded text field.
inline std::string padded(std::string text, std::size_t size) {
  text.resize(size, '\0');
  return text;
}

// A LAS file of version 1.`minor`, point format `format`, one VLR before the points
// and `extra_bytes` after each record's standard fields. Colours are written 16-bit
// (c * 257, so the high byte is c).
inline std::string las_bytes(const std::vector<TestPoint>& points, int minor, int format, int extra_bytes = 0) {
  const std::size_t header_size = minor == 2 ? 227 : minor == 3 ? 235 : 375;
  const std::size_t standard[] = {20, 28, 26, 34, 0, 0, 30, 36, 38};
  const int rgb_at[] = {-1, -1, 20, 28, -1, -1, -1, 30, 30};
  const std::size_t record = standard[format] + std::size_t(extra_bytes);
  const std::string vlr_data = "0123456789";
  const std::size_t point_offset = header_size + 54 + vlr_data.size();
  std::string h = "LASF";
  put<std::uint16_t>(h, 0);                // file source id
  put<std::uint16_t>(h, 0);                // global encoding
  h.append(16, '\0');                      // GUID
  put<std::uint8_t>(h, 1);
  put<std::uint8_t>(h, std::uint8_t(minor));
  h.append(padded("strata test", 32));
  h.append(padded("scan_files.hpp", 32));
  put<std::uint16_t>(h, 152);              // day of year
  put<std::uint16_t>(h, 2026);
  put<std::uint16_t>(h, std::uint16_t(header_size));
  put<std::uint32_t>(h, std::uint32_t(point_offset));
  put<std::uint32_t>(h, 1);                // VLRs
  put<std::uint8_t>(h, std::uint8_t(format));
  put<std::uint16_t>(h, std::uint16_t(record));
  put<std::uint32_t>(h, format >= 6 ? 0u : std::uint32_t(points.size()));  // legacy count
  for (int i = 0; i < 5; ++i) put<std::uint32_t>(h, 0);
  for (int a = 0; a < 3; ++a) put<double>(h, kLasScale);
  for (int a = 0; a < 3; ++a) put<double>(h, kLasOffset[a]);
  for (int a = 0; a < 6; ++a) put<double>(h, 0.0);  // max/min x y z: not used by the reader
  if (minor >= 3) put<std::uint64_t>(h, 0);          // waveform data
  if (minor == 4) {
    put<std::uint64_t>(h, 0);                        // first EVLR
    put<std::uint32_t>(h, 0);
    put<std::uint64_t>(h, points.size());
    for (int i = 0; i < 15; ++i) put<std::uint64_t>(h, 0);
  }
  // One VLR (LAS 1.4 R14, table 15): reserved, user id, record id, length, description.
  put<std::uint16_t>(h, 0);
  h.append(padded("strata", 16));
  put<std::uint16_t>(h, 1);
  put<std::uint16_t>(h, std::uint16_t(vlr_data.size()));
  h.append(padded("test record", 32));
  h += vlr_data;
  for (const auto& p : points) {
    std::string r;
    for (int a = 0; a < 3; ++a) put<std::int32_t>(r, std::int32_t(std::lround((p.position[a] - kLasOffset[a]) / kLasScale)));
    put<std::uint16_t>(r, std::uint16_t(p.intensity));
    r.resize(record, '\x5a');  // every other field: a pattern the reader must not take for coordinates
    if (rgb_at[format] >= 0) {
      std::string rgb;
      for (int c = 0; c < 3; ++c) put<std::uint16_t>(rgb, std::uint16_t(p.colour[std::size_t(c)] * 257));
      r.replace(std::size_t(rgb_at[format]), 6, rgb);
    }
    h += r;
  }
  return h;
}

}  // namespace strata::test
