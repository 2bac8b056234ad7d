// importer.scans.pts and importer.scans.xyz: the text exports of scanner software.
// PTS (Leica Cyclone and others): a line with the point count, then one point a line,
// `x y z [intensity [r g b]]`; several such blocks may follow one another (one per
// station). XYZ/TXT: `x y z [r g b]`, no count. Both: fields separated by
// whitespace or commas, blank lines and '#' comments skipped; every point has as
// many fields as the first one.
#include "importers/scans/scan_formats.hpp"

#include <algorithm>
#include <charconv>

namespace strata::scan_formats {
namespace {

constexpr const char* kPtsLayout = "x y z, x y z intensity, or x y z intensity r g b";
constexpr const char* kXyzLayout = "x y z, or x y z r g b";

// Reads x y z from the first three fields.
Eigen::Vector3d parse_xyz(const std::vector<std::string_view>& f, const ChunkBuilder& out, const FilePosition& at) {
  return {parse_number(f[0], "x", out, at), parse_number(f[1], "y", out, at), parse_number(f[2], "z", out, at)};
}

Rgb8 parse_rgb(const std::vector<std::string_view>& f, std::size_t first, const ChunkBuilder& out,
               const FilePosition& at) {
  return {parse_channel(f[first], "red", out, at), parse_channel(f[first + 1], "green", out, at),
          parse_channel(f[first + 2], "blue", out, at)};
}

// The field count every point of the file must have: the first point's.
class PointLayout {
 public:
  PointLayout(std::vector<std::size_t> allowed, const char* layout) : allowed_(std::move(allowed)), layout_(layout) {}
  // Fixes the count at the first point; refuses a count that is not allowed or
  // differs from the first point's.
  std::size_t check(const TextLines& lines, const ChunkBuilder& out) {
    const std::size_t n = lines.fields().size();
    if (fields_ == 0) {
      if (std::find(allowed_.begin(), allowed_.end(), n) == allowed_.end()) {
        throw out.error(lines.position(), fmt::format("expected {}, found {} field{}", layout_, n, n == 1 ? "" : "s"));
      }
      fields_ = n;
      first_line_ = lines.line_number();
    } else if (n != fields_) {
      throw out.error(lines.position(), fmt::format("{} fields, but the first point (line {}) has {}", n,
                                                    first_line_, fields_));
    }
    return n;
  }
  bool started() const { return fields_ != 0; }

 private:
  std::vector<std::size_t> allowed_;
  const char* layout_;
  std::size_t fields_ = 0;
  std::uint64_t first_line_ = 0;
};

}  // namespace

std::string read_pts(std::istream& in, ChunkBuilder& out) {
  TextLines lines(in);
  PointLayout layout({3, 4, 7}, kPtsLayout);
  while (lines.next()) {
    const auto& f = lines.fields();
    std::uint64_t declared = 0;
    const bool one_field = f.size() == 1;
    const auto [end, ec] =
        one_field ? std::from_chars(f[0].data(), f[0].data() + f[0].size(), declared) : std::from_chars_result{};
    if (!one_field || ec != std::errc() || end != f[0].data() + f[0].size()) {
      throw out.error(lines.position(),
                      fmt::format("expected the point count of a PTS block (one whole number), found '{}'{}",
                                  f.empty() ? "" : f[0], f.size() > 1 ? " ..." : ""));
    }
    const std::uint64_t count_line = lines.line_number();
    for (std::uint64_t k = 0; k < declared; ++k) {
      if (!lines.next()) {
        throw out.error(FilePosition::line(lines.line_number()),
                        fmt::format("the file ends after {} of the {} points declared on line {} (truncated?)", k,
                                    declared, count_line));
      }
      const FilePosition at = lines.position();
      if (!layout.started()) {
        const std::size_t n = lines.fields().size();
        out.declare(n == 7, n >= 4, false);
      }
      const std::size_t n = layout.check(lines, out);
      ScanPoint p;
      p.position = parse_xyz(lines.fields(), out, at);
      if (n >= 4) p.intensity = float(parse_number(lines.fields()[3], "intensity", out, at));
      if (n == 7) p.colour = parse_rgb(lines.fields(), 4, out, at);
      out.add(p, at);
    }
  }
  return "pts";
}

std::string read_xyz(std::istream& in, ChunkBuilder& out) {
  TextLines lines(in);
  PointLayout layout({3, 6}, kXyzLayout);
  while (lines.next()) {
    const FilePosition at = lines.position();
    if (!layout.started()) out.declare(lines.fields().size() == 6, false, false);
    const std::size_t n = layout.check(lines, out);
    ScanPoint p;
    p.position = parse_xyz(lines.fields(), out, at);
    if (n == 6) p.colour = parse_rgb(lines.fields(), 3, out, at);
    out.add(p, at);
  }
  return "xyz";
}

}  // namespace strata::scan_formats
