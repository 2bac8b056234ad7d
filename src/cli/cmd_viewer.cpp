// strata export viewer: the site model in one self-contained HTML page (three.js from
// Debian's libjs-three inlined, the .glb embedded as base64), for any browser offline.
#include "cli/site_scene.hpp"
#include "core/base64.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "core/staged_files.hpp"
#include "dense/dense_mesh.hpp"

#include <fmt/format.h>

#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

namespace strata::cli {

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
// Above this a browser tab needs several times as much memory to decode and upload it.
constexpr std::uintmax_t kLargeModelBytes = 150'000'000;

std::string read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("export viewer: {}: cannot read", path.string()));
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

std::string three_js_sources() {
  std::string out;
  for (const char* f : kThreeFiles) {
    const fs::path path = three_dir() / f;
    if (!fs::exists(path)) {
      throw InputError(fmt::format("export viewer: {} not found: the viewer inlines three.js from Debian's "
                                   "libjs-three; run 'apt-get install libjs-three'", path.string()));
    }
    out += "<script>\n" + script_safe(read_file_bytes(path)) + "\n</script>\n";
  }
  return out;
}

// The page's own CSS and markup; the script follows in kViewerJs.
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

// The embedded models: `first` shown as soon as it is decoded, `detail` (may be empty)
// the full level of the layers `first` holds coarse.
struct ViewerModels {
  std::string first, detail;
};

std::string viewer_page(const std::string& title, const std::string& crs, const std::string& three_js,
                        const ViewerModels& models) {
  const bool detail = !models.detail.empty();
  std::string html = fmt::format(fmt::runtime(kViewerHead), fmt::arg("title", title), fmt::arg("crs", crs));
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

struct ViewerArgs {
  std::string dir, layer, out;
  std::size_t max_faces = 300000;
  int coarse_lod = 2;  // level of detail shown first (faces / 4^N); 0: the full level only
};

// The coarse level of every layer mesh that has one (faces / 4^coarse_lod keeps at least
// kMinLevelOfDetailFaces; textured meshes keep their level: simplification would lose
// their UVs): `first` is the whole scene with those layers coarse, `detail` those layers
// at full level.
ViewerModels viewer_models(const SiteScene& site, int coarse_lod, const ExportFrame& frame, const std::string& out) {
  GltfScene first = site.scene, detail;
  std::deque<DenseMesh> coarse;  // stable addresses for the scene's pointers
  for (const GltfNode& node : site.scene.nodes) {
    if (coarse_lod == 0 || node.mesh < 0 || node.name.rfind("layer ", 0) != 0) continue;
    GltfMesh& gm = first.meshes[std::size_t(node.mesh)];
    const std::size_t faces = gm.mesh->faces.size(), target = faces >> (2 * coarse_lod);
    if (gm.texture || target < kMinLevelOfDetailFaces) continue;
    coarse.push_back(simplify_mesh(*gm.mesh, target));
    gm.mesh = &coarse.back();
    detail.meshes.push_back(site.scene.meshes[std::size_t(node.mesh)]);
    GltfNode full = node;
    full.mesh = int(detail.meshes.size()) - 1;
    detail.nodes.push_back(std::move(full));
    log::info("export viewer: {}: {} faces shown first (coarse level {}), then all {}", node.name,
              coarse.back().faces.size(), coarse_lod, faces);
  }
  ViewerModels m;
  m.first = encode_glb(first, frame, out);
  if (!detail.nodes.empty()) m.detail = encode_glb(detail, frame, out);
  return m;
}

void export_viewer(const ViewerArgs& a) {
  const std::string three_js = three_js_sources();  // read first: a missing package is refused before the slow part
  Project p = Project::open(a.dir);
  SiteSceneOptions options;
  options.max_layer_faces = a.max_faces;
  options.command = "export viewer";
  options.only_layer = a.layer;
  const SiteScene site = build_site_scene(p, a.dir, options);
  const SiteInfo info = p.site();
  ExportFrame frame;
  frame.site_origin = info.origin;
  frame.crs = info.crs;
  const ViewerModels models = viewer_models(site, a.coarse_lod, frame, a.out);
  const std::size_t model_bytes = models.first.size() + models.detail.size();
  if (model_bytes > kLargeModelBytes) {
    log::warn("export viewer: the embedded model is {:.0f} MB: browsers may be slow or run out of memory; lower "
              "--max-faces (now {}) or view one --layer", double(model_bytes) / 1e6, a.max_faces);
  }
  const std::string title = fs::path(a.dir).filename().string() + (a.layer.empty() ? "" : " layer " + a.layer);
  StagedFiles staged("export viewer");
  const fs::path tmp = staged.add(a.out);
  {
    std::ofstream out(tmp, std::ios::binary);
    out << viewer_page(title, info.crs, three_js, models);
    out.close();
    if (!out) throw IoError(fmt::format("export viewer: {}: cannot write (disk full?)", tmp.string()));
  }
  staged.swap_in();
  log::info("wrote {} ({} layers, {} units, {} markers, {} finds, {} cameras; model {:.1f} MB{})", a.out, site.layers,
            site.units, site.markers, site.finds, site.cameras, double(model_bytes) / 1e6,
            models.detail.empty() ? ""
                                  : fmt::format(": {:.1f} MB shown first, {:.1f} MB of full-level layers after",
                                                double(models.first.size()) / 1e6, double(models.detail.size()) / 1e6));
}

}  // namespace

void register_viewer_command(CLI::App& exp) {
  auto* cmd = exp.add_subcommand(
      "viewer",
      "the site model (as 'export model' builds it) in one self-contained HTML page that opens\n"
      "in any browser offline: three.js inlined from Debian's libjs-three, the model embedded.\n"
      "Layers and units toggle, unit volumes on hover, markers named, a movable vertical section\n"
      "plane, and a measuring tool showing site CRS coordinates and distances (a click on a\n"
      "marker gives its surveyed coordinates). Layers show their photo colours unlit ('shade\n"
      "layers' lights them). Layer meshes above --max-faces are simplified first (colours and\n"
      "normals kept); each layer is shown first at a coarse level (--coarse-lod, faces / 4^N),\n"
      "replaced by the full one once the browser has decoded it (both are in the page).\n"
      "URL parameters: ?hide=layer%20L2,markers starts those switched off; ?shade=1 lights the\n"
      "layers. See docs/model.md (Viewer).");
  auto a = std::make_shared<ViewerArgs>();
  cmd->add_option("DIR", a->dir, "project folder")->required();
  cmd->add_option("--layer", a->layer, "only this layer's mesh (default: every layer)");
  cmd->add_option("--out", a->out, "output file, .html")->required();
  cmd->add_option("--max-faces", a->max_faces, "faces per layer mesh at most (simplified above; 0: keep all)")
      ->capture_default_str();
  cmd->add_option("--coarse-lod", a->coarse_lod,
                  "level shown first while the full one loads: faces / 4^N (0: the full level only; a layer "
                  "whose level would keep fewer than 100 faces has none)")
      ->check(CLI::Range(0, 8))
      ->capture_default_str();
  cmd->callback([=] { export_viewer(*a); });
}

}  // namespace strata::cli
