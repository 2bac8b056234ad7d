// strata export ...
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "dense/dense_mesh.hpp"
#include "exporters/cameras/camera_export.hpp"
#include "exporters/gltf/gltf_writer.hpp"
#include "pipeline/alignment_store.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "volume/site_volumes.hpp"
#include "volume/volume.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <deque>
#include <memory>

namespace strata::cli {
namespace {

// What every per-layer export takes: the project, the layer, where to write.
struct LayerExportArgs {
  std::string dir, layer, out;
};

std::shared_ptr<LayerExportArgs> add_layer_export_options(CLI::App* cmd, const std::string& out_help,
                                                          const std::string& layer_help = "") {
  auto a = std::make_shared<LayerExportArgs>();
  cmd->add_option("DIR", a->dir, "project folder")->required();
  auto* layer = cmd->add_option("--layer", a->layer, layer_help.empty() ? "the layer" : layer_help);
  if (layer_help.empty()) layer->required();
  cmd->add_option("--out", a->out, out_help)->required();
  return a;
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

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

// The site model under construction: the scene and the meshes it points to (a deque:
// adding a mesh must not move the others).
struct SiteScene {
  std::deque<DenseMesh> meshes;
  GltfScene scene;

  void add_mesh(std::string name, DenseMesh mesh, std::optional<std::array<double, 4>> colour,
                std::string extras_json = "") {
    meshes.push_back(std::move(mesh));
    scene.meshes.push_back({name, &meshes.back(), colour});
    GltfNode n;
    n.name = std::move(name);
    n.mesh = int(scene.meshes.size()) - 1;
    n.extras_json = std::move(extras_json);
    scene.nodes.push_back(std::move(n));
  }
};

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

// Every layer's dense mesh, top layer first; the number added.
int add_layer_meshes(Project& p, const std::vector<LayerRecord>& layers, const std::string& dir, SiteScene& site) {
  const Eigen::Vector3d origin = p.site().origin;
  int added = 0;
  for (const auto& l : layers) {
    const auto product = find_product(p.db(), l.id, "mesh");
    if (!product) {
      log::warn("export model: layer {} has no dense mesh yet: left out", l.name);
      continue;
    }
    site.add_mesh("layer " + l.name, site_frame_mesh(read_ply(checked_product_file(p, l, *product, dir)), origin),
                  std::nullopt);
    ++added;
  }
  return added;
}

// The unit solids as `strata volume` computes them (default options, the kept trench
// outline). load_site_model writes only when given a new outline file, which the
// default options never are: the export stays read-only.
void add_unit_solids(Project& p, const std::vector<LayerRecord>& layers, SiteScene& site) {
  const auto with_surface = std::count_if(layers.begin(), layers.end(), [&](const LayerRecord& l) {
    return find_product(p.db(), l.id, "surface") || find_product(p.db(), l.id, "dtm");
  });
  if (with_surface < 2) {
    log::warn("export model: {} layer(s) have a surface; unit solids need two: none in the model", with_surface);
    return;
  }
  const SiteModel model = load_site_model(p, SiteVolumeOptions{});
  for (std::size_t i = 0; i < model.solids.size(); ++i) {
    const UnitSolid& s = model.solids[i];
    DenseMesh mesh = unit_solid_mesh(s);
    if (mesh.faces.empty()) continue;  // a unit dug nowhere on the grid
    const nlohmann::ordered_json extras = {{"unit", s.unit},
                                           {"volume_m3", s.measures.volume_m3},
                                           {"interval_m3", {s.measures.interval_low_m3, s.measures.interval_high_m3}}};
    site.add_mesh("unit " + s.unit, std::move(mesh), unit_colour(i), extras.dump());
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
  }
}

// The registered photos of every georeferenced layer, top layer first.
void add_cameras(Project& p, const std::vector<LayerRecord>& layers, SiteScene& site) {
  for (const auto& l : layers) {
    const auto a = load_alignment(p.db(), l);
    if (!a) continue;
    if (!a->rec.georeferenced) {
      log::warn("export model: layer {} is aligned but not georeferenced: its cameras are left out", l.name);
      continue;
    }
    for (const auto& img : a->rec.images) {
      if (!img.registered) continue;
      GltfNode n = gltf_camera_node(fmt::format("camera {}/{}", l.name, img.name), img.pose,
                                    a->rec.groups.at(std::size_t(img.group)).intrinsics);
      n.extras_json = nlohmann::ordered_json{{"layer", l.name}, {"image", img.name}}.dump();
      site.scene.nodes.push_back(std::move(n));
    }
  }
}

// The whole site in one .glb: layer meshes, unit solids, markers, cameras.
void export_site_model(const std::string& dir, const std::string& out) {
  Project p = Project::open(dir);
  const std::vector<LayerRecord> layers = capture_order(list_layers(p.db()));
  // Refused before any warning about single layers: the error stays one line.
  if (std::none_of(layers.begin(), layers.end(), [&](const LayerRecord& l) { return find_product(p.db(), l.id, "mesh"); })) {
    throw InputError(fmt::format("export model: no layer of {} has a dense mesh yet; run 'strata process {} --layer L "
                                 "--until dense' first", dir, dir));
  }
  SiteScene site;
  const std::size_t n_layers = std::size_t(add_layer_meshes(p, layers, dir, site));
  add_unit_solids(p, layers, site);
  const std::size_t n_units = site.scene.nodes.size() - n_layers;
  add_markers(p, site);
  const std::size_t n_markers = site.scene.nodes.size() - n_layers - n_units;
  add_cameras(p, layers, site);
  const SiteInfo info = p.site();
  ExportFrame frame;
  frame.site_origin = info.origin;
  frame.crs = info.crs;
  write_glb(out, site.scene, frame);
  log::info("wrote {} ({} layers, {} units, {} markers, {} cameras)", out, n_layers, n_units, n_markers,
            site.scene.nodes.size() - n_layers - n_units - n_markers);
}

void register_model_command(CLI::App& exp) {
  auto* cmd = exp.add_subcommand(
      "model",
      "the site or one layer as a 3D model for viewers (Blender, MeshLab, three.js, Cesium):\n"
      "a glTF 2.0 binary (.glb). glTF stores float32 and is Y-up: vertices are written relative\n"
      "to a local origin (the bounding-box centre of everything in the file, in site CRS\n"
      "coordinates, rounded to whole metres), which is the mesh nodes' translation, so\n"
      "millimetres survive at UTM coordinates. Axes: glTF x = E, y = Z (up), z = -N. The CRS,\n"
      "the origin [E, N, Z] and the axes are in asset.extras.\n"
      "Without --layer: the site model, top of the stratigraphy first: every layer's dense mesh\n"
      "(nodes 'layer L', vertex colours), the unit solids as closed meshes as 'strata volume'\n"
      "computes them (nodes 'unit U', one translucent colour each, volume_m3 and interval_m3\n"
      "in extras), the surveyed markers (nodes 'marker M') and every layer's aligned cameras\n"
      "(nodes 'camera L/IMAGE' with a glTF perspective camera). Reads the project only.\n"
      "With --layer L: that layer's dense mesh alone, its vertex colours and normals.\n"
      "Not yet: photo textures, levels of detail.\n"
      "Needs the layers' dense meshes ('strata process DIR --layer L --until dense').");
  const auto a = add_layer_export_options(cmd, "output file, .glb", "the layer (default: the whole site)");
  cmd->callback([=] {
    if (lower_extension(a->out) != ".glb") {
      throw InputError(fmt::format("--out {}: export model writes glTF binary (.glb) only so far; OBJ comes later "
                                   "(the plain mesh as PLY: 'strata export mesh')", a->out));
    }
    if (a->layer.empty()) {
      export_site_model(a->dir, a->out);
      return;
    }
    Project p = Project::open(a->dir);
    const LayerRecord l = require_layer(p.db(), a->layer);
    const auto product = find_product(p.db(), l.id, "mesh");
    if (!product) {
      throw InputError(fmt::format("layer {} has no dense mesh yet; run 'strata process {} --layer {} --until dense'",
                                   l.name, a->dir, l.name));
    }
    const SiteInfo site = p.site();
    const DenseMesh mesh = site_frame_mesh(read_ply(checked_product_file(p, l, *product, a->dir)), site.origin);
    ExportFrame frame;
    frame.site_origin = site.origin;
    frame.crs = site.crs;
    const GltfMesh meshes[] = {{l.name, &mesh}};
    write_glb(a->out, meshes, frame);
    log::info("wrote {} ({} vertices, {} faces)", a->out, mesh.vertices.size(), mesh.faces.size());
  });
}

}  // namespace

void register_export_commands(CLI::App& app) {
  auto* exp = app.add_subcommand("export", "write products for other tools (GIS, CAD, photogrammetry)");
  exp->require_subcommand(1);
  {
    auto* cmd = exp->add_subcommand(
        "cameras",
        "aligned cameras of a layer. csv: one row per photo with the header\n"
        "image,fx,fy,ppx,ppy,k1,k2,r11,...,r33,X,Y,Z (pixels, world-to-camera rotation, camera\n"
        "centre in site CRS coordinates; the brown and fisheye terms k3, k4, p1, p2 are not in it).\n"
        "csv-lens: the same with the lens model and all its terms:\n"
        "image,model,fx,fy,ppx,ppy,k1,k2,k3,k4,p1,p2,r11,...,r33,X,Y,Z.\n"
        "colmap: a COLMAP text model (cameras.txt, images.txt,\n"
        "points3D.txt) in the site frame, to continue in COLMAP or OpenMVS.");
    const auto args = add_layer_export_options(cmd, "output file (csv) or folder (colmap)");
    auto format = std::make_shared<std::string>("csv");
    cmd->add_option("--format", *format, "csv (default), csv-lens or colmap")
        ->check(CLI::IsMember({"csv", "csv-lens", "colmap"}));
    cmd->callback([=] {
      Project p = Project::open(args->dir);
      const LayerRecord l = require_layer(p.db(), args->layer);
      const auto a = load_alignment(p.db(), l);
      if (!a) throw InputError(fmt::format("layer {} is not aligned yet; run 'strata process {} --layer {}'",
                                           l.name, args->dir, l.name));
      const SiteInfo site = p.site();
      if (*format == "csv") {
        write_cameras_csv(a->rec, site.origin, args->out);
        for (const auto& g : a->rec.groups) {
          if (g.intrinsics.model != CameraModel::radial) {
            log::warn("layer {}: its {} lens terms (k3, k4, p1, p2) are not in the csv format; "
                      "--format csv-lens has them", l.name, to_string(g.intrinsics.model));
            break;
          }
        }
      } else if (*format == "csv-lens") {
        write_cameras_lens_csv(a->rec, site.origin, args->out);
      } else {
        write_colmap_model(a->rec, args->out);
      }
      log::info("wrote {}", args->out);
    });
  }
  // Products the dense stage already wrote (double-precision site CRS vertices):
  // exported by copy, after checking the file still matches its recorded checksum.
  const std::pair<const char*, const char*> copies[] = {
      {"mesh", "the layer's triangle mesh (PLY; .obj when the dense stage wrote one), site CRS coordinates"},
      {"points", "the layer's coloured dense point cloud (PLY), site CRS coordinates"}};
  for (const auto& [kind_c, help] : copies) {
    const std::string kind = kind_c;
    auto* cmd = exp->add_subcommand(kind, help);
    const auto a = add_layer_export_options(cmd, "output file");
    cmd->callback([=] {
      Project p = Project::open(a->dir);
      const LayerRecord l = require_layer(p.db(), a->layer);
      const bool obj = std::filesystem::path(a->out).extension() == ".obj";
      auto product = find_product(p.db(), l.id, obj ? "mesh_obj" : kind);
      if (!product) {
        throw InputError(fmt::format("layer {} has no {} yet; run 'strata process {} --layer {} --until dense'{}",
                                     l.name, obj ? "OBJ mesh" : kind, a->dir, l.name,
                                     obj ? " (OBJ meshes need the dense stage's OBJ option)" : ""));
      }
      const auto src = checked_product_file(p, l, *product, a->dir);
      const std::string tmp = a->out + ".tmp";
      std::filesystem::copy_file(src, tmp, std::filesystem::copy_options::overwrite_existing);
      fault::point("export.copy.temp_written");
      std::filesystem::rename(tmp, a->out);
      log::info("wrote {}", a->out);
    });
  }
  register_model_command(*exp);
}

}  // namespace strata::cli
