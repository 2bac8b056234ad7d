#pragma once
// Internal to the report module: HTML escaping, inline PNG data and plan drawings
// in SVG (thumbnails of GeoTIFF products are read by importers/raster). OpenCV
// stays behind this header's .cpp; images cross it as plain byte buffers.
#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace strata::report_detail {


// 8-bit image, row-major, `channels` 1, 3 (RGB) or 4 (RGBA).
struct Image {
  int width = 0, height = 0, channels = 3;
  std::vector<std::uint8_t> pixels;
  std::uint8_t* at(int x, int y) { return pixels.data() + (std::size_t(y) * std::size_t(width) + std::size_t(x)) * std::size_t(channels); }
};
// "data:image/png;base64,..." (cv::imencode).
std::string png_data_uri(const Image& image);
// Nearest-neighbour enlargement by an integer factor (crisp cells in coverage maps).
Image enlarge(const Image& image, int factor);

// An axis-aligned box in the site frame, metres.
struct Extent {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  void add(double x, double y);
  void add(const Extent& e);
  bool empty() const { return !(x1 > x0 && y1 > y0); }
  Extent padded(double fraction) const;
};

// Maps a site-frame plan onto an SVG of given width, north up, and draws the
// decorations every plan needs (scale bar, north arrow).
class PlanFrame {
 public:
  PlanFrame(const Extent& extent, int width_px, int max_height_px);
  Eigen::Vector2d px(double x, double y) const;
  double scale() const { return scale_; }  // pixels per metre
  int width() const { return width_; }
  int height() const { return height_; }
  std::string open(const std::string& label) const;  // <svg ...> with a background
  std::string image(const std::string& data_uri, const Extent& where, bool pixelated = false) const;
  // Scale bar bottom-left, north arrow top-right. A plan in an arbitrary frame (a
  // layer without markers) gets a bar in arbitrary units and no north arrow.
  std::string decorations(bool georeferenced = true) const;
  static std::string close() { return "</svg>\n"; }

 private:
  Extent extent_;
  double scale_ = 1;
  int width_ = 0, height_ = 0;
};

// Colour ramps, t in [0, 1].
void ramp_viridis(double t, std::uint8_t rgb[3]);
void ramp_terrain(double t, std::uint8_t rgb[3]);

// Removes the XML prolog, doctype, comments and namespace declarations of an SVG
// file's text so that it can sit inline in HTML5 (which needs none of them and
// where they would be the only URLs of the report).
std::string inline_svg(std::string svg);


}  // namespace strata::report_detail
