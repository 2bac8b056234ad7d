// The layer report: reads a layer's figures from the database, applies the
// quality rules and draws the sections an archaeologist checks before digging.
#include "core/time.hpp"
#include "core/text.hpp"
#include "core/statistics.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "pipeline/stage_json.hpp"
#include "products/hillshade.hpp"
#include "importers/raster/geotiff.hpp"
#include "report/html_util.hpp"
#include "report/report_internal.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <regex>
#include <cmath>
#include <numbers>
#include <set>

namespace strata {
namespace rd = report_detail;
using rd::Extent;
using rd::PlanFrame;
using rd::LayerData;

namespace {

std::string duration_words(std::int64_t s) {
  if (s < 60) return fmt::format("{} s", s);
  if (s < 3600) return fmt::format("{} min {} s", s / 60, s % 60);
  return fmt::format("{} h {} min", s / 3600, (s % 3600) / 60);
}

std::string missing(const std::string& text) { return "<p class=\"missing\">" + xml_escape(text) + "</p>\n"; }

// ---- drawing helpers ----------------------------------------------------------

std::string ortho_image(const LayerData& d, int px, Extent* extent) {
  const RasterThumbnail t = read_raster_thumbnail(*d.ortho, px, true);
  rd::Image im{t.width, t.height, 4, {}};
  im.pixels.assign(std::size_t(t.width) * std::size_t(t.height) * 4, 0);
  for (int y = 0; y < t.height; ++y) {
    for (int x = 0; x < t.width; ++x) {
      const std::size_t i = std::size_t(y) * std::size_t(t.width) + std::size_t(x);
      std::uint8_t* p = im.at(x, y);
      for (int c = 0; c < 3; ++c) {
        const int b = std::min(c, t.bands - 1);
        p[c] = std::uint8_t(std::clamp(t.band[std::size_t(b)][i], 0.0f, 255.0f));
      }
      p[3] = t.bands >= 4 ? std::uint8_t(std::clamp(t.band[3][i], 0.0f, 255.0f)) : 255;
    }
  }
  *extent = {t.west - d.site.origin.x(), t.south - d.site.origin.y(), t.east - d.site.origin.x(),
             t.north - d.site.origin.y()};
  return rd::png_data_uri(im);
}

std::string cameras_svg(const PlanFrame& f, const LayerData& d) {
  std::string s = "<g class=\"cams\">";
  for (const auto& cam : d.cameras) {
    const Eigen::Vector3d C = cam.pose.centre();
    const Eigen::Vector3d axis = cam.pose.R.row(2).transpose();  // viewing direction, world
    const Eigen::Vector2d p = f.px(C.x(), C.y());
    Eigen::Vector2d dir(axis.x(), -axis.y());
    const double len = 14 * std::min(1.0, dir.norm());
    if (dir.norm() > 1e-6) dir.normalize();
    s += fmt::format("<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#08306b\" stroke-width=\"1.5\"/>",
                     p.x(), p.y(), p.x() + len * dir.x(), p.y() + len * dir.y());
    s += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"4\" fill=\"#2171b5\" stroke=\"#fff\"/>", p.x(), p.y());
  }
  return s + "</g>\n";
}

std::string markers_svg(const PlanFrame& f, const LayerData& d) {
  std::string s = "<g class=\"markers\">";
  for (const auto& m : d.figures.markers) {
    const auto it = d.marker_positions.find(m.name);
    if (it == d.marker_positions.end()) continue;
    const Eigen::Vector2d p = f.px(it->second.x(), it->second.y());
    const char* colour = m.role == "check" ? "#e6550d" : m.role == "control" ? "#6a3d9a" : "#888";
    s += fmt::format(
        "<polygon points=\"{:.1f},{:.1f} {:.1f},{:.1f} {:.1f},{:.1f}\" fill=\"{}\" stroke=\"#fff\"/>"
        "<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"lbl halo\">{}</text>",
        p.x(), p.y() - 7, p.x() - 6, p.y() + 5, p.x() + 6, p.y() + 5, colour, p.x() + 8, p.y() + 4, xml_escape(m.name));
  }
  return s + "</g>\n";
}

// The key to the symbols of cameras_svg and markers_svg.
std::string plan_symbols_legend(bool markers) {
  std::string s =
      "<div class=\"legend\"><span><svg width=\"26\" height=\"14\"><line x1=\"7\" y1=\"7\" x2=\"22\" y2=\"7\" "
      "stroke=\"#08306b\" stroke-width=\"1.5\"/><circle cx=\"7\" cy=\"7\" r=\"4\" fill=\"#2171b5\" "
      "stroke=\"#fff\"/></svg>camera, with its viewing direction</span>";
  if (markers) {
    for (const auto& [colour, label] : {std::pair{"#6a3d9a", "control marker"}, std::pair{"#e6550d", "check marker"}}) {
      s += fmt::format("<span><svg width=\"16\" height=\"14\"><polygon points=\"8,1 2,13 14,13\" fill=\"{}\"/></svg>{}</span>",
                       colour, label);
    }
  }
  return s + "</div>\n";
}

Extent plan_extent(const LayerData& d) {
  Extent e;
  for (const auto& cam : d.cameras) e.add(cam.pose.centre().x(), cam.pose.centre().y());
  if (d.figures.georeferenced) {
    for (const auto& m : d.figures.markers) {
      const auto it = d.marker_positions.find(m.name);
      if (it != d.marker_positions.end()) e.add(it->second.x(), it->second.y());
    }
  }
  if (d.coverage) {
    e.add(d.coverage->x_min, d.coverage->y_max - d.coverage->height * d.coverage->cell);
    e.add(d.coverage->x_min + d.coverage->width * d.coverage->cell, d.coverage->y_max);
  }
  return e;
}

// ---- sections -------------------------------------------------------------------

std::string photos_section(const LayerData& d) {
  std::string s = "<section><h2>Photos</h2>\n";
  if (d.images.empty()) return s + missing("No photos have been imported for this layer.") + "</section>\n";
  std::vector<std::int64_t> times;
  for (const auto& im : d.images) {
    if (im.captured_at) {
      if (auto t = iso_seconds(*im.captured_at)) times.push_back(*t);
    }
  }
  std::string span = "unknown (no capture times in the photos' EXIF)";
  if (!times.empty()) {
    const auto [lo, hi] = std::minmax_element(times.begin(), times.end());
    std::string first, last;
    for (const auto& im : d.images) {
      if (!im.captured_at) continue;
      const auto t = iso_seconds(*im.captured_at);
      if (t == *lo && first.empty()) first = *im.captured_at;
      if (t == *hi) last = *im.captured_at;
    }
    span = fmt::format("{} to {} ({})", first, last, duration_words(*hi - *lo));
  }
  s += "<table class=\"kv\">";
  s += fmt::format("<tr><th>photos</th><td>{}</td></tr>", d.images.size());
  s += fmt::format("<tr><th>capture time span</th><td>{}</td></tr>", xml_escape(span));
  if (d.alignment) {
    s += fmt::format("<tr><th>aligned</th><td>{} of {}</td></tr>", d.figures.registered, d.images.size());
  } else {
    s += "<tr><th>aligned</th><td>not processed yet</td></tr>";
  }
  std::set<std::pair<int, int>> sizes;
  for (const auto& im : d.images) sizes.emplace(im.width, im.height);
  std::string sz;
  for (const auto& [w, h] : sizes) sz += (sz.empty() ? "" : ", ") + fmt::format("{} × {}", w, h);
  s += fmt::format("<tr><th>image size (px)</th><td>{}</td></tr>", sz);
  if (d.layer.captured_at) s += fmt::format("<tr><th>layer recorded</th><td>{}</td></tr>", xml_escape(*d.layer.captured_at));
  s += "</table>\n";
  if (!d.figures.unaligned.empty()) {
    std::string names;
    for (const auto& n : d.figures.unaligned) names += (names.empty() ? "" : ", ") + n;
    s += "<p>Not aligned: " + xml_escape(names) + "</p>\n";
  }
  return s + "</section>\n";
}

std::string cameras_section(const LayerData& d, const ReportOptions& o) {
  std::string s = "<section><h2>Camera positions</h2>\n";
  if (!d.alignment) return s + missing("No camera positions yet: the layer has not been aligned.") + "</section>\n";
  Extent e = plan_extent(d);
  std::string background, caption;
  Extent ortho_extent;
  if (d.ortho) {
    try {
      background = ortho_image(d, o.image_px, &ortho_extent);
      e.add(ortho_extent);
      caption = "Camera positions (blue, with viewing direction) and markers over the orthophoto.";
    } catch (const Error& err) {
      caption = fmt::format("The orthophoto could not be read ({}); ", err.what());
    }
  }
  std::string points;
  if (background.empty()) {
    const auto& pts = d.alignment->rec.points;
    for (const auto& p : pts) e.add(p.X.x(), p.X.y());
    caption += d.products_quality ? "Camera positions over the sparse point cloud (plan view)."
                                  : "No orthophoto yet: camera positions (blue, with viewing direction) and markers "
                                    "over the sparse point cloud (plan view).";
  }
  if (e.empty()) return s + missing("Nothing to draw: no registered camera.") + "</section>\n";
  const PlanFrame f(e.padded(0.06), o.image_px, o.image_px);
  s += f.open("camera positions");
  if (!background.empty()) {
    s += f.image(background, ortho_extent);
  } else {
    const auto& pts = d.alignment->rec.points;
    const std::size_t step = std::max<std::size_t>(1, pts.size() / 6000);
    s += "<g>";
    for (std::size_t i = 0; i < pts.size(); i += step) {
      const Eigen::Vector2d p = f.px(pts[i].X.x(), pts[i].X.y());
      s += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"2\" height=\"2\" fill=\"#{:02x}{:02x}{:02x}\"/>", p.x() - 1,
                       p.y() - 1, pts[i].colour(0), pts[i].colour(1), pts[i].colour(2));
    }
    s += "</g>\n";
  }
  s += cameras_svg(f, d);
  if (d.figures.georeferenced) s += markers_svg(f, d);
  s += f.decorations(d.figures.georeferenced) + PlanFrame::close();
  s += plan_symbols_legend(d.figures.georeferenced);
  if (!d.figures.georeferenced) caption += " The layer is not georeferenced: arbitrary frame and scale.";
  s += "<p class=\"caption\">" + xml_escape(caption) + fmt::format(" {} cameras.", d.cameras.size()) + "</p>\n";
  return s + "</section>\n";
}

void coverage_colour(int n, int min_photos, std::uint8_t rgba[4]) {
  struct Stop {
    int n;
    std::uint8_t c[3];
  };
  // Reds below the threshold (gaps), yellow to green above.
  static const Stop kBelow[] = {{0, {127, 0, 0}}, {1, {215, 48, 31}}, {2, {252, 141, 89}}};
  static const Stop kAbove[] = {{0, {254, 224, 139}}, {3, {145, 207, 96}}, {7, {26, 152, 80}}};
  const std::uint8_t* c;
  if (n < min_photos) {
    c = kBelow[std::min(2, n * 3 / std::max(1, min_photos))].c;
  } else {
    const int above = n - min_photos;
    c = above >= 7 ? kAbove[2].c : above >= 3 ? kAbove[1].c : kAbove[0].c;
  }
  rgba[0] = c[0];
  rgba[1] = c[1];
  rgba[2] = c[2];
  rgba[3] = 255;
}

std::string coverage_section(const LayerData& d, const ReportOptions& o) {
  std::string s = "<section><h2>Coverage</h2>\n";
  if (!d.coverage || d.coverage->area_cells() == 0) {
    return s + missing(d.alignment ? "The coverage could not be mapped: no DTM and too few sparse points."
                                   : "No coverage map yet: the layer has not been aligned.") +
           "</section>\n";
  }
  const CoverageMap& m = *d.coverage;
  const QualityThresholds& t = o.thresholds;
  Extent e = plan_extent(d);
  const PlanFrame f(e.padded(0.06), o.image_px, o.image_px);
  const int factor = std::max(1, int(std::floor(m.cell * f.scale())));
  rd::Image im{m.width, m.height, 4, {}};
  im.pixels.assign(std::size_t(m.width) * std::size_t(m.height) * 4, 0);
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const std::size_t i = m.index(c, r);
      if (m.inside(i)) coverage_colour(m.count[i], t.min_photos_per_area, im.at(c, r));
    }
  }
  im = rd::enlarge(im, factor);
  // Hatch low-resolution cells with dark blue diagonals (a ground resolution needs a
  // scale: not for a layer without markers).
  for (int y = 0; y < im.height && d.figures.georeferenced; ++y) {
    for (int x = 0; x < im.width; ++x) {
      const std::size_t i = m.index(x / factor, y / factor);
      if (!m.inside(i) || !(m.gsd_m[i] > t.max_gsd_m) || (x + y) % 8 >= 2) continue;
      std::uint8_t* p = im.at(x, y);
      p[0] = 40;
      p[1] = 40;
      p[2] = 160;
    }
  }
  const Extent where{m.x_min, m.y_max - m.height * m.cell, m.x_min + m.width * m.cell, m.y_max};
  s += f.open("coverage map");
  s += f.image(rd::png_data_uri(im), where, true);
  s += cameras_svg(f, d);
  for (const auto& g : d.figures.gaps) {
    const Eigen::Vector2d p = f.px(g.centroid.x(), g.centroid.y());
    s += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"lbl halo gap\" text-anchor=\"middle\">gap: {}</text>", p.x(),
                     p.y(), xml_escape(g.sector.name));
  }
  s += f.decorations(d.figures.georeferenced) + PlanFrame::close();
  // Legend and figures.
  std::size_t area = 0, enough = 0;
  std::vector<double> counts, gsds;
  for (std::size_t i = 0; i < m.z.size(); ++i) {
    if (!m.inside(i)) continue;
    ++area;
    if (m.count[i] >= t.min_photos_per_area) ++enough;
    counts.push_back(m.count[i]);
    if (std::isfinite(m.gsd_m[i])) gsds.push_back(m.gsd_m[i]);
  }
  s += "<div class=\"legend\">";
  const std::pair<int, std::string> keys[] = {
      {0, "0 photos"},
      {1, fmt::format("1–{} photos (gap)", t.min_photos_per_area - 1)},
      {t.min_photos_per_area, fmt::format("{}–{}", t.min_photos_per_area, t.min_photos_per_area + 2)},
      {t.min_photos_per_area + 3, fmt::format("{}–{}", t.min_photos_per_area + 3, t.min_photos_per_area + 6)},
      {t.min_photos_per_area + 7, fmt::format("{} or more", t.min_photos_per_area + 7)}};
  for (const auto& [n, label] : keys) {
    std::uint8_t c[4];
    coverage_colour(n, t.min_photos_per_area, c);
    s += fmt::format("<span><i style=\"background:#{:02x}{:02x}{:02x}\"></i>{}</span>", c[0], c[1], c[2], xml_escape(label));
  }
  if (d.figures.georeferenced)
    s += fmt::format("<span><i class=\"hatch\"></i>coarser than {} per pixel</span>", format_mm(t.max_gsd_m));
  s += "</div>\n";
  const double enough_percent = 100.0 * double(enough) / double(std::max<std::size_t>(1, area));
  const std::string caption =
      d.figures.georeferenced
          ? fmt::format("Photos that see each part of the trench (plan grid of {} cells of {:.0f} mm from the {}). "
                        "{:.0f} % of the area is seen by {} or more photos; median {} photos per cell; median best "
                        "ground resolution {} per pixel.",
                        area, 1000 * m.cell, d.coverage_source, enough_percent, t.min_photos_per_area,
                        median(counts), format_mm(median(gsds)))
          : fmt::format("Photos that see each part of the trench (plan grid of {} cells from the {}, in the "
                        "layer's arbitrary frame: no scale, no north). {:.0f} % of the area is seen by {} or more "
                        "photos; median {} photos per cell. The ground resolution is unknown without markers.",
                        area, d.coverage_source, enough_percent, t.min_photos_per_area, median(counts));
  s += "<p class=\"caption\">" + xml_escape(caption) + "</p>\n";
  return s + "</section>\n";
}

std::string residual_plot(const LayerData& d, const ReportOptions& o) {
  std::vector<const MarkerFigures*> ms;
  double vmax = o.thresholds.max_check_rmse_m * 1.5;
  for (const auto& m : d.figures.markers) {
    if (!m.triangulated) continue;
    ms.push_back(&m);
    vmax = std::max(vmax, m.residual_m.cwiseAbs().maxCoeff() * 1.1);
  }
  if (ms.empty()) return "";
  std::stable_sort(ms.begin(), ms.end(), [](auto* a, auto* b) { return a->role < b->role; });  // check before control
  const int left = 56, top = 16, group = 54, plot_h = 220;
  const int w = left + group * int(ms.size()) + 20, h = top + plot_h + 44;
  const double mid = top + plot_h / 2.0, k = (plot_h / 2.0) / (vmax * 1000);  // px per mm
  std::string s = fmt::format("<svg class=\"chart\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" role=\"img\" "
                              "aria-label=\"marker residuals\">",
                              w, h, w, h);
  // Grid lines at round millimetres and the check RMSE tolerance.
  // Grid every 1-2-5 x 10^k mm, about four lines each side of zero.
  double step_mm = 1;
  for (double decade = 1; decade < 1e7; decade *= 10) {
    for (double m : {1.0, 2.0, 5.0}) {
      if (m * decade * 4 <= vmax * 1000 * 1.2) step_mm = m * decade;
    }
  }
  for (double v = -std::floor(vmax * 1000 / step_mm) * step_mm; v <= vmax * 1000; v += step_mm) {
    const double y = mid - v * k;
    s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#ddd\"/>"
                     "<text x=\"{}\" y=\"{:.1f}\" class=\"lbl\" text-anchor=\"end\">{:g}</text>",
                     left, w - 10, y, y, left - 4, y + 4, v);
  }
  for (double sign : {-1.0, 1.0}) {
    const double y = mid - sign * o.thresholds.max_check_rmse_m * 1000 * k;
    s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#b30000\" stroke-dasharray=\"5 4\"/>",
                     left, w - 10, y, y);
  }
  s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#444\"/>", left, w - 10, mid, mid);
  s += fmt::format("<text x=\"12\" y=\"{:.1f}\" class=\"lbl\" transform=\"rotate(-90 12 {:.1f})\" "
                   "text-anchor=\"middle\">residual (mm)</text>",
                   mid, mid);
  static const char* kAxisColour[3] = {"#d95f02", "#1b9e77", "#7570b3"};
  for (std::size_t i = 0; i < ms.size(); ++i) {
    const double x0 = left + group * double(i);
    const bool check = ms[i]->role == "check";
    s += fmt::format("<rect x=\"{:.1f}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" opacity=\"0.35\"/>", x0 + 2,
                     top, group - 4, plot_h, check ? "#fdd0a2" : "#dadaeb");
    for (int a = 0; a < 3; ++a) {
      const double v = ms[i]->residual_m[a] * 1000 * k;
      s += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"12\" height=\"{:.1f}\" fill=\"{}\"/>", x0 + 8 + 13 * a,
                       v > 0 ? mid - v : mid, std::max(0.5, std::abs(v)), kAxisColour[a]);
    }
    s += fmt::format("<text x=\"{:.1f}\" y=\"{}\" class=\"lbl\" text-anchor=\"middle\">{}</text>"
                     "<text x=\"{:.1f}\" y=\"{}\" class=\"lbl small\" text-anchor=\"middle\">{}</text>",
                     x0 + group / 2.0, top + plot_h + 16, xml_escape(ms[i]->name), x0 + group / 2.0, top + plot_h + 30,
                     xml_escape(ms[i]->role));
  }
  s += "</svg>\n<div class=\"legend\">";
  const char* names[3] = {"east (dE)", "north (dN)", "height (dZ)"};
  for (int a = 0; a < 3; ++a) s += fmt::format("<span><i style=\"background:{}\"></i>{}</span>", kAxisColour[a], names[a]);
  s += "<span><i style=\"background:#dadaeb\"></i>control</span><span><i style=\"background:#fdd0a2\"></i>check</span>";
  s += fmt::format("<span><i class=\"dash\"></i>±{} tolerance</span></div>\n", format_mm(o.thresholds.max_check_rmse_m));
  return s;
}

// Why a marker's rays do not meet as one point (its own dispersion, clicks that
// disagree), and findings about the block as a whole, from the alignment's figures.
std::string marker_diagnosis(const AlignmentQuality& q) {
  std::string items;
  for (const auto& m : q.markers) {
    if (m.diagnosis.empty()) continue;
    items += fmt::format("<li><b>{}</b> ({} of {} photos agree, spread {}): {}</li>", xml_escape(m.name), m.images,
                         m.observed, format_mm(m.dispersion_m), xml_escape(m.diagnosis));
  }
  for (const auto& d : q.georeference_diagnosis) items += fmt::format("<li>{}</li>", xml_escape(d));
  if (items.empty()) return "";
  return "<p>Where the marker rays do not meet as one point:</p><ul class=\"notes\">" + items + "</ul>\n";
}

std::string markers_section(const LayerData& d, const ReportOptions& o) {
  std::string s = "<section><h2>Marker residuals</h2>\n";
  if (!d.alignment) return s + missing("No marker residuals yet: the layer has not been aligned.") + "</section>\n";
  if (d.figures.markers.empty()) {
    return s + missing("No surveyed marker was used: the layer is not georeferenced. Residuals need markers seen in "
                       "the photos.") +
           "</section>\n";
  }
  const auto& q = d.alignment->quality;
  auto rmse_row = [&](const AxisRmse& r, const char* label) {
    if (r.markers == 0) return fmt::format("<tr><th>{}</th><td colspan=\"4\">no {} markers</td></tr>", label, label);
    return fmt::format("<tr><th>{} RMSE ({} {})</th><td>{}</td><td>{}</td><td>{}</td><td><b>{}</b></td></tr>",
                       label, r.markers, r.markers == 1 ? "marker" : "markers", format_mm(r.e), format_mm(r.n),
                       format_mm(r.z), format_mm(r.xyz));
  };
  s += "<table class=\"grid\"><tr><th></th><th>east</th><th>north</th><th>height</th><th>3D</th></tr>";
  s += rmse_row(q.control_rmse, "control") + rmse_row(q.check_rmse, "check") + "</table>\n";
  s += "<table class=\"grid\"><tr><th>marker</th><th>role</th><th>photos</th><th>dE</th><th>dN</th><th>dZ</th>"
       "<th>3D</th><th>reprojection</th></tr>";
  for (const auto& m : d.figures.markers) {
    const bool few = m.images < o.thresholds.min_marker_photos;
    const bool far = m.triangulated && m.residual_m.norm() > allowed_marker_residual_m(m, o.thresholds);
    s += fmt::format("<tr class=\"{}\"><td>{}</td><td>{}</td><td class=\"{}\">{}</td>", m.role, xml_escape(m.name),
                     xml_escape(m.role), few ? "bad" : "", m.images);
    if (m.triangulated) {
      s += fmt::format("<td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td><td>{:.2f} px</td></tr>",
                       format_mm(m.residual_m.x()), format_mm(m.residual_m.y()), format_mm(m.residual_m.z()),
                       far ? "bad" : "", format_mm(m.residual_m.norm()), m.reprojection_px);
    } else {
      s += "<td colspan=\"5\">not located</td></tr>";
    }
  }
  s += "</table>\n";
  s += marker_diagnosis(q);
  s += residual_plot(d, o);
  std::string yardstick;
  if (!d.figures.survey_words.empty()) {
    double expected = 0;
    for (const auto& m : d.figures.markers) expected = std::max(expected, m.expected_m);
    yardstick = fmt::format(" The markers come from {}: each is expected within about {} (3D, one sigma) of its "
                            "surveyed position, and is flagged only beyond {:g} times that or {}, whichever is larger.",
                            d.figures.survey_words, format_mm(expected), o.thresholds.survey_allowance,
                            format_mm(o.thresholds.max_marker_residual_m));
  }
  s += "<p class=\"caption\">" +
       xml_escape("Residuals are photogrammetric minus surveyed positions. Control markers drive the georeference; "
                  "check markers measure it independently." + yardstick) +
       "</p>\n";
  return s + "</section>\n";
}

std::string histogram_section(const LayerData& d, const ReportOptions& o) {
  std::string s = "<section><h2>Reprojection error</h2>\n";
  if (!d.alignment || d.alignment->rec.points.empty()) {
    return s + missing("No sparse points yet: the layer has not been aligned.") + "</section>\n";
  }
  std::vector<double> e;
  for (const auto& p : d.alignment->rec.points) {
    if (std::isfinite(p.error_px)) e.push_back(p.error_px);
  }
  std::vector<double> sorted = e;
  std::sort(sorted.begin(), sorted.end());
  const double p99 = sorted[std::min(sorted.size() - 1, std::size_t(0.99 * double(sorted.size())))];
  const double hi = std::max(2 * o.thresholds.max_reprojection_rmse_px, p99);
  const int bins = o.histogram_bins;
  std::vector<int> hist(std::size_t(bins), 0);
  for (double v : e) ++hist[std::size_t(std::clamp(int(v / hi * bins), 0, bins - 1))];
  const int peak = std::max(1, *std::max_element(hist.begin(), hist.end()));
  const int left = 56, top = 12, pw = o.image_px - left - 20, ph = 200;
  const int w = o.image_px, h = top + ph + 40;
  s += fmt::format("<svg class=\"chart\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" role=\"img\" "
                   "aria-label=\"reprojection error histogram\">",
                   w, h, w, h);
  const double bw = double(pw) / bins;
  for (int b = 0; b < bins; ++b) {
    const double bh = double(hist[std::size_t(b)]) / peak * ph;
    const bool over = (b + 0.5) * hi / bins > o.thresholds.max_reprojection_rmse_px;
    s += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"{}\"/>", left + b * bw + 1,
                     top + ph - bh, bw - 2, bh, over ? "#fc8d59" : "#4292c6");
  }
  s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"#444\"/>", left, left + pw, top + ph, top + ph);
  for (int k = 0; k <= 4; ++k) {
    const double v = hi * k / 4, x = left + pw * k / 4.0;
    s += fmt::format("<text x=\"{:.1f}\" y=\"{}\" class=\"lbl\" text-anchor=\"middle\">{:.2g}</text>", x, top + ph + 16, v);
  }
  s += fmt::format("<text x=\"{:.1f}\" y=\"{}\" class=\"lbl\" text-anchor=\"middle\">error per point (px, mean over its "
                   "track)</text>",
                   left + pw / 2.0, top + ph + 34);
  s += fmt::format("<text x=\"{}\" y=\"{}\" class=\"lbl\" text-anchor=\"end\">{}</text><text x=\"{}\" y=\"{}\" "
                   "class=\"lbl\" text-anchor=\"end\">0</text>",
                   left - 4, top + 10, peak, left - 4, top + ph);
  const auto marker_line = [&](double v, const char* colour, const std::string& label) {
    const double x = left + std::min(v, hi) / hi * pw;
    return fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{}\" y2=\"{}\" stroke=\"{}\" stroke-dasharray=\"5 4\"/>"
                       "<text x=\"{:.1f}\" y=\"{}\" class=\"lbl halo\">{}</text>",
                       x, x, top, top + ph, colour, x + 4, top + 14, xml_escape(label));
  };
  s += marker_line(o.thresholds.max_reprojection_rmse_px, "#b30000",
                   fmt::format("tolerance {:.1f} px", o.thresholds.max_reprojection_rmse_px));
  if (d.figures.reprojection_rmse_px) {
    s += marker_line(*d.figures.reprojection_rmse_px, "#000", fmt::format("RMSE {:.2f} px", *d.figures.reprojection_rmse_px));
  }
  s += "</svg>\n";
  s += "<p class=\"caption\">" +
       xml_escape(fmt::format("{} sparse points; median error {:.2f} px, 99th percentile {:.2f} px.", e.size(), median(e), p99)) +
       "</p>\n";
  return s + "</section>\n";
}

std::string hillshade_section(const LayerData& d, const ReportOptions& o) {
  std::string s = "<section><h2>DTM hillshade</h2>\n";
  if (!d.dtm) {
    return s + missing(d.alignment ? "No DTM yet: run the products stage (strata process DIR --layer " +
                                         d.layer.name + ")."
                                   : "No DTM yet: the layer has not been processed.") +
           "</section>\n";
  }
  RasterThumbnail t;
  try {
    t = read_raster_thumbnail(*d.dtm, o.image_px, false);
  } catch (const Error& e) {
    return s + missing(fmt::format("The DTM could not be read: {}", e.what())) + "</section>\n";
  }
  const auto& z = t.band[0];
  float lo = INFINITY, hi = -INFINITY;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (!t.valid[i]) continue;
    lo = std::min(lo, z[i]);
    hi = std::max(hi, z[i]);
  }
  if (!(hi >= lo)) return s + missing("The DTM has no valid cell.") + "</section>\n";
  // Lit from the north-west, 45 degrees up (the cartographic convention), over the
  // height colours.
  const double cx = (t.east - t.west) / t.width, cy = (t.north - t.south) / t.height;
  const std::vector<float> shade = hillshade({t.width, t.height, cx, cy, z.data(), t.valid.data()});
  rd::Image im{t.width, t.height, 4, {}};
  im.pixels.assign(std::size_t(t.width) * std::size_t(t.height) * 4, 0);
  for (int y = 0; y < t.height; ++y) {
    for (int x = 0; x < t.width; ++x) {
      const std::size_t i = std::size_t(y) * std::size_t(t.width) + std::size_t(x);
      if (std::isnan(shade[i])) continue;
      std::uint8_t rgb[3];
      rd::ramp_terrain(hi > lo ? (z[i] - lo) / (hi - lo) : 0.5, rgb);
      std::uint8_t* p = im.at(x, y);
      for (int k = 0; k < 3; ++k) p[k] = std::uint8_t(std::clamp(rgb[k] * (0.3 + 0.85 * shade[i]), 0.0, 255.0));
      p[3] = 255;
    }
  }
  const Extent where{t.west - d.site.origin.x(), t.south - d.site.origin.y(), t.east - d.site.origin.x(),
                     t.north - d.site.origin.y()};
  const PlanFrame f(where.padded(0.03), o.image_px, o.image_px);
  s += f.open("DTM hillshade") + f.image(rd::png_data_uri(im), where) + f.decorations(d.figures.georeferenced) + PlanFrame::close();
  std::string ramp = "<div class=\"ramp\">";
  for (int k = 0; k <= 10; ++k) {
    std::uint8_t rgb[3];
    rd::ramp_terrain(k / 10.0, rgb);
    ramp += fmt::format("<i style=\"background:#{:02x}{:02x}{:02x}\"></i>", rgb[0], rgb[1], rgb[2]);
  }
  ramp += "</div>";
  const char* unit = d.figures.georeferenced ? "m" : "units";
  s += "<div class=\"legend\"><span>" + fmt::format("{:.3f} {}", lo, unit) + "</span>" + ramp + "<span>" +
       fmt::format("{:.3f} {}", hi, unit) + "</span></div>\n";
  std::string caption = fmt::format("Heights {:.3f}–{:.3f} m ({} relief {:.0f} mm), lit from the north-west.", lo, hi,
                                    d.site.crs, 1000.0 * (hi - lo));
  if (d.products_quality) {
    const DtmFigures& dtm = d.products_quality->dtm;
    caption += fmt::format(" Area {:.2f} m². Cell {:.0f} mm.", dtm.area_m2, dtm.cell_m * 1000);
    if (dtm.sigma)
      caption += fmt::format(" Height uncertainty per cell (one sigma, from the agreement of the fused depth maps; "
                             "dtm_sigma.tif): median {:.1f} mm, 95 % of cells within {:.1f} mm.",
                             dtm.sigma->median_m * 1000, dtm.sigma->p95_m * 1000);
  }
  if (!d.figures.georeferenced) {
    caption = fmt::format("Relative heights of the layer's arbitrary frame (range {:.3g} units), lit from one side. "
                          "The layer is not georeferenced: no scale, no north, no heights in {}; the figures are in "
                          "arbitrary units.",
                          hi - lo, d.site.crs);
  }
  s += "<p class=\"caption\">" + xml_escape(caption) + "</p>\n";
  return s + "</section>\n";
}

std::string figures_section(const LayerData& d) {
  std::string s = "<section><h2>Figures</h2>\n<table class=\"kv\">";
  auto row = [&](const std::string& k, const std::string& v) {
    s += "<tr><th>" + xml_escape(k) + "</th><td>" + xml_escape(v) + "</td></tr>";
  };
  row("unit", d.layer.unit);
  row("site CRS", d.site.crs);
  if (d.alignment) {
    const auto& q = d.alignment->quality;
    row("sparse points", fmt::format("{}", q.sparse.points));
    row("mean track length", fmt::format("{:.1f} photos", q.sparse.mean_track_length));
    row("reprojection RMSE", fmt::format("{:.2f} px", q.sparse.reprojection_rmse_px));
    row("ground sampling distance", d.figures.georeferenced
                                        ? format_mm(q.sparse.gsd_m) + " per pixel"
                                        : "unknown: the layer has no scale (not georeferenced)");
    row("georeferenced", d.figures.georeferenced ? "yes" : "no");
    row("alignment time", fmt::format("{:.0f} s", q.timings.total_s));
  } else {
    row("alignment", "not processed");
  }
  if (d.dense_quality) {
    const DenseSummary& dense = d.dense_quality->figures;
    row("dense completeness", fmt::format("{:.0f} %", 100 * dense.completeness));
    if (std::isfinite(dense.median_distance_sparse_m))
      row("dense vs sparse (median)", d.figures.georeferenced
                                          ? format_mm(dense.median_distance_sparse_m)
                                          : fmt::format("{:.3g} units (arbitrary scale)", dense.median_distance_sparse_m));
  } else {
    row("dense surface", "not processed");
  }
  if (d.products_quality) {
    if (d.products_quality->ortho) row("orthophoto coverage", fmt::format("{:.0f} %", 100 * d.products_quality->ortho->coverage));
    row("footprint area", d.figures.georeferenced
                              ? fmt::format("{:.2f} m²", d.products_quality->footprint.area_m2)
                              : fmt::format("{:.3g} square units (arbitrary scale)", d.products_quality->footprint.area_m2));
  } else {
    row("DTM and orthophoto", "not produced");
  }
  s += "</table>\n";
  for (const auto& n : d.notes) s += missing(n);
  return s + "</section>\n";
}

// The survey's yardstick (docs/quality.md): each marker's expected error from its
// stated sigma, the rounding the alignment found in the survey, and its photos; and
// the survey in the verdict's words.
void judge_against_survey(const AlignmentQuality& q, const std::map<std::string, MarkerRecord>& surveyed,
                          LayerFigures& f) {
  const SurveyAssessment& survey = q.survey;
  double stated = 0;
  for (auto& m : f.markers) {
    const auto it = surveyed.find(m.name);
    const bool is_stated = it != surveyed.end() && it->second.sigma_stated;
    const Eigen::Vector3d sigma = is_stated ? it->second.sigma : Eigen::Vector3d::Zero();
    if (m.triangulated && (m.role == "control" || m.role == "check")) stated = std::max(stated, sigma.maxCoeff());
    m.expected_m = expected_marker_error_m(sigma, survey.plan_rounding_sigma_m(), survey.height_rounding_sigma_m(),
                                           m.reprojection_px * q.sparse.gsd_m);
  }
  // The same steps the alignment warns about.
  std::vector<std::string> words;
  const bool plan = survey.plan_coarse(), height = survey.height_coarse();
  if (plan && height && survey.plan_step_m == survey.height_step_m) {
    words.push_back(fmt::format("rounded to {} m", survey.plan_step_m));
  } else {
    if (plan) words.push_back(fmt::format("rounded to {} m in plan", survey.plan_step_m));
    if (height) words.push_back(fmt::format("with heights rounded to {} m", survey.height_step_m));
  }
  if (stated > 0) words.push_back(fmt::format("stated to {} per axis", format_mm(stated)));
  if (words.empty()) return;
  f.survey_words = "a survey " + words[0];
  for (std::size_t i = 1; i < words.size(); ++i) f.survey_words += (i + 1 == words.size() ? " and " : ", ") + words[i];
}

}  // namespace

namespace report_detail {

LayerData gather_layer(Project& project, const LayerRecord& layer, const ReportOptions& o) {
  Database& db = project.db();
  LayerData d;
  d.layer = layer;
  d.site = project.site();
  d.images = list_images(db, layer.id);
  std::map<std::string, MarkerRecord> surveyed;
  for (auto& m : list_markers(db)) {
    d.marker_positions[m.name] = m.position - d.site.origin;
    surveyed[m.name] = std::move(m);
  }
  LayerFigures& f = d.figures;
  f.layer = layer.name;
  f.photos = int(d.images.size());
  try {
    d.alignment = load_alignment(db, layer);
  } catch (const std::exception& e) {
    d.notes.push_back(fmt::format("The stored alignment could not be read ({}).", e.what()));
  }
  d.dense_quality = stored_dense_quality(db, layer.id);
  d.products_quality = stored_products_quality(db, layer.id);
  for (const char* kind : {"dtm", "ortho"}) {
    const auto p = find_product(db, layer.id, kind);
    if (!p) continue;
    const auto path = project.dir() / p->path;
    if (!std::filesystem::exists(path)) {
      d.notes.push_back(fmt::format("The {} file {} is recorded but missing.", kind, p->path));
      continue;
    }
    (std::string(kind) == "dtm" ? d.dtm : d.ortho) = path;
  }
  f.dense = d.dense_quality.has_value();
  f.products = d.products_quality.has_value() || d.dtm.has_value();

  if (d.alignment) {
    const auto& a = *d.alignment;
    f.aligned = true;
    f.georeferenced = a.rec.georeferenced;
    f.georeference_message = a.quality.georeference_message;
    f.reprojection_rmse_px = a.quality.sparse.reprojection_rmse_px;
    if (a.quality.control_rmse.markers > 0) f.control_rmse_m = a.quality.control_rmse.xyz;
    if (a.quality.check_rmse.markers > 0) f.check_rmse_m = a.quality.check_rmse.xyz;
    std::set<std::string> imported;
    for (const auto& im : a.rec.images) {
      imported.insert(im.name);
      if (!im.registered) {
        f.unaligned.push_back(im.name);
        continue;
      }
      ++f.registered;
      if (im.group >= 0 && std::size_t(im.group) < a.rec.groups.size()) {
        d.cameras.push_back({a.rec.groups[std::size_t(im.group)].intrinsics, im.pose});
        f.camera_centres.push_back(im.pose.centre().head<2>());
      }
    }
    // Photos imported after the alignment are not in it: they count as not aligned.
    for (const auto& im : d.images) {
      if (!imported.count(im.name)) f.unaligned.push_back(im.name + " (imported after processing)");
    }
    for (const auto& r : list_marker_residuals(db, layer.name)) {
      MarkerFigures m;
      m.name = r.marker;
      m.role = r.role;
      m.triangulated = r.triangulated;
      m.residual_m = r.residual_m;
      m.reprojection_px = r.reprojection_px;
      m.images = r.images;
      f.markers.push_back(m);
    }
    judge_against_survey(a.quality, surveyed, f);

    // Coverage: on the DTM when there is one (the surface as reconstructed), else
    // on the sparse points.
    if (d.dtm) {
      try {
        const RasterThumbnail t = read_raster_thumbnail(*d.dtm, o.coverage_cells, false);
        std::vector<float> z(t.band[0].size(), NAN);
        for (std::size_t i = 0; i < z.size(); ++i) {
          if (t.valid[i]) z[i] = float(t.band[0][i] - d.site.origin.z());
        }
        d.coverage = coverage_grid(t.west - d.site.origin.x(), t.north - d.site.origin.y(),
                                   (t.east - t.west) / t.width, t.width, t.height, std::move(z));
        d.coverage_source = "DTM";
      } catch (const Error& e) {
        d.notes.push_back(fmt::format("The DTM could not be read for the coverage map ({}).", e.what()));
      }
    }
    if (!d.coverage) {
      std::vector<Eigen::Vector3d> pts;
      pts.reserve(a.rec.points.size());
      for (const auto& p : a.rec.points) pts.push_back(p.X);
      auto m = coverage_grid_from_points(pts, std::min(o.coverage_cells, 60));
      if (m.width > 0) {
        d.coverage = std::move(m);
        d.coverage_source = "sparse points";
      }
    }
    if (d.coverage) {
      count_coverage(*d.coverage, d.cameras);
      f.coverage_known = true;
      f.gaps = find_coverage_gaps(*d.coverage, o.thresholds.min_photos_per_area, o.thresholds.min_shortfall_fraction);
      f.low_resolution = find_low_resolution(*d.coverage, o.thresholds.max_gsd_m, o.thresholds.min_shortfall_fraction);
      Extent e;
      for (int r = 0; r < d.coverage->height; ++r) {
        for (int c = 0; c < d.coverage->width; ++c) {
          if (d.coverage->inside(d.coverage->index(c, r))) e.add(d.coverage->x_centre(c), d.coverage->y_centre(r));
        }
      }
      f.trench_centre = {(e.x0 + e.x1) / 2, (e.y0 + e.y1) / 2};
    }
  }
  d.findings = evaluate_layer(f, o.thresholds);
  return d;
}

std::string findings_html(const std::vector<Finding>& findings) {
  if (findings.empty()) return "<p class=\"ok\">No warnings: every figure is within its threshold.</p>\n";
  std::string s = "<ul class=\"findings\">\n";
  for (const auto& f : findings) {
    s += fmt::format("<li class=\"{}\"><b>{}</b> {}<br><span class=\"todo\">What to do: {}</span></li>\n",
                     to_string(f.severity), to_string(f.severity), xml_escape(f.message), xml_escape(f.advice));
  }
  return s + "</ul>\n";
}

std::string verdict_html(const std::vector<Finding>& findings) {
  int problems = 0, warnings = 0;
  for (const auto& f : findings) {
    problems += f.severity == Severity::problem;
    warnings += f.severity == Severity::warning;
  }
  if (problems > 0) {
    return fmt::format("<div class=\"verdict problem\">Not ready to dig: {} {} to fix first{}</div>\n", problems,
                       problems == 1 ? "problem" : "problems",
                       warnings ? fmt::format(", and {} {}", warnings, warnings == 1 ? "warning" : "warnings") : "");
  }
  if (warnings > 0) {
    return fmt::format("<div class=\"verdict warning\">Recorded, with {} {} worth fixing while the layer is still "
                       "there</div>\n",
                       warnings, warnings == 1 ? "warning" : "warnings");
  }
  return "<div class=\"verdict good\">Recorded well enough: the layer can be dug away</div>\n";
}

std::string layer_sections_html(const LayerData& d, const ReportOptions& o) {
  std::string s = verdict_html(d.findings);
  s += "<section><h2>Warnings and what to do</h2>\n" + findings_html(d.findings) + "</section>\n";
  s += photos_section(d);
  s += cameras_section(d, o);
  s += coverage_section(d, o);
  s += markers_section(d, o);
  s += histogram_section(d, o);
  s += hillshade_section(d, o);
  s += figures_section(d);
  return s;
}

std::string page_html(const std::string& title, const std::string& subtitle, const std::string& body) {
  static const char* kStyle = R"(
body{font-family:"DejaVu Sans",Helvetica,Arial,sans-serif;margin:0 auto;max-width:1100px;padding:16px 24px;color:#222;background:#fff}
h1{font-size:26px;margin:8px 0 2px}h2{font-size:19px;border-bottom:2px solid #8c6d46;padding-bottom:3px;margin:26px 0 10px;color:#5a4025}
h3{font-size:16px;margin:18px 0 6px}.sub{color:#666;margin:0 0 12px}
section{page-break-inside:avoid}
.verdict{font-size:20px;font-weight:bold;padding:12px 16px;border-radius:6px;margin:12px 0}
.verdict.problem{background:#fde0dd;color:#99000d;border:2px solid #cb181d}.verdict.warning{background:#fff3cd;color:#7a5500;border:2px solid #e6a700}
.verdict.good{background:#e5f5e0;color:#00441b;border:2px solid #41ab5d}
ul.findings{list-style:none;padding:0}ul.findings li{padding:8px 12px;margin:6px 0;border-left:6px solid #999;background:#f7f7f7}
ul.findings li.problem{border-color:#cb181d;background:#fff5f5}ul.findings li.warning{border-color:#e6a700;background:#fffaf0}
ul.findings li.note{border-color:#6baed6}ul.findings li b{text-transform:uppercase;font-size:12px;margin-right:6px}
.todo{color:#333;font-style:italic}.ok{color:#00441b;font-weight:bold}
.missing{color:#7a5500;background:#fffaf0;padding:8px 12px;border:1px dashed #e6a700}
table{border-collapse:collapse;margin:8px 0}th,td{padding:3px 10px;text-align:left;border-bottom:1px solid #e3e3e3;font-size:14px}
table.kv th{color:#555;font-weight:normal}table.grid th{background:#f1ece3}td.bad{color:#b30000;font-weight:bold}
tr.check td:first-child{color:#a63603}tr.control td:first-child{color:#54278f}
svg.plan,svg.chart{display:block;border:1px solid #ccc;margin:6px 0;max-width:100%;height:auto}
svg text.lbl{font-size:12px;fill:#222}svg text.small{font-size:10px;fill:#666}
svg text.halo{paint-order:stroke;stroke:#fff;stroke-width:3px}svg text.gap{font-weight:bold;fill:#7f0000}
.legend{display:flex;flex-wrap:wrap;gap:14px;align-items:center;font-size:13px;margin:4px 0}
.legend i{display:inline-block;width:14px;height:14px;margin-right:5px;vertical-align:-2px;border:1px solid #999}
.legend svg{vertical-align:-2px;margin-right:5px}
.legend i.hatch{background:repeating-linear-gradient(45deg,#2828a0 0 2px,#fff 2px 6px)}
.legend i.dash{border:none;border-top:2px dashed #b30000;height:0;width:22px}
.ramp{display:flex}.ramp i{width:20px;height:14px;border:none;margin:0}
.caption{color:#555;font-size:13px;margin:4px 0 10px}
.svgbox{overflow-x:auto;border:1px solid #ccc;padding:4px;background:#fff;text-align:center}
.maps{display:flex;flex-wrap:wrap;gap:8px 24px}.maps h3{margin-top:8px}.svgbox svg{max-width:100%;height:auto}
.layer{border-top:1px solid #ccc;margin-top:18px}
footer{color:#888;font-size:12px;margin-top:30px;border-top:1px solid #ddd;padding-top:6px}
)";
  // Every section gets an id from its heading, so that a note can point at report.html#coverage.
  static const std::regex heading("<section><h2>([^<]+)</h2>");
  std::string linked;
  auto it = std::sregex_iterator(body.begin(), body.end(), heading);
  std::size_t at = 0;
  for (; it != std::sregex_iterator(); ++it) {
    std::string id;
    for (char c : (*it)[1].str()) id += std::isalnum(static_cast<unsigned char>(c)) ? char(std::tolower(c)) : '-';
    linked += body.substr(at, std::size_t(it->position()) - at) + "<section id=\"" + id + "\"><h2>" + (*it)[1].str() + "</h2>";
    at = std::size_t(it->position() + it->length());
  }
  linked += body.substr(at);
  const auto now = std::chrono::floor<std::chrono::seconds>(std::chrono::system_clock::now());
  return fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" "
      "content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>{}</style>\n</head>\n<body>\n"
      "<h1>{}</h1>\n<p class=\"sub\">{}</p>\n{}<footer>strata field report, generated {:%Y-%m-%d %H:%M} UTC. "
      "Self-contained: images and drawings are inside this file.</footer>\n</body>\n</html>\n",
      xml_escape(title), kStyle, xml_escape(title), xml_escape(subtitle), linked, now);
}

}  // namespace report_detail

void ReportOptions::validate() const {
  thresholds.validate();
  if (image_px < 200 || image_px > 4000) throw InputError("report options: image_px must be 200-4000 pixels");
  if (coverage_cells < 8 || coverage_cells > 1000) throw InputError("report options: coverage_cells must be 8-1000");
  if (histogram_bins < 4 || histogram_bins > 200) throw InputError("report options: histogram_bins must be 4-200");
}

int LayerVerdict::count(Severity s) const {
  return int(std::count_if(findings.begin(), findings.end(), [&](const Finding& f) { return f.severity == s; }));
}

std::string layer_report_html(Project& project, const std::string& layer, const ReportOptions& options,
                              ReportSummary* summary) {
  options.validate();
  const LayerRecord l = require_layer(project.db(), layer);
  const auto d = rd::gather_layer(project, l, options);
  if (summary) summary->layers.push_back({l.name, d.findings});
  const SiteInfo site = d.site;
  return rd::page_html(fmt::format("Layer {} — field report", l.name),
                       fmt::format("Site {} · unit {} · {}", site.name, l.unit, site.crs),
                       rd::layer_sections_html(d, options));
}

ReportSummary write_layer_report(Project& project, const std::string& layer, const std::filesystem::path& out,
                                 const ReportOptions& options) {
  ReportSummary summary;
  const std::string html = layer_report_html(project, layer, options, &summary);
  write_bytes_atomically(out, "report", html, "export.report.temp_written");
  log::info("wrote the report of layer {} to {}", layer, out.string());
  return summary;
}

std::filesystem::path write_layer_report_product(Project& project, const std::string& layer,
                                                 const ReportOptions& options) {
  const std::string rel = "products/" + layer + "/report.html";
  const auto path = project.dir() / rel;
  const LayerRecord l = require_layer(project.db(), layer);
  write_layer_report(project, layer, path, options);
  Transaction tx(project.db());
  ProductRecord r;
  r.layer_id = l.id;
  r.kind = "report";
  r.path = rel;
  record_product(project.db(), project.dir(), r);
  tx.commit();
  return path;
}

}  // namespace strata
