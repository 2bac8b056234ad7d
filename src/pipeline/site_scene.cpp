// The site model's glTF scene, shared by `export model` and `export viewer`.
#include "pipeline/site_scene.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "dense/dense_mesh.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/products_layer.hpp"
#include "project/find_records.hpp"
#include "project/records.hpp"
#include "volume/finds.hpp"
#include "volume/site_volumes.hpp"
#include "volume/volume.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace strata {

void SiteScene::add_mesh(std::string name, DenseMesh mesh, std::optional<std::array<double, 4>> colour,
                         std::string extras_json, std::optional<MeshTexture> texture) {
  meshes.push_back(std::move(mesh));
  GltfMesh gm{name, &meshes.back(), colour};
  if (texture) {
    textures.push_back(std::move(*texture));
    gm.texture = &textures.back();
  }
  scene.meshes.push_back(std::move(gm));
  GltfNode n;
  n.name = std::move(name);
  n.mesh = int(scene.meshes.size()) - 1;
  n.extras_json = std::move(extras_json);
  scene.nodes.push_back(std::move(n));
}

TexturedModel texture_layer_mesh(const std::vector<OrthoView>& views, const DenseMesh& mesh, const ModelTextureArgs& t,
                                 const std::string& layer) {
  TextureOptions o;
  o.atlas_size_px = t.atlas_size_px;
  o.colour_balance = t.colour_gains;
  TextureSummary s;
  TexturedModel out;
  out.textured = build_texture_atlas(mesh, views, o, &s);
  out.texture.uv = out.textured.uv;
  out.texture.face_image = out.textured.face_atlas;
  out.texture.mime_type = t.jpeg_quality > 0 ? "image/jpeg" : "image/png";
  for (const TextureImage& im : out.textured.atlases) out.texture.images.push_back(encode_texture_image(im, t.jpeg_quality));
  log::info("layer {}: texture: {} of {} faces from {} of {} photos, {} charts in {} atlas(es) of {} px, {:.2f} texels "
            "per photo pixel, median texel {:.2f} mm, seams on {:.1f} % of edges, {:.1f} s",
            layer, s.textured_faces, s.faces, s.views_used, s.views, s.charts, s.atlases, o.atlas_size_px,
            s.texel_scale, 1000 * s.median_texel_m, 100 * s.seam_fraction, s.seconds);
  if (o.colour_balance && !s.gains.empty()) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (const auto& g : s.gains) {
      lo = std::min({lo, g[0], g[1], g[2]});
      hi = std::max({hi, g[0], g[1], g[2]});
    }
    log::info("layer {}: texture: colour gains {:.3f}-{:.3f} fitted on {} overlaps; RMS of log colour ratios between "
              "photos {:.3f} before, {:.3f} after", layer, lo, hi, s.balance_overlaps, s.balance_rms_before,
              s.balance_rms_after);
  }
  return out;
}

// The file of a product the dense stage recorded, refused when it has gone or changed
// since (an export must not pass off another file as the layer's).
std::filesystem::path checked_product_file(Project& p, const LayerRecord& l, const ProductRecord& product,
                                           const std::string& dir) {
  const auto src = p.dir() / product.path;
  if (!std::filesystem::exists(src) || sha256_file(src) != product.sha256) {
    throw IoError(fmt::format("{}: missing or changed since it was recorded; rerun 'strata process {} --layer "
                              "{} --force'", src.string(), dir, l.name));
  }
  return src;
}

// The dense stage's PLY holds site CRS coordinates (double) or site-frame floats with
// their offset in a comment; the glTF writer takes the site frame.
DenseMesh site_frame_mesh(PlyContents ply, const Eigen::Vector3d& site_origin) {
  const Eigen::Vector3d shift = (ply.has_offset_comment ? ply.offset : Eigen::Vector3d::Zero()) - site_origin;
  for (auto& v : ply.mesh.vertices) v += shift;
  return std::move(ply.mesh);
}

void check_level_of_detail(int lod) {
  if (lod < 0) {
    throw InputError(fmt::format("--lod {}: a level of detail is 0 (the full mesh) or more (N: about faces / 4^N)", lod));
  }
}

// A level that ends above this multiple of its target is reported: the edge collapse
// stops when no edge can be collapsed without breaking the surface's topology.
constexpr double kLevelOfDetailSlack = 1.25;

DenseMesh layer_mesh_at_level(DenseMesh mesh, int lod, const std::string& layer, const std::string& command) {
  check_level_of_detail(lod);
  if (lod == 0) return mesh;
  const std::size_t faces = mesh.faces.size();
  std::size_t target = faces;
  int highest = 0;  // the highest level that keeps kMinLevelOfDetailFaces
  for (int k = 1; k <= lod && target >= kMinLevelOfDetailFaces; ++k) target /= 4;
  for (std::size_t t = faces / 4; t >= kMinLevelOfDetailFaces; t /= 4) ++highest;
  if (target < kMinLevelOfDetailFaces) {
    throw InputError(fmt::format("--lod {}: layer {} has {} faces, level {} would leave fewer than {} (the highest "
                                 "level for this layer is {})", lod, layer, faces, lod, kMinLevelOfDetailFaces,
                                 highest));
  }
  DenseMesh simplified = simplify_mesh(mesh, target);
  if (double(simplified.faces.size()) > kLevelOfDetailSlack * double(target)) {
    log::warn("{}: layer {}: level of detail {} stopped at {} faces, {:.1f} x its target {}: the edge collapse "
              "cannot shrink the mesh's small separate pieces and borders further", command, layer, lod,
              simplified.faces.size(), double(simplified.faces.size()) / double(target), target);
  }
  log::info("{}: layer {}: level of detail {}: {} faces (of {}; target faces / 4^{} = {})", command, layer, lod,
            simplified.faces.size(), faces, lod, target);
  return simplified;
}

namespace {

// A distinct colour per unit, the same on every export of the same units: hues a golden
// angle apart in the units' order (so neighbouring units differ most), as glTF's linear
// RGBA; the alpha lets the layer surfaces show through the solids.
std::array<double, 4> unit_colour(std::size_t index) {
  constexpr double kGoldenAngleDeg = 137.50776405;
  constexpr double kSaturation = 0.7, kValue = 0.9, kAlpha = 0.45;
  const double h = std::fmod(double(index) * kGoldenAngleDeg, 360.0) / 60.0;  // sextant of the HSV hexcone
  const double c = kValue * kSaturation, x = c * (1 - std::abs(std::fmod(h, 2.0) - 1)), m = kValue - c;
  const std::array<std::array<double, 3>, 6> sextants = {
      {{c, x, 0}, {x, c, 0}, {0, c, x}, {0, x, c}, {x, 0, c}, {c, 0, x}}};
  std::array<double, 4> rgba{0, 0, 0, kAlpha};
  for (int k = 0; k < 3; ++k) {
    rgba[k] = srgb_to_linear(sextants[std::size_t(h) % 6][k] + m);
  }
  return rgba;
}

// The photos a layer mesh is textured from: its aligned photos, or none (with a warning)
// when the layer has no alignment.
std::vector<OrthoView> texture_views(Project& p, const LayerRecord& l, const std::string& command) {
  if (!load_alignment(p.db(), l)) {
    log::warn("{}: layer {} has no aligned photos (a range-scan layer?): vertex colours, not textured", command, l.name);
    return {};
  }
  return layer_ortho_views(p, l.name);
}

// Faces a mesh is simplified to for the options: faces / 4^lod and at most max_layer_faces;
// never below kMinLevelOfDetailFaces, nor above the faces it has.
std::size_t simplified_faces(std::size_t faces, const SiteSceneOptions& options) {
  std::size_t target = faces;
  for (int k = 0; k < options.lod; ++k) target /= 4;
  if (options.max_layer_faces > 0) target = std::min(target, options.max_layer_faces);
  return std::min(faces, std::max(target, kMinLevelOfDetailFaces));
}

// Every layer's dense mesh, top layer first, simplified when larger than the options allow,
// textured from its photos when asked.
void add_layer_meshes(Project& p, const std::vector<LayerRecord>& layers, const std::string& dir,
                      const SiteSceneOptions& options, SiteScene& site) {
  const Eigen::Vector3d origin = p.site().origin;
  for (const auto& l : layers) {
    const auto product = find_product(p.db(), l.id, "mesh");
    if (!product) {
      log::warn("{}: layer {} has no dense mesh yet: left out", options.command, l.name);
      continue;
    }
    DenseMesh mesh = layer_mesh_at_level(site_frame_mesh(read_ply(checked_product_file(p, l, *product, dir)), origin),
                                         options.lod, l.name, options.command);
    if (options.max_layer_faces > 0 && mesh.faces.size() > options.max_layer_faces) {
      log::info("{}: layer {}: {} faces simplified to at most {}", options.command, l.name,
                mesh.faces.size(), options.max_layer_faces);
      mesh = simplify_mesh(mesh, options.max_layer_faces);
    }
    const std::string name = "layer " + l.name;
    const std::vector<OrthoView> views = options.texture ? texture_views(p, l, options.command) : std::vector<OrthoView>{};
    if (!views.empty()) {
      TexturedModel t = texture_layer_mesh(views, mesh, *options.texture, l.name);
      site.add_mesh(name, std::move(t.textured.mesh), std::nullopt, "", std::move(t.texture));
      ++site.textured_layers;
    } else {
      site.add_mesh(name, std::move(mesh), std::nullopt);
    }
    ++site.layers;
  }
}

// The unit solids as `strata volume` computes them (default options, the kept trench
// outline). load_site_model writes only when given a new outline file, which the
// default options never are: the export stays read-only.
void add_unit_solids(Project& p, const std::vector<LayerRecord>& layers, const SiteSceneOptions& options,
                     SiteScene& site) {
  const std::string& command = options.command;
  const auto with_surface = std::count_if(layers.begin(), layers.end(), [&](const LayerRecord& l) {
    return find_product(p.db(), l.id, "surface") || find_product(p.db(), l.id, "dtm");
  });
  if (with_surface < 2) {
    log::warn("{}: {} layer(s) have a surface; unit solids need two: none in the model", command, with_surface);
    return;
  }
  const SiteModel model = load_site_model(p, SiteVolumeOptions{});
  for (std::size_t i = 0; i < model.solids.size(); ++i) {
    const UnitSolid& s = model.solids[i];
    DenseMesh mesh = unit_solid_mesh(s);
    if (mesh.faces.empty()) continue;  // a unit dug nowhere on the grid
    // Flat tops and walls of grid cells collapse well; the edge collapse keeps the solid closed.
    const std::size_t target = simplified_faces(mesh.faces.size(), options);
    if (target < mesh.faces.size()) {
      const std::size_t before = mesh.faces.size();
      mesh = simplify_mesh(mesh, target);
      log::info("{}: unit {}: solid of {} faces simplified to {}", command, s.unit, before, mesh.faces.size());
    }
    const nlohmann::ordered_json extras = {{"unit", s.unit},
                                           {"volume_m3", s.measures.volume_m3},
                                           {"interval_m3", {s.measures.interval_low_m3, s.measures.interval_high_m3}}};
    site.add_mesh("unit " + s.unit, std::move(mesh), unit_colour(i), extras.dump());
    ++site.units;
  }
}

void add_markers(Project& p, SiteScene& site) {
  const Eigen::Vector3d origin = p.site().origin;
  for (const auto& m : list_markers(p.db())) {
    GltfNode n;
    n.name = "marker " + m.name;
    n.position = m.position - origin;
    n.extras_json = nlohmann::ordered_json{{"marker", m.name},
                                           {"kind", m.kind},
                                           {"site_crs", {m.position.x(), m.position.y(), m.position.z()}}}
                        .dump();
    site.scene.nodes.push_back(std::move(n));
    ++site.markers;
  }
}

// The finds at their surveyed points, with their record and, when `strata volume` has
// written the voxel model, the unit whose solid holds each one (as `strata finds`).
void add_finds(Project& p, const std::string& command, SiteScene& site) {
  const std::vector<FindRecord> finds = list_finds(p.db());
  if (finds.empty()) return;
  std::vector<FindPlacement> placed;
  bool checked = true;
  try {
    placed = check_project_finds(p, FindCheckOptions{}).finds;
  } catch (const InputError& e) {  // no voxel model yet: the record alone
    log::info("{}: finds without their geometric unit ({})", command, e.what());
    checked = false;
    for (const FindRecord& f : finds) placed.push_back({f, std::nullopt, std::nullopt, false});
  }
  const Eigen::Vector3d origin = p.site().origin;
  for (const FindPlacement& pl : placed) {
    const FindRecord& f = pl.find;
    GltfNode n;
    n.name = "find " + f.id;
    n.position = f.position - origin;
    nlohmann::ordered_json extras = {{"find", f.id},
                                     {"recorded_unit", f.unit},
                                     {"type", f.type},
                                     {"description", f.description},
                                     {"site_crs", {f.position.x(), f.position.y(), f.position.z()}}};
    if (checked) {
      extras["geometric_unit"] = pl.geometric_unit ? nlohmann::ordered_json(*pl.geometric_unit) : nullptr;
      extras["distance_m"] = pl.distance_m ? nlohmann::ordered_json(*pl.distance_m) : nullptr;
      extras["conflict"] = pl.conflict;
    }
    n.extras_json = extras.dump();
    site.scene.nodes.push_back(std::move(n));
    ++site.finds;
  }
}

// The registered photos of every georeferenced layer, top layer first.
void add_cameras(Project& p, const std::vector<LayerRecord>& layers, const std::string& command, SiteScene& site) {
  for (const auto& l : layers) {
    const auto a = load_alignment(p.db(), l);
    if (!a) continue;
    if (!a->rec.georeferenced) {
      log::warn("{}: layer {} is aligned but not georeferenced: its cameras are left out", command, l.name);
      continue;
    }
    for (const auto& img : a->rec.images) {
      if (!img.registered) continue;
      GltfNode n = gltf_camera_node(fmt::format("camera {}/{}", l.name, img.name), img.pose,
                                    a->rec.groups.at(std::size_t(img.group)).intrinsics);
      n.extras_json = nlohmann::ordered_json{{"layer", l.name}, {"image", img.name}}.dump();
      site.scene.nodes.push_back(std::move(n));
      ++site.cameras;
    }
  }
}

}  // namespace

SiteScene build_site_scene(Project& p, const std::string& dir, const SiteSceneOptions& options) {
  const std::vector<LayerRecord> layers = options.only_layer.empty()
                                              ? capture_order(list_layers(p.db()))
                                              : std::vector<LayerRecord>{require_layer(p.db(), options.only_layer)};
  // Refused before any warning about single layers: the error stays one line.
  if (std::none_of(layers.begin(), layers.end(), [&](const LayerRecord& l) { return find_product(p.db(), l.id, "mesh"); })) {
    throw InputError(fmt::format("{}: no layer of {} has a dense mesh yet; run 'strata process {} --layer L "
                                 "--until dense' first", options.command, dir, dir));
  }
  SiteScene site;
  add_layer_meshes(p, layers, dir, options, site);
  if (options.only_layer.empty()) add_unit_solids(p, layers, options, site);
  add_markers(p, site);
  add_finds(p, options.command, site);
  add_cameras(p, layers, options.command, site);
  return site;
}

}  // namespace strata
