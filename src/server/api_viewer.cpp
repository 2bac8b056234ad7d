// The 3D page's route: the site model in the viewer page `strata export viewer` writes
// (build_site_viewer), served to an iframe. Built once per state of the record and
// kept: the page of a site takes seconds to build (the coarse levels are simplified).
#include "core/hash.hpp"
#include "pipeline/site_viewer.hpp"
#include "project/find_records.hpp"
#include "project/records.hpp"
#include "server/http.hpp"

#include <fmt/format.h>

#include <mutex>

namespace strata::server {
using httplib::Request;
using httplib::Response;

namespace {

// What the viewer page shows: the products (by checksum), units, markers and finds.
std::string record_state(Project& p, const std::string& layer) {
  std::string s = layer + "\n";
  for (const auto& product : list_products(p.db())) s += product.kind + " " + product.sha256 + "\n";
  for (const auto& u : list_units(p.db())) s += u.code + " " + u.type + " " + u.description + "\n";
  for (const auto& m : list_markers(p.db())) {
    s += fmt::format("{} {} {:.6f} {:.6f} {:.6f}\n", m.name, m.kind, m.position.x(), m.position.y(), m.position.z());
  }
  for (const auto& f : list_finds(p.db())) {
    s += fmt::format("{} {} {} {:.6f} {:.6f} {:.6f}\n", f.id, f.unit, f.type, f.position.x(), f.position.y(),
                     f.position.z());
  }
  return sha256_hex(s);
}

struct ViewerCache {
  std::mutex building;  // one page built at a time; the others wait for it and reuse it
  std::string key, html;
};

void get_viewer(Context& c, const Request& req, Response& res) {
  static ViewerCache cache;
  const std::string layer = req.has_param("layer") ? req.get_param_value("layer") : "";
  Project p = c.read();
  if (!layer.empty() && !find_layer(p.db(), layer)) {
    throw HttpError(404, fmt::format("layer '{}' does not exist", layer), "layer", layer);
  }
  std::string html;
  {
    std::lock_guard lock(cache.building);
    const std::string key = record_state(p, layer);
    if (cache.key != key) {
      SiteViewerOptions options;
      options.layer = layer;
      options.command = "the 3D page";
      cache.html = build_site_viewer(p, c.dir.string(), options).html;
      cache.key = key;
    }
    html = cache.html;
  }
  // The page inlines three.js and its own script: they may run, nothing else may load.
  res.set_header("Content-Security-Policy",
                 "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data: blob:; "
                 "connect-src data: blob:; frame-ancestors 'self'");
  res.status = 200;
  res.set_content(html, "text/html; charset=utf-8");
}

}  // namespace

std::vector<Route> viewer_routes() {
  return {{{"GET", "/api/viewer", Role::viewer, "the site model in the 3D viewer page"}, get_viewer, {}}};
}

}  // namespace strata::server
