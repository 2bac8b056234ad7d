// strata export viewer: the site model in one self-contained HTML page (three.js from
// Debian's libjs-three inlined, the .glb embedded as base64), for any browser offline.
// The page is built by build_site_viewer (src/pipeline), as the field station's 3D page.
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "core/staged_files.hpp"
#include "pipeline/site_viewer.hpp"

#include <fmt/format.h>

#include <fstream>
#include <memory>
#include <string>

namespace strata::cli {
namespace {

struct ViewerArgs {
  std::string dir, out;
  SiteViewerOptions options;
};

void export_viewer(const ViewerArgs& a) {
  Project p = Project::open(a.dir);
  const SiteViewer v = build_site_viewer(p, a.dir, a.options);
  const std::size_t model_bytes = v.first_bytes + v.detail_bytes;
  if (model_bytes > kLargeViewerModelBytes) {
    log::warn("export viewer: the embedded model is {:.0f} MB: browsers may be slow or run out of memory; lower "
              "--max-faces (now {}) or view one --layer", double(model_bytes) / 1e6, a.options.max_faces);
  }
  StagedFiles staged("export viewer");
  const auto tmp = staged.add(a.out);
  {
    std::ofstream out(tmp, std::ios::binary);
    out << v.html;
    out.close();
    if (!out) throw IoError(fmt::format("export viewer: {}: cannot write (disk full?)", tmp.string()));
  }
  fault::point("export.viewer.staged");
  staged.swap_in();
  log::info("wrote {} ({} layers, {} units, {} markers, {} finds, {} cameras; model {:.1f} MB{})", a.out, v.layers,
            v.units, v.markers, v.finds, v.cameras, double(model_bytes) / 1e6,
            v.detail_bytes == 0 ? ""
                                : fmt::format(": {:.1f} MB shown first, {:.1f} MB of full-level layers after",
                                              double(v.first_bytes) / 1e6, double(v.detail_bytes) / 1e6));
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
  cmd->add_option("--layer", a->options.layer, "only this layer's mesh (default: every layer)");
  cmd->add_option("--out", a->out, "output file, .html")->required();
  cmd->add_option("--max-faces", a->options.max_faces, "faces per layer mesh at most (simplified above; 0: keep all)")
      ->capture_default_str();
  cmd->add_option("--coarse-lod", a->options.coarse_lod,
                  "level shown first while the full one loads: faces / 4^N (0: the full level only; a layer "
                  "whose level would keep fewer than 100 faces has none)")
      ->check(CLI::Range(0, 8))
      ->capture_default_str();
  cmd->callback([=] { export_viewer(*a); });
}

}  // namespace strata::cli
