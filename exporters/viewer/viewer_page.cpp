#include "exporters/viewer/viewer_page.hpp"

#include "core/base64.hpp"
#include "core/error.hpp"
#include "core/text.hpp"

#include <fmt/format.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace strata {

extern const char* const kViewerJs;  // viewer_js.cpp: the page's script

namespace {

namespace fs = std::filesystem;

// Debian's libjs-three (r111): the non-module builds that define the global THREE.
// STRATA_LIBJS_THREE_DIR replaces the folder (tests of a missing package).
fs::path three_dir() {
  const char* env = std::getenv("STRATA_LIBJS_THREE_DIR");
  return env && *env ? fs::path(env) : fs::path("/usr/share/javascript/three");
}
const char* const kThreeFiles[] = {"build/three.min.js", "examples/js/loaders/GLTFLoader.js",
                                   "examples/js/controls/OrbitControls.js"};

std::string read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("writer.viewer: {}: cannot read", path.string()));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Inlined into <script>: a literal "</script" inside would end the element early.
std::string script_safe(std::string js) {
  for (std::size_t i = js.find("</script"); i != std::string::npos; i = js.find("</script", i + 2)) {
    js.replace(i, 2, "<\\/");
  }
  return js;
}

}  // namespace

std::string viewer_three_js() {
  std::string out;
  for (const char* f : kThreeFiles) {
    const fs::path path = three_dir() / f;
    if (!fs::exists(path)) {
      throw InputError(fmt::format("writer.viewer: {} not found: the viewer inlines three.js from Debian's "
                                   "libjs-three; run 'apt-get install libjs-three'", path.string()));
    }
    out += "<script>\n" + script_safe(read_file_bytes(path)) + "\n</script>\n";
  }
  return out;
}

// The page's own CSS and markup; the script follows in kViewerJs.
namespace {

const char* const kViewerHead = R"HTML(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
html, body {{ margin: 0; height: 100%; overflow: hidden; font: 13px sans-serif; }}
#view {{ position: absolute; inset: 0; }}
#panel {{ position: absolute; top: 8px; left: 8px; max-height: 90%; overflow-y: auto; background: rgba(255,255,255,0.88);
  padding: 6px 10px; border-radius: 4px; min-width: 200px; }}
#panel h3 {{ margin: 6px 0 2px; font-size: 13px; }}
#panel label {{ display: block; white-space: nowrap; }}
#readout {{ position: absolute; bottom: 8px; left: 8px; background: rgba(255,255,255,0.88); padding: 4px 8px;
  border-radius: 4px; font-family: monospace; white-space: pre; }}
#tip {{ position: absolute; pointer-events: none; background: #ffd; border: 1px solid #999; padding: 2px 5px; display: none; }}
.label {{ position: absolute; pointer-events: none; font-size: 11px; color: #000; text-shadow: 0 0 3px #fff; }}
#status {{ position: absolute; top: 8px; right: 8px; background: rgba(255,255,255,0.88); padding: 2px 6px; }}
#status.error {{ color: #b00; }}
</style></head><body>
<div id="view"></div><div id="labels"></div>
<div id="panel"><b>{title}</b>
<h3>Layers</h3><div id="layers"></div>
<h3>Units</h3><div id="units"></div>
<h3>Show</h3>
<label><input type="checkbox" id="show-markers" checked> markers</label>
<label><input type="checkbox" id="show-cameras"> cameras</label>
<label><input type="checkbox" id="shade-layers"> shade layers (light the relief)</label>
<h3>Section</h3>
<label><input type="checkbox" id="section"> vertical section plane</label>
<label>position <input type="range" id="section-pos" min="-1" max="1" step="0.001" value="0"></label>
<label>azimuth <input type="range" id="section-az" min="0" max="180" step="1" value="90"> <span id="az-deg">90</span>&deg;</label>
<h3>Measure</h3>
<label><input type="checkbox" id="measure"> click two points</label>
</div>
<div id="readout">{crs}</div><div id="tip"></div><div id="status">loading</div>
)HTML";

}  // namespace

std::string viewer_page(const std::string& title, const std::string& crs, const std::string& three_js,
                        const ViewerModels& models) {
  const bool detail = !models.detail.empty();
  std::string html = fmt::format(fmt::runtime(kViewerHead), fmt::arg("title", xml_escape(title)),
                                 fmt::arg("crs", xml_escape(crs)));
  html += three_js;
  html += fmt::format("<script id=\"model\" type=\"application/octet-stream\" data-detail=\"{}\">\n",
                      detail ? "yes" : "no") + base64(models.first) + "\n</script>\n";
  html += "<script>\n" + std::string(kViewerJs) + "\n</script>\n";
  // After the script: the browser runs it, and draws the coarse level, while it is
  // still parsing this element.
  if (detail) html += "<script id=\"model-detail\" type=\"application/octet-stream\">\n" + base64(models.detail) + "\n</script>\n";
  html += "</body></html>\n";
  return html;
}

}  // namespace strata
