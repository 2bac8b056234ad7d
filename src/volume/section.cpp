// Sections: profile sampling, the SVG drawing (writer.section.svg) and the
// GeoPackage of 3D lines (writer.section.gpkg).
#include "volume/section.hpp"

#include "core/text.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "crs/crs.hpp"
#include "exporters/raster/gdal_util.hpp"

#include <fmt/format.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

namespace strata {
namespace fs = std::filesystem;
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

}  // namespace

SectionProfile cut_section(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const std::vector<LayerSurface>& layers,
                           const std::vector<UnitSolid>& solids, double step_m) {
  if (layers.empty()) throw InputError("section: there are no layer surfaces to cut");
  const double step = step_m > 0 ? step_m : layers.front().z.cell;
  const double length = (b - a).norm();
  if (!(length >= 2 * step))
    throw InputError(fmt::format("section: the line is {:.3f} m long; it must be at least {:.3f} m", length, 2 * step));
  SectionProfile p;
  p.a = a;
  p.b = b;
  const int n = int(std::floor(length / step)) + 1;
  for (int i = 0; i < n; ++i) p.s.push_back(std::min(i * step, length));
  if (p.s.back() < length - 1e-9) p.s.push_back(length);
  for (const auto& l : layers) {
    SectionProfile::Surface s{l.layer, l.unit, {}};
    for (double c : p.s) {
      const Eigen::Vector2d q = p.point(c);
      s.z.push_back(sample_height(l.z, q.x(), q.y()));
    }
    p.surfaces.push_back(std::move(s));
  }
  for (const auto& solid : solids) {
    SectionProfile::Body body{solid.unit, {}, {}};
    for (double c : p.s) {
      const Eigen::Vector2d q = p.point(c);
      const double t = sample_height(solid.top, q.x(), q.y()), bt = sample_height(solid.bottom, q.x(), q.y());
      const bool ok = std::isfinite(t) && std::isfinite(bt) && t > bt;
      body.top.push_back(ok ? t : kNaN);
      body.bottom.push_back(ok ? bt : kNaN);
    }
    p.bodies.push_back(std::move(body));
  }
  return p;
}

void write_section_svg(const fs::path& path, const SectionProfile& p, const Eigen::Vector3d& origin,
                       const SectionDrawingOptions& o) {
  constexpr const char* kStage = "writer.section.svg";
  if (!(o.scale > 0)) throw InputError(fmt::format("{}: scale 1:{} is not positive", kStage, o.scale));
  const double mm_per_m = 1000.0 / o.scale;  // paper millimetres per metre of ground
  const std::size_t n = p.s.size();

  // Height range of everything drawn (site frame).
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (const auto& s : p.surfaces)
    for (double z : s.z)
      if (std::isfinite(z)) zmin = std::min(zmin, z), zmax = std::max(zmax, z);
  if (!std::isfinite(zmin)) throw ProcessingError(fmt::format("{}: no surface crosses the section line", kStage));
  // The unit not excavated is shown as a hatched band this deep below the last surface.
  constexpr double kNaturalBand = 0.08;  // metres
  const double tick = 0.1;                // metres between height ticks
  const double z_lo = std::floor((zmin + origin.z() - kNaturalBand - 0.02) / tick) * tick - origin.z();
  const double z_hi = std::ceil((zmax + origin.z() + 0.05) / tick) * tick - origin.z();

  const double left = 32, right = 18, top = 28;
  const double width_draw = p.length() * mm_per_m, height_draw = (z_hi - z_lo) * mm_per_m;
  const double legend_h = 10 + 6.0 * double((p.bodies.size() + 2 + 2) / 3);
  const double page_w = std::max(left + width_draw + right, 200.0), page_h = top + height_draw + 22 + legend_h;
  auto X = [&](double s) { return left + s * mm_per_m; };
  auto Y = [&](double z) { return top + (z_hi - z) * mm_per_m; };

  std::string svg;
  auto add = [&](const std::string& s) { svg += s; svg += '\n'; };
  add(R"~(<?xml version="1.0" encoding="UTF-8"?>)~");
  add(fmt::format(R"~(<svg xmlns="http://www.w3.org/2000/svg" width="{0:.1f}mm" height="{1:.1f}mm" viewBox="0 0 {0:.2f} {1:.2f}" font-family="DejaVu Sans, Arial, sans-serif">)~",
                  page_w, page_h));
  add(R"~(<defs><pattern id="natural" patternUnits="userSpaceOnUse" width="2" height="2" patternTransform="rotate(45)"><rect width="2" height="2" fill="#efe6c8"/><line x1="0" y1="0" x2="0" y2="2" stroke="#8a7a50" stroke-width="0.25"/></pattern></defs>)~");
  add(fmt::format(R"~(<rect x="0" y="0" width="{:.2f}" height="{:.2f}" fill="white"/>)~", page_w, page_h));

  // Title and the ends of the line.
  const Eigen::Vector2d A = p.a + origin.head<2>(), B = p.b + origin.head<2>();
  add(fmt::format(R"~(<text x="{:.2f}" y="8" font-size="5" font-weight="bold">{} A-B</text>)~", left, xml_escape(o.title)));
  add(fmt::format(R"~(<text x="{:.2f}" y="13.5" font-size="2.8">A: E {:.2f} N {:.2f}   B: E {:.2f} N {:.2f}   length {:.2f} m   {}   scale 1:{:g}   heights in m</text>)~",
                  left, A.x(), A.y(), B.x(), B.y(), p.length(), xml_escape(o.crs), o.scale));
  add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="4" font-weight="bold" text-anchor="middle">A</text>)~", X(0), top - 3));
  add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="4" font-weight="bold" text-anchor="middle">B</text>)~", X(p.length()), top - 3));

  // Height scale on the left, absolute heights every 10 cm, light grid lines.
  add(fmt::format(R"~(<line x1="{0:.2f}" y1="{1:.2f}" x2="{0:.2f}" y2="{2:.2f}" stroke="black" stroke-width="0.3"/>)~",
                  left - 4, Y(z_hi), Y(z_lo)));
  for (double z = z_lo; z <= z_hi + 1e-9; z += tick) {
    add(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.3"/>)~",
                    left - 6, Y(z), left - 4, Y(z)));
    add(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="#cccccc" stroke-width="0.1"/>)~",
                    left - 4, Y(z), X(p.length()), Y(z)));
    add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5" text-anchor="end">{:.2f}</text>)~", left - 7,
                    Y(z) + 0.9, z + origin.z()));
  }

  // Labels are placed after the drawing, in order of importance (unit numbers,
  // the unit not excavated, layer names), each where it overlaps no label already
  // placed; they are written last, above fills and lines.
  std::vector<LabelBox> placed;
  std::string labels;
  constexpr double kLabelGap = 0.6;  // mm of paper between labels
  auto clear_of_labels = [&](const LabelBox& b) {
    return std::none_of(placed.begin(), placed.end(), [&](const LabelBox& q) { return q.overlaps(b, kLabelGap); });
  };

  // Excavated units, filled, with their number where they are thick enough.
  constexpr double kUnitFont = 3.2;  // mm
  for (std::size_t u = 0; u < p.bodies.size(); ++u) {
    const auto& body = p.bodies[u];
    const char* fill = kFills[u % std::size(kFills)];
    const std::string text = label_of(body.unit, o);
    for (const auto& [i0, i1] : runs(n, [&](std::size_t i) { return std::isfinite(body.top[i]); })) {
      std::string d;
      for (std::size_t i = i0; i <= i1; ++i) d += fmt::format("{}{:.2f},{:.2f} ", i == i0 ? "M" : "L", X(p.s[i]), Y(body.top[i]));
      for (std::size_t i = i1 + 1; i-- > i0;) d += fmt::format("L{:.2f},{:.2f} ", X(p.s[i]), Y(body.bottom[i]));
      add(fmt::format(R"~(<path d="{}Z" fill="{}" stroke="{}" stroke-width="0.15"/>)~", d, fill, fill));
      // Label inside the body where it is 3.5 mm of paper thick or more: the
      // thickest place first, then the next thickest, clear of other labels.
      const double run_mm = (p.s[i1] - p.s[i0]) * mm_per_m;
      if (run_mm < 8) continue;
      std::vector<std::size_t> order;
      for (std::size_t i = i0; i <= i1; ++i) order.push_back(i);
      std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return body.top[a] - body.bottom[a] > body.top[b] - body.bottom[b];
      });
      for (std::size_t i : order) {
        const double paper = (body.top[i] - body.bottom[i]) * mm_per_m;
        if (paper < 3.5) break;
        const double xs = std::clamp(X(p.s[i]), X(p.s[i0]) + 5, X(p.s[i1]) - 5);
        const double ys = Y(0.5 * (body.top[i] + body.bottom[i])) + 1.1;
        const LabelBox b = text_box(xs, ys, kUnitFont, text.size(), "middle");
        if (!clear_of_labels(b)) continue;
        placed.push_back(b);
        labels += fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" font-weight="bold" text-anchor="middle">{}</text>)~",
                              xs, ys, kUnitFont, xml_escape(text)) + "\n";
        break;
      }
    }
  }

  // The unit not yet excavated: a hatched band under the last surface, labelled
  // once per stretch long enough to hold the label; when none is, once, under the
  // longest stretch with a leader line to it.
  if (!p.surfaces.empty()) {
    const auto& last = p.surfaces.back();
    const bool dug = std::any_of(p.bodies.begin(), p.bodies.end(), [&](const auto& b) { return b.unit == last.unit; });
    if (!dug) {
      constexpr double kNaturalFont = 3.0;  // mm
      const std::string text = label_of(last.unit, o) + " not excavated";
      auto stretches = runs(n, [&](std::size_t i) { return std::isfinite(last.z[i]); });
      for (const auto& [i0, i1] : stretches) {
        std::string d;
        for (std::size_t i = i0; i <= i1; ++i) d += fmt::format("{}{:.2f},{:.2f} ", i == i0 ? "M" : "L", X(p.s[i]), Y(last.z[i]));
        for (std::size_t i = i1 + 1; i-- > i0;) d += fmt::format("L{:.2f},{:.2f} ", X(p.s[i]), Y(last.z[i] - kNaturalBand));
        add(fmt::format(R"~(<path d="{}Z" fill="url(#natural)" stroke="none"/>)~", d));
      }
      std::stable_sort(stretches.begin(), stretches.end(),
                       [](const auto& a, const auto& b) { return a.second - a.first > b.second - b.first; });
      bool any = false;
      for (const auto& [i0, i1] : stretches) {
        const std::size_t mid = (i0 + i1) / 2;
        const double xs = X(p.s[mid]), ys = Y(last.z[mid] - 0.5 * kNaturalBand) + 1;
        const LabelBox b = text_box(xs, ys, kNaturalFont, text.size(), "middle");
        if (b.x0 < X(p.s[i0]) || b.x1 > X(p.s[i1]) || !clear_of_labels(b)) continue;  // does not fit in this stretch
        placed.push_back(b);
        any = true;
        labels += fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" text-anchor="middle" font-style="italic">{}</text>)~",
                              xs, ys, kNaturalFont, xml_escape(text)) + "\n";
      }
      if (!any && !stretches.empty()) {
        const auto [i0, i1] = stretches.front();
        const std::size_t mid = (i0 + i1) / 2;
        double low = 0;  // paper y of the band's lowest point
        for (std::size_t i = i0; i <= i1; ++i) low = std::max(low, Y(last.z[i] - kNaturalBand));
        const double xs = std::clamp(X(p.s[mid]), left + 0.3 * kNaturalFont * double(text.size()),
                                     X(p.length()) - 0.3 * kNaturalFont * double(text.size()));
        const double ys = low + 4.5;
        placed.push_back(text_box(xs, ys, kNaturalFont, text.size(), "middle"));
        labels += fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.15"/>)~",
                              xs, ys - 0.8 * kNaturalFont - 0.3, X(p.s[mid]), Y(last.z[mid] - 0.5 * kNaturalBand)) + "\n";
        labels += fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="{}" text-anchor="middle" font-style="italic">{}</text>)~",
                              xs, ys, kNaturalFont, xml_escape(text)) + "\n";
      }
    }
  }

  // Layer surfaces: thin lines; the last (limit of excavation) heavier.
  for (std::size_t k = 0; k < p.surfaces.size(); ++k) {
    const auto& s = p.surfaces[k];
    const bool last = k + 1 == p.surfaces.size();
    for (const auto& [i0, i1] : runs(n, [&](std::size_t i) { return std::isfinite(s.z[i]); })) {
      std::string pts;
      for (std::size_t i = i0; i <= i1; ++i) pts += fmt::format("{:.2f},{:.2f} ", X(p.s[i]), Y(s.z[i]));
      add(fmt::format(R"~(<polyline points="{}" fill="none" stroke="black" stroke-width="{}" stroke-linejoin="round"/>)~",
                      pts, last ? 0.5 : 0.25));
    }
    // Layer name at the right end of its line, where it overlaps no other label
    // (outside the cutting all surfaces coincide: one name there is enough).
    for (std::size_t i = n; i-- > 0;)
      if (std::isfinite(s.z[i])) {
        const double x = X(p.s[i]) + 1, y = Y(s.z[i]) + 0.8;
        const LabelBox b = text_box(x, y, 2.2, s.layer.size(), "start");
        if (!clear_of_labels(b)) break;
        placed.push_back(b);
        labels += fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.2" fill="#444444">{}</text>)~", x, y,
                              xml_escape(s.layer)) + "\n";
        break;
      }
  }
  svg += labels;

  // Datum line: dashed, at the round height just above the highest surface.
  {
    const double datum = std::ceil((zmax + origin.z() + 0.005) / tick) * tick - origin.z();
    add(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.25" stroke-dasharray="3,1.5"/>)~",
                    X(0), Y(datum), X(p.length()), Y(datum)));
    add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5">datum {:.2f} m</text>)~", X(0) + 1, Y(datum) - 1,
                    datum + origin.z()));
  }

  // Scale bar: 1 m in 10 cm divisions, alternating black and white.
  const double bar_y = top + height_draw + 8;
  for (int i = 0; i < 10; ++i)
    add(fmt::format(R"~(<rect x="{:.2f}" y="{:.2f}" width="{:.2f}" height="1.5" fill="{}" stroke="black" stroke-width="0.15"/>)~",
                    left + i * 0.1 * mm_per_m, bar_y, 0.1 * mm_per_m, i % 2 ? "white" : "black"));
  for (double m : {0.0, 0.5, 1.0})
    add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5" text-anchor="middle">{:g}</text>)~",
                    left + m * mm_per_m, bar_y + 4.5, m));
  add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5">m   scale 1:{:g}</text>)~", left + mm_per_m + 3,
                  bar_y + 1.4, o.scale));

  // Legend: fills of the excavated units, the hatched natural, the lines.
  double lx = left, ly = bar_y + 10;
  int col = 0;
  auto legend_item = [&](const std::string& swatch, const std::string& text) {
    add(swatch);
    add(fmt::format(R"~(<text x="{:.2f}" y="{:.2f}" font-size="2.5">{}</text>)~", lx + 8, ly + 2.6, xml_escape(text)));
    if (++col == 3) {
      col = 0;
      lx = left;
      ly += 6;
    } else {
      lx += 55;
    }
  };
  for (std::size_t u = 0; u < p.bodies.size(); ++u) {
    const auto& unit = p.bodies[u].unit;
    const auto t = o.unit_types.find(unit);
    legend_item(fmt::format(R"~(<rect x="{:.2f}" y="{:.2f}" width="6" height="3.5" fill="{}" stroke="black" stroke-width="0.15"/>)~",
                            lx, ly, kFills[u % std::size(kFills)]),
                fmt::format("{} {}", label_of(unit, o), t != o.unit_types.end() ? t->second : "unit"));
  }
  legend_item(fmt::format(R"~(<rect x="{:.2f}" y="{:.2f}" width="6" height="3.5" fill="url(#natural)" stroke="black" stroke-width="0.15"/>)~", lx, ly),
              "not excavated");
  legend_item(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.25"/>)~", lx, ly + 1.75, lx + 6, ly + 1.75),
              "recorded surface (layer)");
  legend_item(fmt::format(R"~(<line x1="{:.2f}" y1="{:.2f}" x2="{:.2f}" y2="{:.2f}" stroke="black" stroke-width="0.5"/>)~", lx, ly + 1.75, lx + 6, ly + 1.75),
              "limit of excavation");
  add("</svg>");

  write_bytes_atomically(path, kStage, svg);
}

void write_section_gpkg(const fs::path& path, const SectionProfile& p, const Eigen::Vector3d& origin,
                        const std::string& crs) {
  constexpr const char* kStage = "writer.section.gpkg";
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!driver) throw IoError(fmt::format("{}: GDAL has no GPKG driver", kStage));
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  const fs::path tmp = path.parent_path() / (".partial-" + path.filename().string());
  std::error_code ec;
  fs::remove(tmp, ec);
  GDALDataset* ds = driver->Create(tmp.c_str(), 0, 0, 0, GDT_Unknown, nullptr);
  if (!ds) throw IoError(fmt::format("{}: {}: cannot create", kStage, path.string()));
  OGRSpatialReference srs;
  srs.importFromWkt(describe_crs(crs).wkt.c_str());
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  auto fail = [&](const std::string& what) {
    GDALClose(GDALDataset::ToHandle(ds));
    fs::remove(tmp, ec);
    throw IoError(fmt::format("{}: {}: {}", kStage, path.string(), what));
  };
  auto point3 = [&](double s, double z) {
    const Eigen::Vector2d q = p.point(s) + origin.head<2>();
    return Eigen::Vector3d(q.x(), q.y(), z + origin.z());
  };
  auto add_line = [&](OGRLayer* layer, const std::vector<Eigen::Vector3d>& pts,
                      const std::vector<std::pair<const char*, std::string>>& fields) {
    OGRFeature f(layer->GetLayerDefn());
    for (const auto& [k, v] : fields) f.SetField(k, v.c_str());
    OGRLineString line;
    for (const auto& q : pts) line.addPoint(q.x(), q.y(), q.z());
    f.SetGeometry(&line);
    if (layer->CreateFeature(&f) != OGRERR_NONE) fail("cannot write a feature");
  };
  auto make_layer = [&](const char* name, std::vector<const char*> fields) {
    OGRLayer* l = ds->CreateLayer(name, &srs, wkbLineString25D, nullptr);
    if (!l) fail(fmt::format("cannot create table {}", name));
    for (const char* f : fields) {
      OGRFieldDefn d(f, OFTString);
      l->CreateField(&d);
    }
    return l;
  };
  const std::size_t n = p.s.size();
  ds->StartTransaction();
  {
    OGRLayer* l = make_layer("section_surfaces", {"layer", "unit"});
    for (const auto& s : p.surfaces)
      for (const auto& [i0, i1] : runs(n, [&](std::size_t i) { return std::isfinite(s.z[i]); })) {
        std::vector<Eigen::Vector3d> pts;
        for (std::size_t i = i0; i <= i1; ++i) pts.push_back(point3(p.s[i], s.z[i]));
        if (pts.size() >= 2) add_line(l, pts, {{"layer", s.layer}, {"unit", s.unit}});
      }
  }
  {
    OGRLayer* l = make_layer("section_units", {"unit"});
    for (const auto& b : p.bodies)
      for (const auto& [i0, i1] : runs(n, [&](std::size_t i) { return std::isfinite(b.top[i]); })) {
        std::vector<Eigen::Vector3d> pts;
        for (std::size_t i = i0; i <= i1; ++i) pts.push_back(point3(p.s[i], b.top[i]));
        for (std::size_t i = i1 + 1; i-- > i0;) pts.push_back(point3(p.s[i], b.bottom[i]));
        pts.push_back(pts.front());
        add_line(l, pts, {{"unit", b.unit}});
      }
  }
  {
    OGRLayer* l = make_layer("section_line", {"name"});
    double ztop = -std::numeric_limits<double>::infinity();
    for (const auto& s : p.surfaces)
      for (double z : s.z)
        if (std::isfinite(z)) ztop = std::max(ztop, z);
    add_line(l, {point3(0, ztop), point3(p.length(), ztop)}, {{"name", "A-B"}});
  }
  if (ds->CommitTransaction() != OGRERR_NONE) fail("cannot commit the features: " + std::string(CPLGetLastErrorMsg()));
  CPLErrorReset();
  GDALClose(GDALDataset::ToHandle(ds));
  if (gdal_detail::gdal_failed()) {
    const std::string why = CPLGetLastErrorMsg();
    fs::remove(tmp, ec);
    throw IoError(fmt::format("{}: {}: {}", kStage, path.string(), why));
  }
  fs::rename(tmp, path, ec);
  if (ec) throw IoError(fmt::format("{}: {}: {}", kStage, path.string(), ec.message()));
}

}  // namespace strata
