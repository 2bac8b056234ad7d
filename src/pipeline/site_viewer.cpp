#include "pipeline/site_viewer.hpp"

#include "core/log.hpp"
#include "dense/dense_mesh.hpp"
#include "exporters/viewer/viewer_page.hpp"
#include "pipeline/site_scene.hpp"

#include <fmt/format.h>

#include <deque>
#include <filesystem>

namespace strata {
namespace {

// The coarse level of every layer mesh that has one (faces / 4^coarse_lod keeps at least
// kMinLevelOfDetailFaces; textured meshes keep their level: simplification would lose
// their UVs): `first` is the whole scene with those layers coarse, `detail` those layers
// at full level.
ViewerModels viewer_models(const SiteScene& site, int coarse_lod, const ExportFrame& frame, const std::string& command) {
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
    log::info("{}: {}: {} faces shown first (coarse level {}), then all {}", node.name,
              command, coarse.back().faces.size(), coarse_lod, faces);
  }
  ViewerModels m;
  m.first = encode_glb(first, frame, command);
  if (!detail.nodes.empty()) m.detail = encode_glb(detail, frame, command);
  return m;
}

}  // namespace

SiteViewer build_site_viewer(Project& p, const std::string& dir, const SiteViewerOptions& o) {
  const std::string three_js = viewer_three_js();  // read first: a missing package is refused before the slow part
  SiteSceneOptions options;
  options.max_layer_faces = o.max_faces;
  options.command = o.command;
  options.only_layer = o.layer;
  const SiteScene site = build_site_scene(p, dir, options);
  const SiteInfo info = p.site();
  ExportFrame frame;
  frame.site_origin = info.origin;
  frame.crs = info.crs;
  const ViewerModels models = viewer_models(site, o.coarse_lod, frame, o.command);
  const std::string title =
      std::filesystem::path(dir).filename().string() + (o.layer.empty() ? "" : " layer " + o.layer);
  SiteViewer out;
  out.html = viewer_page(title, info.crs, three_js, models);
  out.first_bytes = models.first.size();
  out.detail_bytes = models.detail.size();
  out.layers = site.layers;
  out.units = site.units;
  out.markers = site.markers;
  out.finds = site.finds;
  out.cameras = site.cameras;
  return out;
}

}  // namespace strata
