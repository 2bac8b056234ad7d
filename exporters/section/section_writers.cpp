// Writers of a section: the SVG drawing (writer.section.svg) and the GeoPackage
// of 3D lines (writer.section.gpkg).
#include "exporters/section/section_writers.hpp"

#include "core/text.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "crs/crs.hpp"
#include "exporters/raster/gdal_util.hpp"

#include <fmt/format.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace strata {
namespace fs = std::filesystem;
namespace {

// Earth colours for unit fills, in the order units were excavated.
constexpr const char* kFills[] = {"#8c7a5b", "#b98f5e", "#d1a36a", "#a9a66f", "#c7b27d",
                                  "#9c8466", "#b5a48b", "#d8c49a"};

// Continuous stretches [first, last] of samples where `present(i)` holds.
template <typename F>
std::vector<std::pair<std::size_t, std::size_t>> runs(std::size_t n, F present) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  std::size_t i = 0;
  while (i < n) {
    while (i < n && !present(i)) ++i;
    if (i >= n) break;
    std::size_t j = i;
    while (j + 1 < n && present(j + 1)) ++j;
    out.emplace_back(i, j);
    i = j + 1;
  }
  return out;
}

std::string label_of(const std::string& unit, const SectionDrawingOptions& o) {
  const auto t = o.unit_types.find(unit);
  if (t != o.unit_types.end() && t->second == "cut") return "[" + unit + "]";
  return "(" + unit + ")";
}

// A label's box on paper (mm) for the overlap test. DejaVu Sans averages about
// 0.6 em per character; the box is the text's advance by its font size.
struct LabelBox {
  double x0, y0, x1, y1;
  bool overlaps(const LabelBox& o, double gap) const {
    return x0 < o.x1 + gap && o.x0 < x1 + gap && y0 < o.y1 + gap && o.y0 < y1 + gap;
  }
};
LabelBox text_box(double x, double baseline, double font, std::size_t chars, const char* anchor) {
  const double w = 0.6 * font * double(chars);
  const double x0 = std::string(anchor) == "middle" ? x - 0.5 * w : std::string(anchor) == "end" ? x - w : x;
  return {x0, baseline - 0.8 * font, x0 + w, baseline + 0.2 * font};
}

// The page of the drawing: millimetres of paper, y down; heights in the site frame.
struct SectionPage {
  double mm_per_m = 0;                    // paper millimetres per metre of ground
  double z_lo = 0, z_hi = 0, zmax = 0;    // drawn height range; highest surface
  double left = 32, right = 18, top = 28; // margins, mm
  double width_draw = 0, height_draw = 0, page_w = 0, page_h = 0;
  double X(double s) const { return left + s * mm_per_m; }
  double Y(double z) const { return top + (z_hi - z) * mm_per_m; }
};

// The unit not excavated is shown as a hatched band this deep below the last surface.
constexpr double kNaturalBand = 0.08;  // metres
constexpr double kTick = 0.1;          // metres between height ticks

SectionPage layout_page(const SectionProfile& p, const Eigen::Vector3d& origin, const SectionDrawingOptions& o,
                        const char* stage) {
  SectionPage page;
  page.mm_per_m = 1000.0 / o.scale;
  // Height range of everything drawn (site frame).
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (const auto& s : p.surfaces)
    for (double z : s.z)
      if (std::isfinite(z)) zmin = std::min(zmin, z), zmax = std::max(zmax, z);
  if (!std::isfinite(zmin)) throw ProcessingError(fmt::format("{}: no surface crosses the section line", stage));
  page.zmax = zmax;
  // A find off the surfaces (a wrong height in the survey) is still drawn, where it is.
  for (const auto& f : p.finds) zmin = std::min(zmin, f.z), zmax = std::max(zmax, f.z);
  page.z_lo = std::floor((zmin + origin.z() - kNaturalBand - 0.02) / kTick) * kTick - origin.z();
  page.z_hi = std::ceil((zmax + origin.z() + 0.05) / kTick) * kTick - origin.z();
  page.width_draw = p.length() * page.mm_per_m;
  page.height_draw = (page.z_hi - page.z_lo) * page.mm_per_m;
  // Legend items: the units, not excavated, the two lines, and the two find markers.
  const std::size_t items = p.bodies.size() + 3 + (p.finds.empty() ? 0 : 2);
  const double legend_h = 10 + 6.0 * double((items + 2) / 3);
  page.page_w = std::max(page.left + page.width_draw + page.right, 200.0);
  page.page_h = page.top + page.height_draw + 22 + legend_h;
  return page;
}

// The SVG as it is drawn. Labels are placed after the drawing, in order of
// importance (unit numbers, the unit not excavated, layer names), each where it
// overlaps no label already placed; they are written last, above fills and lines.
struct SectionSvg {
  const SectionProfile& p;
  const Eigen::Vector3d& origin;
  const SectionDrawingOptions& o;
  const SectionPage& page;
  std::string svg, labels;
  std::vector<LabelBox> placed;

  void add(const std::string& s) {
    svg += s;
    svg += '\n';
  }
  bool clear_of_labels(const LabelBox& b) const {
    constexpr double kLabelGap = 0.6;  // mm of paper between labels
    return std::none_of(placed.begin(), placed.end(), [&](const LabelBox& q) { return q.overlaps(b, kLabelGap); });
  }
  void place_label(const LabelBox& b, const std::string& element) {
    placed.push_back(b);
    labels += element + "\n";
  }
};

void draw_page_and_title(SectionSvg& d) {
  const auto& p = d.p;
  const auto& origin = d.origin;
  const auto& o = d.o;
  const auto& page = d.page;
  d.add(R"~(<?xml version="1.0" encoding="UTF-8"?>)~");
  d.add(fmt::format(R"~(<svg xmlns="http://www.w3.org/2000/svg" width="{0:.1f}mm" height="{1:.1f}mm" viewBox="0 0 {0:.2f} {1:.2f}" font-family="DejaVu Sans, Arial, sans-serif">)~",
                    page.page_w, page.page_h));
  d.add(R"~(<defs><pattern id="natural" patternUnits="userSpaceOnUse" width="2" height="2" patternTransform="rotate(45)"><rect width="2" height="2" fill="#efe6c8"/><line x1="0" y1="0" x2="0" y2="2" stroke="#8a7a50" stroke-width="0.25"/></pattern></defs>)~");
  d.add(fmt::format(R"~(<rect x="0" y="0" width="{:.2f}" height="{:.2f}" fill="white"/>)~", page.page_w, page.page_h));

  // Title and the ends of the line.
  const Eigen::Vector2d A = p.a + origin.head<2>(), B = p.b + origin.head<2>();
  d.add(fmt::format(R"~(<text x="{:.2f}" y="8" font-size="5" font-weight="bold">{} A-B</text>)~", page.left,
                    xml_escape(o.title)));
  d.add(fmt::format(R"~(<text x="{:.2f}" y="13.5" font-size="2.8">A: E {:.2f} N {:.2f}   B: E {:.2f} N {:.2f}   length {:.2f} m   {}   scale 1:{:g}   heights in m</text>)~",
                    page.left, A.x(), A.y(), B.x(), B.y(), p.length(), xml_escape(o.crs), o.scale));
  d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="4" font-weight="bold" text-anchor="middle">A</text>)~",
                    page.X(0), page.top - 3));
  d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="4" font-weight="bold" text-anchor="middle">B</text>)~",
                    page.X(p.length()), page.top - 3));
}

// Height scale on the left, absolute heights every 10 cm, light grid lines.
void draw_height_scale(SectionSvg& d) {
  const SectionPage& page = d.page;
  const double left = page.left;
  d.add(fmt::format(R"~(<line x1="{0:.2f}" y1="{1:.2f}" x2="{0:.2f}" y2="{2:.2f}" stroke="black" stroke-width="0.3"/>)~",
                    left - 4, page.Y(page.z_hi), page.Y(page.z_lo)));
  for (double z = page.z_lo; z <= page.z_hi + 1e-9; z += kTick) {
    d.add(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.3"/>)~",
                      left - 6, page.Y(z), left - 4, page.Y(z)));
    d.add(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="#cccccc" stroke-width="0.1"/>)~",
                      left - 4, page.Y(z), page.X(d.p.length()), page.Y(z)));
    d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5" text-anchor="end">{:.2f}</text>)~", left - 7,
                      page.Y(z) + 0.9, z + d.origin.z()));
  }
}

// The outline of a band over samples [i0, i1]: along its top, back along its bottom
// (heights by sample index, site frame), open for the caller's "Z".
template <typename Top, typename Bottom>
std::string band_path(const SectionProfile& p, const SectionPage& page, std::size_t i0, std::size_t i1, Top top,
                      Bottom bottom) {
  std::string path;
  for (std::size_t i = i0; i <= i1; ++i) path += fmt::format("{}{:.2f},{:.2f} ", i == i0 ? "M" : "L", page.X(p.s[i]), page.Y(top(i)));
  for (std::size_t i = i1 + 1; i-- > i0;) path += fmt::format("L{:.2f},{:.2f} ", page.X(p.s[i]), page.Y(bottom(i)));
  return path;
}

// The unit's number inside one stretch [i0, i1] of its body where it is 3.5 mm of
// paper thick or more: the thickest place first, then the next thickest, clear of
// other labels.
void label_unit_stretch(SectionSvg& d, const SectionProfile::Body& body, std::size_t i0, std::size_t i1,
                        const std::string& text) {
  constexpr double kUnitFont = 3.2;  // mm
  const auto& p = d.p;
  const auto& page = d.page;
  const double run_mm = (p.s[i1] - p.s[i0]) * page.mm_per_m;
  if (run_mm < 8) return;
  std::vector<std::size_t> order;
  for (std::size_t i = i0; i <= i1; ++i) order.push_back(i);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return body.top[a] - body.bottom[a] > body.top[b] - body.bottom[b];
  });
  for (std::size_t i : order) {
    const double paper = (body.top[i] - body.bottom[i]) * page.mm_per_m;
    if (paper < 3.5) break;
    const double xs = std::clamp(page.X(p.s[i]), page.X(p.s[i0]) + 5, page.X(p.s[i1]) - 5);
    const double ys = page.Y(0.5 * (body.top[i] + body.bottom[i])) + 1.1;
    const LabelBox b = text_box(xs, ys, kUnitFont, text.size(), "middle");
    if (!d.clear_of_labels(b)) continue;
    d.place_label(b, fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" font-weight="bold" text-anchor="middle">{}</text>)~",
                                 xs, ys, kUnitFont, xml_escape(text)));
    break;
  }
}

// Excavated units, filled, with their number where they are thick enough.
void draw_units(SectionSvg& d) {
  const auto& p = d.p;
  const auto& page = d.page;
  const std::size_t n = p.s.size();
  for (std::size_t u = 0; u < p.bodies.size(); ++u) {
    const auto& body = p.bodies[u];
    const char* fill = kFills[u % std::size(kFills)];
    const std::string text = label_of(body.unit, d.o);
    for (const auto& [i0, i1] : runs(n, [&](std::size_t i) { return std::isfinite(body.top[i]); })) {
      const std::string path = band_path(p, page, i0, i1, [&](std::size_t i) { return body.top[i]; },
                                         [&](std::size_t i) { return body.bottom[i]; });
      d.add(fmt::format(R"~(<path d="{}Z" fill="{}" stroke="{}" stroke-width="0.15"/>)~", path, fill, fill));
      label_unit_stretch(d, body, i0, i1, text);
    }
  }
}

// The label of the unit not excavated: once per stretch long enough to hold it;
// when none is, once, under the longest stretch with a leader line to it.
void label_not_excavated(SectionSvg& d, const SectionProfile::Surface& last,
                         std::vector<std::pair<std::size_t, std::size_t>> stretches) {
  constexpr double kNaturalFont = 3.0;  // mm
  const auto& p = d.p;
  const auto& page = d.page;
  const std::string text = label_of(last.unit, d.o) + " not excavated";
  std::stable_sort(stretches.begin(), stretches.end(),
                   [](const auto& a, const auto& b) { return a.second - a.first > b.second - b.first; });
  bool any = false;
  for (const auto& [i0, i1] : stretches) {
    const std::size_t mid = (i0 + i1) / 2;
    const double xs = page.X(p.s[mid]), ys = page.Y(last.z[mid] - 0.5 * kNaturalBand) + 1;
    const LabelBox b = text_box(xs, ys, kNaturalFont, text.size(), "middle");
    if (b.x0 < page.X(p.s[i0]) || b.x1 > page.X(p.s[i1]) || !d.clear_of_labels(b)) continue;  // does not fit in this stretch
    any = true;
    d.place_label(b, fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" text-anchor="middle" font-style="italic">{}</text>)~",
                                 xs, ys, kNaturalFont, xml_escape(text)));
  }
  if (any || stretches.empty()) return;
  const auto [i0, i1] = stretches.front();
  const std::size_t mid = (i0 + i1) / 2;
  double low = 0;  // paper y of the band's lowest point
  for (std::size_t i = i0; i <= i1; ++i) low = std::max(low, page.Y(last.z[i] - kNaturalBand));
  const double xs = std::clamp(page.X(p.s[mid]), page.left + 0.3 * kNaturalFont * double(text.size()),
                               page.X(p.length()) - 0.3 * kNaturalFont * double(text.size()));
  const double ys = low + 4.5;
  d.placed.push_back(text_box(xs, ys, kNaturalFont, text.size(), "middle"));
  d.labels += fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.15"/>)~",
                          xs, ys - 0.8 * kNaturalFont - 0.3, page.X(p.s[mid]), page.Y(last.z[mid] - 0.5 * kNaturalBand)) + "\n";
  d.labels += fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" text-anchor="middle" font-style="italic">{}</text>)~",
                          xs, ys, kNaturalFont, xml_escape(text)) + "\n";
}

// The unit not yet excavated: a hatched band under the last surface.
void draw_not_excavated(SectionSvg& d) {
  const auto& p = d.p;
  const auto& page = d.page;
  if (p.surfaces.empty()) return;
  const auto& last = p.surfaces.back();
  const bool dug = std::any_of(p.bodies.begin(), p.bodies.end(), [&](const auto& b) { return b.unit == last.unit; });
  if (dug) return;
  const auto stretches = runs(p.s.size(), [&](std::size_t i) { return std::isfinite(last.z[i]); });
  for (const auto& [i0, i1] : stretches) {
    const std::string path = band_path(p, page, i0, i1, [&](std::size_t i) { return last.z[i]; },
                                       [&](std::size_t i) { return last.z[i] - kNaturalBand; });
    d.add(fmt::format(R"~(<path d="{}Z" fill="url(#natural)" stroke="none"/>)~", path));
  }
  label_not_excavated(d, last, stretches);
}

// Layer surfaces: thin lines; the last (limit of excavation) heavier.
void draw_surfaces(SectionSvg& d) {
  const auto& p = d.p;
  const auto& page = d.page;
  const std::size_t n = p.s.size();
  for (std::size_t k = 0; k < p.surfaces.size(); ++k) {
    const auto& s = p.surfaces[k];
    const bool last = k + 1 == p.surfaces.size();
    for (const auto& [i0, i1] : runs(n, [&](std::size_t i) { return std::isfinite(s.z[i]); })) {
      std::string pts;
      for (std::size_t i = i0; i <= i1; ++i) pts += fmt::format("{:.2f},{:.2f} ", page.X(p.s[i]), page.Y(s.z[i]));
      d.add(fmt::format(R"~(<polyline points="{}" fill="none" stroke="black" stroke-width="{}" stroke-linejoin="round"/>)~",
                        pts, last ? 0.5 : 0.25));
    }
    // Layer name at the right end of its line, where it overlaps no other label
    // (outside the cutting all surfaces coincide: one name there is enough).
    for (std::size_t i = n; i-- > 0;)
      if (std::isfinite(s.z[i])) {
        const double x = page.X(p.s[i]) + 1, y = page.Y(s.z[i]) + 0.8;
        const LabelBox b = text_box(x, y, 2.2, s.layer.size(), "start");
        if (!d.clear_of_labels(b)) break;
        d.place_label(b, fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.2" fill="#444444">{}</text>)~", x, y,
                                     xml_escape(s.layer)));
        break;
      }
  }
}

// A find's marker: filled in front of the section face (offset >= 0, the side the
// drawing is seen from), open behind it, as finds projected from either side of a
// section are told apart on the drawing.
constexpr double kFindRadius = 0.9;  // mm of paper
std::string find_marker(double x, double y, bool in_front) {
  return fmt::format(R"~(<circle cx="{:.2f}" cy="{:.2f}" r="{}" fill="{}" stroke="black" stroke-width="0.25"/>)~", x, y,
                     kFindRadius, in_front ? "black" : "white");
}

// Finds projected onto the plane: a marker at (chainage, height) and the find's
// number beside it, where it overlaps no label already placed (right, left, above,
// below; on the right when every place is taken: a find is never left unnamed).
void draw_finds(SectionSvg& d) {
  constexpr double kFindFont = 2.2;  // mm
  const auto& page = d.page;
  for (const auto& f : d.p.finds) {
    const double x = page.X(f.s), y = page.Y(f.z);
    d.add(fmt::format(R"~(<g class="find" data-find="{}">{}</g>)~", xml_escape(f.id), find_marker(x, y, f.offset >= 0)));
    const double gap = kFindRadius + 0.6;
    const std::pair<Eigen::Vector2d, const char*> places[] = {
        {{x + gap, y + 0.35 * kFindFont}, "start"},
        {{x - gap, y + 0.35 * kFindFont}, "end"},
        {{x, y - gap}, "middle"},
        {{x, y + gap + 0.8 * kFindFont}, "middle"}};
    std::size_t chosen = 0;
    for (std::size_t k = 0; k < std::size(places); ++k) {
      if (d.clear_of_labels(text_box(places[k].first.x(), places[k].first.y(), kFindFont, f.id.size(), places[k].second))) {
        chosen = k;
        break;
      }
    }
    const auto& [at, anchor] = places[chosen];
    d.place_label(text_box(at.x(), at.y(), kFindFont, f.id.size(), anchor),
                  fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" text-anchor="{}" fill="#7a1010">{}</text>)~",
                              at.x(), at.y(), kFindFont, anchor, xml_escape(f.id)));
  }
}

// Datum line: dashed, at the round height just above the highest surface.
void draw_datum(SectionSvg& d) {
  const auto& p = d.p;
  const auto& origin = d.origin;
  const auto& page = d.page;
  const double datum = std::ceil((page.zmax + origin.z() + 0.005) / kTick) * kTick - origin.z();
  d.add(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.25" stroke-dasharray="3,1.5"/>)~",
                    page.X(0), page.Y(datum), page.X(p.length()), page.Y(datum)));
  d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5">datum {:.2f} m</text>)~", page.X(0) + 1,
                    page.Y(datum) - 1, datum + origin.z()));
}

// Scale bar: 1 m in 10 cm divisions, alternating black and white. Returns its y.
double draw_scale_bar(SectionSvg& d) {
  const SectionPage& page = d.page;
  const double left = page.left, mm_per_m = page.mm_per_m;
  const double bar_y = page.top + page.height_draw + 8;
  for (int i = 0; i < 10; ++i)
    d.add(fmt::format(R"~(<rect x="{:.2f}" y="{:.2f}" width="{:.2f}" height="1.5" fill="{}" stroke="black" stroke-width="0.15"/>)~",
                      left + i * 0.1 * mm_per_m, bar_y, 0.1 * mm_per_m, i % 2 ? "white" : "black"));
  for (double m : {0.0, 0.5, 1.0})
    d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5" text-anchor="middle">{:g}</text>)~",
                      left + m * mm_per_m, bar_y + 4.5, m));
  d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5">m   scale 1:{:g}</text>)~", left + mm_per_m + 3,
                    bar_y + 1.4, d.o.scale));
  return bar_y;
}

// Legend items three to a row below the scale bar.
struct Legend {
  SectionSvg& d;
  double lx, ly;
  int col = 0;

  void item(const std::string& swatch, const std::string& text) {
    d.add(swatch);
    d.add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5">{}</text>)~", lx + 8, ly + 2.6, xml_escape(text)));
    if (++col == 3) {
      col = 0;
      lx = d.page.left;
      ly += 6;
    } else {
      lx += 55;
    }
  }
};

// Legend: fills of the excavated units, the hatched natural, the lines.
void draw_legend(SectionSvg& d, double bar_y) {
  const auto& p = d.p;
  const auto& o = d.o;
  Legend legend{d, d.page.left, bar_y + 10};
  for (std::size_t u = 0; u < p.bodies.size(); ++u) {
    const auto& unit = p.bodies[u].unit;
    const auto t = o.unit_types.find(unit);
    legend.item(fmt::format(R"~(<rect x="{:.2f}" y="{:.2f}" width="6" height="3.5" fill="{}" stroke="black" stroke-width="0.15"/>)~",
                            legend.lx, legend.ly, kFills[u % std::size(kFills)]),
                fmt::format("{} {}", label_of(unit, o), t != o.unit_types.end() ? t->second : "unit"));
  }
  legend.item(fmt::format(R"~(<rect x="{:.2f}" y="{:.2f}" width="6" height="3.5" fill="url(#natural)" stroke="black" stroke-width="0.15"/>)~",
                          legend.lx, legend.ly),
              "not excavated");
  legend.item(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.25"/>)~",
                          legend.lx, legend.ly + 1.75, legend.lx + 6, legend.ly + 1.75),
              "recorded surface (layer)");
  legend.item(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.5"/>)~",
                          legend.lx, legend.ly + 1.75, legend.lx + 6, legend.ly + 1.75),
              "limit of excavation");
  if (p.finds.empty()) return;
  legend.item(find_marker(legend.lx + 3, legend.ly + 1.75, true),
              fmt::format("find, up to {:.2f} m in front", p.finds_within_m));
  legend.item(find_marker(legend.lx + 3, legend.ly + 1.75, false),
              fmt::format("find, up to {:.2f} m behind", p.finds_within_m));
}

// GeoPackage tables of 3D lines, in real CRS coordinates.
class SectionGpkg {
 public:
  SectionGpkg(GDALDataset* ds, const fs::path& path, const SectionProfile& p, const Eigen::Vector3d& origin,
              const std::string& crs)
      : ds_(ds), path_(path), p_(p), origin_(origin) {
    srs_.importFromWkt(describe_crs(crs).wkt.c_str());
    srs_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw IoError(fmt::format("{}: {}: {}", kStage, path_.string(), what));
  }

  void write_surfaces() {
    OGRLayer* l = make_layer("section_surfaces", {"layer", "unit"});
    for (const auto& s : p_.surfaces)
      for (const auto& [i0, i1] : runs(p_.s.size(), [&](std::size_t i) { return std::isfinite(s.z[i]); })) {
        std::vector<Eigen::Vector3d> pts;
        for (std::size_t i = i0; i <= i1; ++i) pts.push_back(point3(p_.s[i], s.z[i]));
        if (pts.size() >= 2) add_line(l, pts, {{"layer", s.layer}, {"unit", s.unit}});
      }
  }

  void write_units() {
    OGRLayer* l = make_layer("section_units", {"unit"});
    for (const auto& b : p_.bodies)
      for (const auto& [i0, i1] : runs(p_.s.size(), [&](std::size_t i) { return std::isfinite(b.top[i]); })) {
        std::vector<Eigen::Vector3d> pts;
        for (std::size_t i = i0; i <= i1; ++i) pts.push_back(point3(p_.s[i], b.top[i]));
        for (std::size_t i = i1 + 1; i-- > i0;) pts.push_back(point3(p_.s[i], b.bottom[i]));
        pts.push_back(pts.front());
        add_line(l, pts, {{"unit", b.unit}});
      }
  }

  void write_line() {
    OGRLayer* l = make_layer("section_line", {"name"});
    double ztop = -std::numeric_limits<double>::infinity();
    for (const auto& s : p_.surfaces)
      for (double z : s.z)
        if (std::isfinite(z)) ztop = std::max(ztop, z);
    add_line(l, {point3(0, ztop), point3(p_.length(), ztop)}, {{"name", "A-B"}});
  }

  // The finds projected onto the plane: a POINT Z each at its place in the section
  // (on the line, at its height), with its chainage, height, offset and recorded
  // unit, and the surveyed E, N. Only when finds were projected (the table may be empty).
  void write_finds() {
    if (p_.finds_within_m <= 0) return;
    OGRLayer* l = ds_->CreateLayer("section_finds", &srs_, wkbPoint25D, nullptr);
    if (!l) fail("cannot create table section_finds");
    for (const char* f : {"find_id", "unit", "type"}) {
      OGRFieldDefn d(f, OFTString);
      l->CreateField(&d);
    }
    for (const char* f : {"chainage_m", "height_m", "offset_m", "e", "n"}) {
      OGRFieldDefn d(f, OFTReal);
      l->CreateField(&d);
    }
    for (const auto& f : p_.finds) {
      OGRFeature feature(l->GetLayerDefn());
      feature.SetField("find_id", f.id.c_str());
      feature.SetField("unit", f.unit.c_str());
      feature.SetField("type", f.type.c_str());
      feature.SetField("chainage_m", f.s);
      feature.SetField("height_m", f.z + origin_.z());
      feature.SetField("offset_m", f.offset);
      feature.SetField("e", f.position.x() + origin_.x());
      feature.SetField("n", f.position.y() + origin_.y());
      const Eigen::Vector3d q = point3(f.s, f.z);
      OGRPoint point(q.x(), q.y(), q.z());
      feature.SetGeometry(&point);
      if (l->CreateFeature(&feature) != OGRERR_NONE) fail("cannot write find " + f.id);
    }
  }

  static constexpr const char* kStage = "writer.section.gpkg";

 private:
  Eigen::Vector3d point3(double s, double z) const {
    const Eigen::Vector2d q = p_.point(s) + origin_.head<2>();
    return Eigen::Vector3d(q.x(), q.y(), z + origin_.z());
  }
  void add_line(OGRLayer* layer, const std::vector<Eigen::Vector3d>& pts,
                const std::vector<std::pair<const char*, std::string>>& fields) const {
    OGRFeature f(layer->GetLayerDefn());
    for (const auto& [k, v] : fields) f.SetField(k, v.c_str());
    OGRLineString line;
    for (const auto& q : pts) line.addPoint(q.x(), q.y(), q.z());
    f.SetGeometry(&line);
    if (layer->CreateFeature(&f) != OGRERR_NONE) fail("cannot write a feature");
  }
  OGRLayer* make_layer(const char* name, const std::vector<const char*>& fields) {
    OGRLayer* l = ds_->CreateLayer(name, &srs_, wkbLineString25D, nullptr);
    if (!l) fail(fmt::format("cannot create table {}", name));
    for (const char* f : fields) {
      OGRFieldDefn d(f, OFTString);
      l->CreateField(&d);
    }
    return l;
  }

  GDALDataset* ds_;
  const fs::path& path_;
  const SectionProfile& p_;
  const Eigen::Vector3d& origin_;
  OGRSpatialReference srs_;
};

}  // namespace

std::string section_svg(const SectionProfile& p, const Eigen::Vector3d& origin, const SectionDrawingOptions& o) {
  constexpr const char* kStage = "writer.section.svg";
  if (!(o.scale > 0)) throw InputError(fmt::format("{}: scale 1:{} is not positive", kStage, o.scale));
  const SectionPage page = layout_page(p, origin, o, kStage);
  SectionSvg d{p, origin, o, page, {}, {}, {}};
  draw_page_and_title(d);
  draw_height_scale(d);
  draw_units(d);
  draw_not_excavated(d);
  draw_surfaces(d);
  draw_finds(d);
  d.svg += d.labels;
  draw_datum(d);
  draw_legend(d, draw_scale_bar(d));
  d.add("</svg>");
  return std::move(d.svg);
}

void write_section_svg(const fs::path& path, const SectionProfile& p, const Eigen::Vector3d& origin,
                       const SectionDrawingOptions& o) {
  write_bytes_atomically(path, "writer.section.svg", section_svg(p, origin, o));
}

void write_section_gpkg(const fs::path& path, const SectionProfile& p, const Eigen::Vector3d& origin,
                        const std::string& crs) {
  constexpr const char* kStage = SectionGpkg::kStage;
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!driver) throw IoError(fmt::format("{}: GDAL has no GPKG driver", kStage));
  write_atomically(path, kStage, [&](const fs::path& tmp) {
    std::error_code ec;
    fs::remove(tmp, ec);
    gdal_detail::DatasetPtr ds(driver->Create(tmp.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    if (!ds) throw IoError(fmt::format("{}: {}: cannot create", kStage, path.string()));
    SectionGpkg gpkg(ds.get(), path, p, origin, crs);
    ds->StartTransaction();
    gpkg.write_surfaces();
    gpkg.write_units();
    gpkg.write_line();
    gpkg.write_finds();
    if (ds->CommitTransaction() != OGRERR_NONE) gpkg.fail("cannot commit the features: " + std::string(CPLGetLastErrorMsg()));
    CPLErrorReset();
    ds.reset();
    if (gdal_detail::gdal_failed()) gpkg.fail(CPLGetLastErrorMsg());
  });
}

}  // namespace strata
