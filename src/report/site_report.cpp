// The site report: every layer's verdict and findings, the finds against the unit
// solids, the Harris matrix, unit volumes, thickness maps, and a section along the
// excavation's long axis with the finds near it.
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/text.hpp"
#include "exporters/section/section_writers.hpp"
#include "importers/raster/geotiff.hpp"
#include "report/html_util.hpp"
#include "report/report_internal.hpp"
#include "stratigraphy/graphviz.hpp"
#include "stratigraphy/harris_matrix.hpp"
#include "stratigraphy/recorded_matrix.hpp"
#include "volume/section.hpp"
#include "volume/site_volumes.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace strata {
namespace rd = report_detail;

namespace {

std::string missing(const std::string& text) { return "<p class=\"missing\">" + xml_escape(text) + "</p>\n"; }

std::string read_all(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// A plain layered drawing when Graphviz is missing: rows by longest path from the
// top of the matrix, edges as straight lines.
std::string own_matrix_svg(const HarrisMatrix& m) {
  const auto order = m.topological_order();
  const auto edges = m.reduced_edges();
  std::vector<int> rank(m.nodes().size(), 0);
  for (int n : order) {
    for (const auto& [a, b] : edges) {
      if (a == n) rank[std::size_t(b)] = std::max(rank[std::size_t(b)], rank[std::size_t(n)] + 1);
    }
  }
  std::map<int, std::vector<int>> rows;
  for (int n : order) rows[rank[std::size_t(n)]].push_back(n);
  std::size_t widest = 1;
  for (const auto& [r, v] : rows) widest = std::max(widest, v.size());
  const double bw = 90, bh = 30, gx = 30, gy = 40;
  const double w = widest * (bw + gx) + gx, h = rows.size() * (bh + gy) + gy;
  std::vector<Eigen::Vector2d> pos(m.nodes().size());
  for (const auto& [r, v] : rows) {
    const double row_w = v.size() * (bw + gx) - gx;
    for (std::size_t i = 0; i < v.size(); ++i) {
      pos[std::size_t(v[i])] = {(w - row_w) / 2 + i * (bw + gx) + bw / 2, gy + r * (bh + gy) + bh / 2};
    }
  }
  std::string s = fmt::format("<svg width=\"{:.0f}\" height=\"{:.0f}\" viewBox=\"0 0 {:.0f} {:.0f}\">", w, h, w, h);
  for (const auto& [a, b] : edges) {
    const auto& p = pos[std::size_t(a)];
    const auto& q = pos[std::size_t(b)];
    s += fmt::format("<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#333\"/>", p.x(),
                     p.y() + bh / 2, q.x(), q.y() - bh / 2);
  }
  for (std::size_t n = 0; n < pos.size(); ++n) {
    s += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{}\" height=\"{}\" fill=\"#fff\" stroke=\"#333\"/>"
                     "<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"lbl\" text-anchor=\"middle\">{}</text>",
                     pos[n].x() - bw / 2, pos[n].y() - bh / 2, bw, bh, pos[n].x(), pos[n].y() + 4,
                     xml_escape(m.nodes()[n].label()));
  }
  return s + "</svg>";
}

std::string matrix_section(Database& db) {
  std::string s = "<section><h2>Harris matrix</h2>\n";
  const auto units = list_units(db);
  if (units.empty()) return s + missing("No stratigraphic units recorded yet.") + "</section>\n";
  try {
    const HarrisMatrix m = recorded_matrix(db);
    std::string svg = rd::inline_svg(graphviz_svg(m.to_dot()).value_or(""));
    const bool graphviz = !svg.empty();
    if (!graphviz) svg = own_matrix_svg(m);
    s += "<div class=\"svgbox\">" + svg + "</div>\n";
    s += fmt::format("<p class=\"caption\">{} units, {} relations; later units above earlier ones{}.</p>\n", units.size(),
                     m.relations().size(), graphviz ? "" : " (simple layout: install Graphviz for a better one)");
  } catch (const Error& e) {
    s += missing(fmt::format("The Harris matrix cannot be drawn: {}", e.what()));
  }
  return s + "</section>\n";
}

std::string volumes_section(Database& db) {
  std::string s = "<section><h2>Volumes</h2>\n";
  auto st = db.prepare(
      "SELECT u.code, v.top_layer, v.bottom_layers, v.volume_m3, v.volume_sigma_m3, v.area_m2, v.mean_thickness_m, "
      "v.min_thickness_m, v.max_thickness_m, v.method, v.details_json FROM unit_volumes v JOIN units u ON u.id = "
      "v.unit_id ORDER BY u.code");
  std::string rows, advice;
  double total = 0;
  while (st.step()) {
    const auto sigma = st.get_optional_double(4);
    total += st.get_double(3);
    rows += fmt::format(
        "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.3f}{}</td><td>{:.2f}</td><td>{:.0f}</td><td>{:.0f}–{:.0f}</td>"
        "<td>{}</td></tr>",
        xml_escape(st.get_text(0)), xml_escape(st.get_text(1)), xml_escape(st.get_text(2)), st.get_double(3),
        sigma ? fmt::format(" ± {:.3f}", *sigma) : "", st.get_double(5), 1000 * st.get_double(6),
        1000 * st.get_double(7), 1000 * st.get_double(8), xml_escape(st.get_text(9)));
    // How sure the figure is and what would make it surer (strata volume).
    const auto details = nlohmann::json::parse(st.is_null(10) ? std::string("{}") : st.get_text(10), nullptr, false);
    if (details.is_object() && details.value("advice", std::string()) != "")
      advice += fmt::format("<li>{}: {}</li>", xml_escape(st.get_text(0)), xml_escape(details.value("advice", std::string())));
  }
  if (rows.empty()) {
    return s + missing("No volumes yet: they need at least two processed layers; run: strata volume DIR") + "</section>\n";
  }
  s += "<table class=\"grid\"><tr><th>unit</th><th>top surface</th><th>bottom surface</th><th>volume (m³)</th>"
       "<th>area (m²)</th><th>mean thickness (mm)</th><th>thickness min–p99 (mm)</th><th>method</th></tr>" +
       rows + "</table>\n";
  if (!advice.empty()) s += "<ul class=\"advice\">" + advice + "</ul>\n";
  s += fmt::format(
      "<p class=\"caption\">Total excavated volume {:.3f} m³. The upper end of the thickness range is the 99th "
      "percentile of the unit's cells (outlier cells of the dense surfaces left out; the single-cell maximum is in "
      "unit_volumes.details_json).</p>\n",
      total);
  return s + "</section>\n";
}

std::string thickness_section(Project& project, const ReportOptions& o) {
  std::string s = "<section><h2>Thickness maps</h2>\n";
  Database& db = project.db();
  const auto products = list_products(db, std::nullopt, "thickness");
  if (products.empty()) return s + missing("No thickness maps yet: run: strata volume DIR") + "</section>\n";
  std::map<std::int64_t, std::string> unit_code;
  for (const auto& u : list_units(db)) unit_code[u.id] = u.code;
  const SiteInfo site = project.site();
  const int px = std::max(200, o.image_px / 2 - 10);
  s += "<div class=\"maps\">\n";  // side by side, wrapping
  for (const auto& p : products) {
    const std::string name = p.unit_id ? "unit " + unit_code[*p.unit_id] : p.path;
    s += "<div class=\"map\"><h3>" + xml_escape(name) + "</h3>\n";
    try {
      const RasterThumbnail t = read_raster_thumbnail(project.dir() / p.path, px, false);
      float hi = 0;
      for (std::size_t i = 0; i < t.valid.size(); ++i) {
        if (t.valid[i]) hi = std::max(hi, t.band[0][i]);
      }
      rd::Image im{t.width, t.height, 4, {}};
      im.pixels.assign(std::size_t(t.width) * std::size_t(t.height) * 4, 0);
      for (int y = 0; y < t.height; ++y) {
        for (int x = 0; x < t.width; ++x) {
          const std::size_t i = std::size_t(y) * std::size_t(t.width) + std::size_t(x);
          if (!t.valid[i] || !(t.band[0][i] > 0)) continue;
          std::uint8_t* q = im.at(x, y);
          rd::ramp_viridis(hi > 0 ? t.band[0][i] / hi : 0, q);
          q[3] = 255;
        }
      }
      const rd::Extent where{t.west - site.origin.x(), t.south - site.origin.y(),
                             t.east - site.origin.x(), t.north - site.origin.y()};
      const rd::PlanFrame f(where.padded(0.03), px, px);
      s += f.open("thickness of " + name) + f.image(rd::png_data_uri(im), where) + f.decorations() +
           rd::PlanFrame::close();
      std::string ramp = "<div class=\"ramp\">";
      for (int k = 0; k <= 10; ++k) {
        std::uint8_t rgb[3];
        rd::ramp_viridis(k / 10.0, rgb);
        ramp += fmt::format("<i style=\"background:#{:02x}{:02x}{:02x}\"></i>", rgb[0], rgb[1], rgb[2]);
      }
      s += "<div class=\"legend\"><span>0 mm</span>" + ramp + fmt::format("</div><span>{:.0f} mm</span></div>\n", 1000 * hi);
    } catch (const Error& e) {
      s += missing(fmt::format("{} could not be read: {}", p.path, e.what()));
    }
    s += "</div>\n";
  }
  return s + "</div>\n<p class=\"caption\">Thickness of each unit: the height of the surface before it was dug "
             "minus the surface after, in millimetres (each map has its own scale).</p>\n</section>\n";
}

std::string section_section(Project& project, const ReportOptions& o) {
  std::string s = "<section><h2>Section</h2>\n";
  if (!o.section) return s + missing("Left out of this report.") + "</section>\n";
  try {
    const SiteModel model = load_site_model(project, SiteVolumeOptions{});
    // The long axis of the excavated area: the longer side of the box of every
    // surface's known cells, through its middle.
    rd::Extent e;
    for (const auto& l : model.layers) {
      for (std::size_t c = 0; c < l.z.z.size(); ++c) {
        if (!std::isfinite(l.z.z[c])) continue;
        const Eigen::Vector2d p = l.z.grid.centre(c);
        e.add(p.x(), p.y());
      }
    }
    if (e.empty()) return s + missing("The layer surfaces have no known cell.") + "</section>\n";
    const double inset = 0.02 * std::max(e.x1 - e.x0, e.y1 - e.y0);
    Eigen::Vector2d a, b;
    if (e.x1 - e.x0 >= e.y1 - e.y0) {
      a = {e.x0 + inset, (e.y0 + e.y1) / 2};
      b = {e.x1 - inset, (e.y0 + e.y1) / 2};
    } else {
      a = {(e.x0 + e.x1) / 2, e.y0 + inset};
      b = {(e.x0 + e.x1) / 2, e.y1 - inset};
    }
    SectionProfile profile = cut_section(a, b, model.layers, model.solids);
    const std::size_t finds =
        add_section_finds(profile, list_finds(project.db()), model.site.origin, SectionFindOptions{});
    SectionDrawingOptions drawing;
    drawing.title = "Section along the long axis";
    drawing.crs = model.site.crs;
    for (const auto& u : model.units) drawing.unit_types[u.code] = u.type;
    const auto tmp = std::filesystem::temp_directory_path() / fmt::format("strata-report-section-{}.svg", ::getpid());
    write_section_svg(tmp, profile, model.site.origin, drawing);
    const std::string svg = rd::inline_svg(read_all(tmp));
    std::filesystem::remove(tmp);
    s += "<div class=\"svgbox\">" + svg + "</div>\n";
    const Eigen::Vector3d o3 = model.site.origin;
    s += "<p class=\"caption\">" +
         xml_escape(fmt::format("From A (E {:.2f}, N {:.2f}) to B (E {:.2f}, N {:.2f}), {:.2f} m, through {} layer "
                                "surfaces; {} finds within {:.2f} m of it projected onto it.",
                                a.x() + o3.x(), a.y() + o3.y(), b.x() + o3.x(), b.y() + o3.y(), profile.length(),
                                profile.surfaces.size(), finds, SectionFindOptions{}.within_m)) +
         "</p>\n";
  } catch (const Error& e) {
    s += missing(fmt::format("No section yet: {}", e.what()));
  }
  return s + "</section>\n";
}

std::string layers_section(Project& project, const ReportOptions& o, ReportSummary* summary) {
  std::string s = "<section><h2>Layers</h2>\n";
  const auto layers = list_layers(project.db());
  if (layers.empty()) return s + missing("No layers recorded yet.") + "</section>\n";
  std::string table =
      "<table class=\"grid\"><tr><th>layer</th><th>unit</th><th>photos</th><th>aligned</th><th>georeferenced</th>"
      "<th>control RMSE</th><th>check RMSE</th><th>DTM</th><th>problems</th><th>warnings</th></tr>";
  std::string details;
  for (const auto& l : layers) {
    const auto d = rd::gather_layer(project, l, o);
    const LayerVerdict v{l.name, d.findings};
    if (summary) summary->layers.push_back(v);
    const auto& f = d.figures;
    auto mm = [](const std::optional<double>& x) { return x ? format_mm(*x) : std::string("–"); };
    table += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
                         "<td class=\"{}\">{}</td><td>{}</td></tr>",
                         xml_escape(l.name), xml_escape(l.unit), f.photos,
                         f.aligned ? fmt::format("{} of {}", f.registered, f.photos) : "not processed",
                         f.aligned ? (f.georeferenced ? "yes" : "no") : "–", mm(f.control_rmse_m), mm(f.check_rmse_m),
                         d.dtm ? "yes" : "no", v.count(Severity::problem) ? "bad" : "", v.count(Severity::problem),
                         v.count(Severity::warning));
    details += "<div class=\"layer\"><h3>Layer " + xml_escape(l.name) + " (unit " + xml_escape(l.unit) + ")</h3>\n" +
               rd::verdict_html(d.findings) + rd::findings_html(d.findings) + "</div>\n";
  }
  s += table + "</table>\n<p class=\"caption\">The full report of a layer: strata report DIR --layer LAYER --out "
               "layer.html</p>\n" + details;
  return s + "</section>\n";
}

}  // namespace

std::string site_report_html(Project& project, const ReportOptions& options, ReportSummary* summary) {
  options.validate();
  const SiteInfo site = project.site();
  std::string body = "<section><h2>Site</h2>\n<table class=\"kv\">";
  body += "<tr><th>name</th><td>" + xml_escape(site.name) + "</td></tr>";
  body += "<tr><th>CRS</th><td>" + xml_escape(site.crs) + "</td></tr>";
  body += site.origin_set ? fmt::format("<tr><th>site origin</th><td>E {:.1f}, N {:.1f}, Z {:.1f} m</td></tr>",
                                        site.origin.x(), site.origin.y(), site.origin.z())
                          : std::string("<tr><th>site origin</th><td>not fixed yet (no markers imported)</td></tr>");
  body += fmt::format("<tr><th>units</th><td>{}</td></tr><tr><th>layers</th><td>{}</td></tr><tr><th>markers</th><td>{}"
                      "</td></tr></table>\n</section>\n",
                      list_units(project.db()).size(), list_layers(project.db()).size(),
                      list_markers(project.db()).size());
  // The layers' verdicts come first in the page: they are what to act on.
  std::string layers = layers_section(project, options, summary);
  body += layers;
  body += rd::finds_section_html(project, summary ? &summary->finds : nullptr);
  body += matrix_section(project.db());
  body += volumes_section(project.db());
  body += thickness_section(project, options);
  body += section_section(project, options);
  return rd::page_html(fmt::format("Site {} — report", site.name), fmt::format("{} · {}", site.crs, project.dir().string()),
                       body);
}

ReportSummary write_site_report(Project& project, const std::filesystem::path& out, const ReportOptions& options) {
  ReportSummary summary;
  const std::string html = site_report_html(project, options, &summary);
  write_bytes_atomically(out, "report", html, "export.report.temp_written");
  log::info("wrote the site report to {}", out.string());
  return summary;
}

}  // namespace strata
