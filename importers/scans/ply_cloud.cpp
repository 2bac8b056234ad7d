// importer.scans.ply: the vertices of a PLY file (Turk's format as CloudCompare,
// Meshlab, phone LiDAR apps and scanner software write it), ascii or binary of either
// byte order. Read: x, y, z (any numeric type), red/green/blue, intensity or
// scalar_intensity, nx/ny/nz; other vertex properties are skipped by their declared
// type; elements before the vertices are skipped, the ones after (faces) not read.
#include "importers/ply/ply_header.hpp"
#include "importers/scans/scan_formats.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <istream>
#include <optional>

namespace strata::scan_formats {
namespace {

using ply::Element;
using ply::is_float;
using ply::Property;
using ply::size_of;
using ply::Type;

// Where each attribute is among the vertex properties (-1: absent).
struct VertexLayout {
  int xyz[3] = {-1, -1, -1};
  int rgb[3] = {-1, -1, -1};
  int intensity = -1;
  int normal[3] = {-1, -1, -1};
  std::vector<Type> types;
  bool has(const int (&v)[3]) const { return v[0] >= 0 && v[1] >= 0 && v[2] >= 0; }
};

VertexLayout vertex_layout(const Element& vertex, const ChunkBuilder& out) {
  VertexLayout l;
  for (std::size_t i = 0; i < vertex.properties.size(); ++i) {
    const Property& p = vertex.properties[i];
    const int k = int(i);
    l.types.push_back(p.type);
    if (p.list) continue;
    const std::string& n = p.name;
    if (n == "x") l.xyz[0] = k;
    else if (n == "y") l.xyz[1] = k;
    else if (n == "z") l.xyz[2] = k;
    else if (n == "red" || n == "diffuse_red") l.rgb[0] = k;
    else if (n == "green" || n == "diffuse_green") l.rgb[1] = k;
    else if (n == "blue" || n == "diffuse_blue") l.rgb[2] = k;
    else if ((n == "intensity" || n == "scalar_intensity") && l.intensity < 0) l.intensity = k;
    else if (n == "nx") l.normal[0] = k;
    else if (n == "ny") l.normal[1] = k;
    else if (n == "nz") l.normal[2] = k;
  }
  if (!l.has(l.xyz)) {
    throw out.error(FilePosition::line(vertex.line), "the vertex element lacks an x, y or z property");
  }
  return l;
}

// A colour channel of any type to 8 bits: floats are 0-1, 16-bit integers 0-65535.
std::uint8_t channel(double v, Type t) {
  if (is_float(t)) v *= 255.0;
  else if (t == Type::uint16 || t == Type::int16) v /= 257.0;
  return std::uint8_t(std::clamp(std::round(v), 0.0, 255.0));
}

ScanPoint to_point(const VertexLayout& l, const std::vector<double>& v) {
  ScanPoint p;
  p.position = {v[std::size_t(l.xyz[0])], v[std::size_t(l.xyz[1])], v[std::size_t(l.xyz[2])]};
  if (l.has(l.rgb)) {
    for (int c = 0; c < 3; ++c) p.colour[std::size_t(c)] = channel(v[std::size_t(l.rgb[c])], l.types[std::size_t(l.rgb[c])]);
  }
  if (l.intensity >= 0) p.intensity = float(v[std::size_t(l.intensity)]);
  if (l.has(l.normal)) {
    p.normal = Eigen::Vector3d(v[std::size_t(l.normal[0])], v[std::size_t(l.normal[1])], v[std::size_t(l.normal[2])])
                   .cast<float>();
  }
  return p;
}

// Buffered bytes of the binary body, with the offset of the next one for messages.
class ByteStream {
 public:
  ByteStream(std::istream& in, std::uint64_t offset) : in_(in), offset_(offset) {}
  // The next n bytes, or nullptr when the file ends before them.
  const unsigned char* take(std::size_t n) {
    if (end_ - pos_ < n) refill(n);
    if (end_ - pos_ < n) return nullptr;
    const unsigned char* p = buffer_.data() + pos_;
    pos_ += n;
    offset_ += n;
    return p;
  }
  std::uint64_t offset() const { return offset_; }
  std::uint64_t file_end() const { return offset_ + (end_ - pos_); }  // valid after take() failed

 private:
  static constexpr std::size_t kBlock = 1 << 20;
  void refill(std::size_t n) {
    std::memmove(buffer_.data(), buffer_.data() + pos_, end_ - pos_);
    end_ -= pos_;
    pos_ = 0;
    buffer_.resize(std::max(kBlock, n));
    in_.read(reinterpret_cast<char*>(buffer_.data() + end_), std::streamsize(buffer_.size() - end_));
    end_ += std::size_t(in_.gcount());
  }
  std::istream& in_;
  std::uint64_t offset_;
  std::vector<unsigned char> buffer_;
  std::size_t pos_ = 0, end_ = 0;
};

using ply::decode;

class BinaryBody {
 public:
  BinaryBody(std::istream& in, std::uint64_t offset, bool big_endian, ChunkBuilder& out)
      : bytes_(in, offset), swap_(big_endian != (std::endian::native == std::endian::big)), out_(out) {}

  // Reads one item of `e` (number `index`) into `values`, one per property (a
  // list's value is its length, its items are skipped).
  void read(const Element& e, std::uint64_t index, std::vector<double>& values) {
    item_start_ = bytes_.offset();
    values.resize(e.properties.size());
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      if (!p.list) {
        values[i] = decode(take(size_of(p.type), e, index), p.type, swap_);
        continue;
      }
      const double n = decode(take(size_of(p.count_type), e, index), p.count_type, swap_);
      if (n < 0) throw out_.error(item_position(), fmt::format("{} {}: negative list length", e.name, index));
      for (std::uint64_t k = 0; k < std::uint64_t(n); ++k) take(size_of(p.type), e, index);
      values[i] = n;
    }
  }
  // Where the item last read starts.
  FilePosition item_position() const { return FilePosition::byte(item_start_); }

 private:
  const unsigned char* take(std::size_t n, const Element& e, std::uint64_t index) {
    if (const unsigned char* p = bytes_.take(n)) return p;
    throw out_.error(FilePosition::byte(bytes_.file_end()),
                     fmt::format("the file ends inside {} {} of the {} declared (truncated)", e.name, index, e.count));
  }
  ByteStream bytes_;
  bool swap_;
  ChunkBuilder& out_;
  std::uint64_t item_start_ = 0;
};

class AsciiBody {
 public:
  AsciiBody(std::istream& in, std::uint64_t header_lines, ChunkBuilder& out) : lines_(in, header_lines), out_(out) {}

  // One item a line: its values, a list as its length followed by its items.
  void read(const Element& e, std::uint64_t index, std::vector<double>& values) {
    if (!lines_.next()) {
      throw out_.error(FilePosition::line(lines_.line_number()),
                       fmt::format("the file ends after {} of the {} items of element '{}' (truncated)", index,
                                   e.count, e.name));
    }
    const auto& f = lines_.fields();
    const FilePosition at = lines_.position();
    values.resize(e.properties.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      if (k >= f.size()) {
        throw out_.error(at, fmt::format("{} {} has {} values, fewer than its properties declare", e.name, index,
                                         f.size()));
      }
      values[i] = parse_number(f[k++], p.name.c_str(), out_, at);
      if (p.type == Type::float32) values[i] = double(float(values[i]));  // as a binary file would hold it
      if (p.list) k += std::size_t(std::max(values[i], 0.0));
    }
    if (k != f.size()) {
      throw out_.error(at, fmt::format("{} {} has {} values, its properties declare {}", e.name, index, f.size(), k));
    }
  }
  FilePosition item_position() const { return lines_.position(); }

 private:
  TextLines lines_;
  ChunkBuilder& out_;
};

// Reads the elements up to and including the vertices.
template <typename Body>
void read_vertices(Body& body, const ply::Header& h, ChunkBuilder& out) {
  std::vector<double> values;
  for (const Element& e : h.elements) {
    if (e.name != "vertex") {
      for (std::uint64_t i = 0; i < e.count; ++i) body.read(e, i, values);
      continue;
    }
    const VertexLayout layout = vertex_layout(e, out);
    out.declare(layout.has(layout.rgb), layout.intensity >= 0, layout.has(layout.normal));
    for (std::uint64_t i = 0; i < e.count; ++i) {
      body.read(e, i, values);
      out.add(to_point(layout, values), body.item_position());
    }
    return;
  }
}

}  // namespace

std::string read_ply(std::istream& in, ChunkBuilder& out) {
  const ply::Header h = ply::read_header(in, out.stage(), out.file());
  if (!h.find("vertex")) throw out.error("the header declares no vertex element");
  if (h.format == ply::Format::ascii) {
    AsciiBody body(in, h.line_count, out);
    read_vertices(body, h, out);
  } else {
    BinaryBody body(in, h.body_offset, h.format == ply::Format::binary_big_endian, out);
    read_vertices(body, h, out);
  }
  return fmt::format("ply {}", ply::format_name(h.format));
}

}  // namespace strata::scan_formats
