// strata export ...
#include "cli/commands.hpp"
#include "cli/site_scene.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "exporters/cameras/camera_export.hpp"
#include "exporters/gltf/gltf_writer.hpp"
#include "exporters/mesh/mesh_writers.hpp"
#include "geometry/mesh.hpp"
#include "importers/mesh/ply_mesh.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/products_layer.hpp"
#include "products/texture_atlas.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <memory>
#include <optional>

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

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

// The whole site in one .glb: layer meshes (at level of detail `lod`), unit solids,
// markers, cameras.
void export_site_model(const std::string& dir, const std::string& out, int lod) {
  Project p = Project::open(dir);
  SiteSceneOptions options;
  options.lod = lod;
  const SiteScene site = build_site_scene(p, dir, options);
  const SiteInfo info = p.site();
  ExportFrame frame;
  frame.site_origin = info.origin;
  frame.crs = info.crs;
  write_glb(out, site.scene, frame);
  log::info("wrote {} ({} layers, {} units, {} markers, {} cameras)", out, site.layers, site.units, site.markers,
            site.cameras);
}

struct TextureArgs {
  bool texture = false;
  int jpeg_quality = 90;  // 0: PNG
  int atlas_size_px = 4096;
};

// The layer mesh textured from its aligned photos (products.texture), as the model
// writers take it.
struct TexturedModel {
  TexturedMesh textured;
  MeshTexture texture;
};

TexturedModel texture_layer_mesh(Project& p, const std::string& layer, const DenseMesh& mesh, const TextureArgs& t) {
  TextureOptions o;
  o.atlas_size_px = t.atlas_size_px;
  TextureSummary s;
  TexturedModel out;
  out.textured = build_texture_atlas(mesh, layer_ortho_views(p, layer), o, &s);
  out.texture.uv = out.textured.uv;
  out.texture.face_image = out.textured.face_atlas;
  out.texture.mime_type = t.jpeg_quality > 0 ? "image/jpeg" : "image/png";
  for (const TextureImage& im : out.textured.atlases) out.texture.images.push_back(encode_texture_image(im, t.jpeg_quality));
  log::info("texture: {} of {} faces from {} of {} photos, {} charts in {} atlas(es) of {} px, {:.2f} texels per photo "
            "pixel, median texel {:.2f} mm, seams on {:.1f} % of edges, {:.1f} s",
            s.textured_faces, s.faces, s.views_used, s.views, s.charts, s.atlases, o.atlas_size_px, s.texel_scale,
            1000 * s.median_texel_m, 100 * s.seam_fraction, s.seconds);
  return out;
}

// The file formats of `export model`, by the extension of --out.
enum class ModelFormat { glb, obj };

ModelFormat model_format(const std::string& out) {
  const std::string ext = lower_extension(out);
  if (ext == ".glb") return ModelFormat::glb;
  if (ext == ".obj") return ModelFormat::obj;
  throw InputError(fmt::format("--out {}: export model writes glTF binary (.glb) or Wavefront OBJ (.obj) "
                               "(the plain mesh as PLY: 'strata export mesh')", out));
}

// One layer's mesh (`mesh`, site frame) as .glb or .obj, textured or vertex-coloured.
void write_layer_model(Project& p, const std::string& layer, const DenseMesh& mesh, const std::string& out,
                       ModelFormat format, const TextureArgs& t) {
  const SiteInfo site = p.site();
  ExportFrame frame;
  frame.site_origin = site.origin;
  frame.crs = site.crs;
  std::optional<TexturedModel> tex;
  if (t.texture) tex = texture_layer_mesh(p, layer, mesh, t);
  const DenseMesh& written = tex ? tex->textured.mesh : mesh;
  const MeshTexture* texture = tex ? &tex->texture : nullptr;
  const std::string what = fmt::format("{} vertices, {} faces{}", written.vertices.size(), written.faces.size(),
                                       tex ? ", textured" : "");
  if (format == ModelFormat::obj) {
    const ObjModelFiles files = write_obj_model(out, written, frame, texture);
    log::info("wrote {} ({}; local origin E {:.0f} N {:.0f} Z {:.0f}, x = E, y = N, z = up){}", out, what,
              files.origin.x(), files.origin.y(), files.origin.z(),
              files.mtl.empty() ? "" : fmt::format(", {} and {} atlas image(s)", files.mtl.string(), files.images.size()));
    return;
  }
  GltfMesh gm{layer, &written};
  gm.texture = texture;
  write_glb(out, std::span<const GltfMesh>(&gm, 1), frame);
  log::info("wrote {} ({})", out, what);
}

void register_model_command(CLI::App& exp) {
  auto* cmd = exp.add_subcommand(
      "model",
      "the site or one layer as a 3D model for viewers (Blender, MeshLab, three.js, Cesium):\n"
      "a glTF 2.0 binary (.glb), or for one layer Wavefront OBJ (.obj, below). glTF stores\n"
      "float32 and is Y-up: vertices are written relative to a local origin (the\n"
      "bounding-box centre of everything in the file, in site CRS\n"
      "coordinates, rounded to whole metres), which is the mesh nodes' translation, so\n"
      "millimetres survive at UTM coordinates. Axes: glTF x = E, y = Z (up), z = -N. The CRS,\n"
      "the origin [E, N, Z] and the axes are in asset.extras.\n"
      "Without --layer: the site model, top of the stratigraphy first: every layer's dense mesh\n"
      "(nodes 'layer L', vertex colours), the unit solids as closed meshes as 'strata volume'\n"
      "computes them (nodes 'unit U', one translucent colour each, volume_m3 and interval_m3\n"
      "in extras), the surveyed markers (nodes 'marker M') and every layer's aligned cameras\n"
      "(nodes 'camera L/IMAGE' with a glTF perspective camera). Reads the project only.\n"
      "With --layer L: that layer's dense mesh alone, its vertex colours and normals.\n"
      "--texture (with --layer): the mesh textured from the layer's aligned photos instead of\n"
      "vertex colours: each face from its best unoccluded photo, packed into square atlases\n"
      "embedded as JPEG (docs/model.md, Textures).\n"
      "--lod N: level of detail, each layer mesh simplified to about faces / 4^N (0: the fused\n"
      "mesh; colours and normals kept; refused when fewer than 100 faces would remain).\n"
      "--out FILE.obj (with --layer): Wavefront OBJ relative to the same local origin, in the\n"
      "site's axes (x = E, y = N, z = up; origin, CRS and axes in the comment lines at the top):\n"
      "'v x y z r g b' vertex colours and vn normals, or with --texture vt, FILE.mtl and the\n"
      "atlases as FILE_atlasK.jpg (.png with --jpeg-quality 0) beside it.\n"
      "Not yet: textures in the site model, the site model as OBJ.\n"
      "Needs the layers' dense meshes ('strata process DIR --layer L --until dense').");
  const auto a = add_layer_export_options(cmd, "output file, .glb or .obj", "the layer (default: the whole site)");
  const auto lod = std::make_shared<int>(0);
  cmd->add_option("--lod", *lod, "level of detail: 0 the fused mesh, N about faces / 4^N")->capture_default_str();
  const auto t = std::make_shared<TextureArgs>();
  cmd->add_flag("--texture", t->texture, "texture the layer mesh from its photos (needs --layer and the aligned photos)");
  cmd->add_option("--jpeg-quality", t->jpeg_quality, "atlas JPEG quality, 1-100; 0 writes PNG (lossless, larger)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  cmd->add_option("--atlas-size", t->atlas_size_px, "side of a square texture atlas, texels (64-16384)")
      ->check(CLI::Range(64, 16384))
      ->capture_default_str();
  cmd->callback([=] {
    check_level_of_detail(*lod);
    const ModelFormat format = model_format(a->out);
    if (a->layer.empty()) {
      if (t->texture) throw InputError("--texture needs --layer: the site model is not textured yet");
      if (format == ModelFormat::obj) {
        throw InputError(fmt::format("--out {}: OBJ holds one layer's mesh, give --layer; the site model (unit "
                                     "solids, markers, cameras) is written as .glb", a->out));
      }
      export_site_model(a->dir, a->out, *lod);
      return;
    }
    Project p = Project::open(a->dir);
    const LayerRecord l = require_layer(p.db(), a->layer);
    const auto product = find_product(p.db(), l.id, "mesh");
    if (!product) {
      throw InputError(fmt::format("layer {} has no dense mesh yet; run 'strata process {} --layer {} --until dense'",
                                   l.name, a->dir, l.name));
    }
    const DenseMesh mesh = layer_mesh_at_level(
        site_frame_mesh(read_ply(checked_product_file(p, l, *product, a->dir)), p.site().origin), *lod, l.name,
        "export model");
    write_layer_model(p, l.name, mesh, a->out, format, *t);
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
      copy_atomically(src, a->out, "export", "export.copy.temp_written");
      log::info("wrote {}", a->out);
    });
  }
  register_model_command(*exp);
  register_viewer_command(*exp);
}

}  // namespace strata::cli
