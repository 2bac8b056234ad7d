#include "report/html_util.hpp"

#include "core/base64.hpp"
#include "core/text.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <regex>

namespace strata::report_detail {

std::string png_data_uri(const Image& image) {
  STRATA_CHECK(image.width > 0 && image.height > 0, "empty image");
  const int type = image.channels == 1 ? CV_8UC1 : image.channels == 3 ? CV_8UC3 : CV_8UC4;
  cv::Mat m(image.height, image.width, type, const_cast<std::uint8_t*>(image.pixels.data()));
  cv::Mat bgr;
  // OpenCV writes BGR(A); our buffers are RGB(A).
  if (image.channels == 3) {
    cv::cvtColor(m, bgr, cv::COLOR_RGB2BGR);
  } else if (image.channels == 4) {
    cv::cvtColor(m, bgr, cv::COLOR_RGBA2BGRA);
  } else {
    bgr = m;
  }
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", bgr, png)) throw IoError("report: cannot encode a PNG image");
  return "data:image/png;base64," + base64(std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

Image enlarge(const Image& image, int factor) {
  if (factor <= 1) return image;
  Image out{image.width * factor, image.height * factor, image.channels, {}};
  out.pixels.resize(std::size_t(out.width) * std::size_t(out.height) * std::size_t(out.channels));
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      const std::uint8_t* s = const_cast<Image&>(image).at(x / factor, y / factor);
      std::copy(s, s + image.channels, out.at(x, y));
    }
  }
  return out;
}

void Extent::add(double x, double y) {
  if (!std::isfinite(x) || !std::isfinite(y)) return;
  x0 = std::min(x0, x);
  y0 = std::min(y0, y);
  x1 = std::max(x1, x);
  y1 = std::max(y1, y);
}

void Extent::add(const Extent& e) {
  if (e.x1 < e.x0) return;
  add(e.x0, e.y0);
  add(e.x1, e.y1);
}

Extent Extent::padded(double fraction) const {
  const double d = fraction * std::max({x1 - x0, y1 - y0, 0.1});
  return {x0 - d, y0 - d, x1 + d, y1 + d};
}

PlanFrame::PlanFrame(const Extent& extent, int width_px, int max_height_px) : extent_(extent) {
  STRATA_CHECK(!extent.empty(), "empty plan extent");
  scale_ = width_px / (extent.x1 - extent.x0);
  if ((extent.y1 - extent.y0) * scale_ > max_height_px) scale_ = max_height_px / (extent.y1 - extent.y0);
  width_ = int(std::ceil((extent.x1 - extent.x0) * scale_));
  height_ = int(std::ceil((extent.y1 - extent.y0) * scale_));
}

Eigen::Vector2d PlanFrame::px(double x, double y) const {
  return {(x - extent_.x0) * scale_, (extent_.y1 - y) * scale_};
}

std::string PlanFrame::open(const std::string& label) const {
  return fmt::format(
      "<svg class=\"plan\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" role=\"img\" aria-label=\"{}\">"
      "<rect width=\"100%\" height=\"100%\" fill=\"#f4f1ea\"/>\n",
      width_, height_, width_, height_, xml_escape(label));
}

std::string PlanFrame::image(const std::string& data_uri, const Extent& where, bool pixelated) const {
  const Eigen::Vector2d a = px(where.x0, where.y1), b = px(where.x1, where.y0);
  return fmt::format(
      "<image x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" preserveAspectRatio=\"none\"{} "
      "href=\"{}\"/>\n",
      a.x(), a.y(), b.x() - a.x(), b.y() - a.y(), pixelated ? " style=\"image-rendering:pixelated\"" : "", data_uri);
}

std::string PlanFrame::decorations(bool georeferenced) const {
  // Scale bar: the largest 1-2-5 length that fits in a quarter of the width.
  const double target_m = 0.25 * width_ / scale_;
  double bar = 0.01;
  for (double decade = 0.01; decade < 1e4; decade *= 10) {
    for (double f : {1.0, 2.0, 5.0}) {
      if (f * decade <= target_m) bar = f * decade;
    }
  }
  const double len = bar * scale_;
  const double x = 12, y = height_ - 14;
  const std::string label = !georeferenced ? fmt::format("{:g} units, arbitrary scale", bar)
                            : bar >= 1     ? fmt::format("{:g} m", bar)
                                           : fmt::format("{:g} cm", bar * 100);
  std::string s = fmt::format(
      "<g class=\"deco\"><rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"6\" fill=\"#222\"/>"
      "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"6\" fill=\"#fff\" stroke=\"#222\"/>"
      "<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"lbl\">{}</text>",
      x, y, len / 2, x + len / 2, y, len / 2, x + len + 6, y + 6, label);
  if (!georeferenced) return s + "</g>\n";  // north is unknown too
  const double nx = width_ - 22, ny = 14;
  s += fmt::format(
      "<polygon points=\"{:.1f},{:.1f} {:.1f},{:.1f} {:.1f},{:.1f}\" fill=\"#222\"/>"
      "<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"lbl\" text-anchor=\"middle\">N</text></g>\n",
      nx, ny, nx - 7, ny + 20, nx + 7, ny + 20, nx, ny + 34);
  return s;
}

namespace {
void ramp(const std::vector<std::array<double, 3>>& stops, double t, std::uint8_t rgb[3]) {
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * double(stops.size() - 1);
  const std::size_t i = std::min(stops.size() - 2, std::size_t(t));
  const double u = t - double(i);
  for (int c = 0; c < 3; ++c) rgb[c] = std::uint8_t(std::lround(stops[i][c] * (1 - u) + stops[i + 1][c] * u));
}
}  // namespace

void ramp_viridis(double t, std::uint8_t rgb[3]) {
  ramp({{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}}, t, rgb);
}

void ramp_terrain(double t, std::uint8_t rgb[3]) {
  ramp({{70, 110, 160}, {110, 170, 120}, {225, 210, 140}, {190, 130, 80}, {245, 240, 235}}, t, rgb);
}

std::string inline_svg(std::string svg) {
  const auto start = svg.find("<svg");
  if (start == std::string::npos) return "";
  svg.erase(0, start);
  static const std::regex comments("<!--[\\s\\S]*?-->");
  static const std::regex xmlns("\\s+xmlns(:[A-Za-z]+)?=\"[^\"]*\"");
  svg = std::regex_replace(svg, comments, "");
  svg = std::regex_replace(svg, xmlns, "");
  return svg;
}

}  // namespace strata::report_detail
