// strata export ...
#include "cli/commands.hpp"
#include "pipeline/site_scene.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "exporters/cameras/camera_export.hpp"
#include "exporters/gltf/gltf_writer.hpp"
#include "exporters/mesh/mesh_writers.hpp"
#include "geometry/mesh.hpp"
#include "importers/mesh/ply_mesh.hpp"
#include "importers/vector/outline.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/products_layer.hpp"
#include "products/model_check.hpp"
#include "products/texture_atlas.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "volume/site_volumes.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <memory>
#include <optional>

namespace strata::cli {
namespace {

namespace fs = std::filesystem;

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

struct TextureArgs : ModelTextureArgs {
  bool texture = false;
};

// The whole site in one .glb: layer meshes (at level of detail `lod`, textured when
// asked), unit solids, markers, finds, cameras.
void export_site_model(const std::string& dir, const std::string& out, int lod, const TextureArgs& t) {
  Project p = Project::open(dir);
  SiteSceneOptions options;
  options.lod = lod;
  if (t.texture) options.texture = t;
  const SiteScene site = build_site_scene(p, dir, options);
  const SiteInfo info = p.site();
  ExportFrame frame;
  frame.site_origin = info.origin;
  frame.crs = info.crs;
  write_glb(out, site.scene, frame);
  log::info("wrote {} ({} layers{}, {} units, {} markers, {} finds, {} cameras)", out, site.layers,
            t.texture ? fmt::format(" of which {} textured", site.textured_layers) : "", site.units, site.markers,
            site.finds, site.cameras);
}

// --check-photos: the textured model rendered from some of its own photos' cameras
// and compared with them (products.model_check).
struct CheckArgs {
  int photos = 0;          // photos to render from, spread over the layer's; 0: no check
  double scale = 1.0;      // rendered pixels per photo pixel
  std::string outline;     // FILE: trench outline (default: the one 'strata volume --outline' kept)
  std::string images_dir;  // DIR: rendered and difference images as PNG
  bool json = false;
};

// `n` of `views` (their indices), spread evenly over the set (the middle of n equal slices).
std::vector<int> spread_views(const std::vector<OrthoView>& views, int n) {
  std::vector<int> out;
  const std::size_t count = std::min(views.size(), std::size_t(n));
  for (std::size_t k = 0; k < count; ++k) out.push_back(int((2 * k + 1) * views.size() / (2 * count)));
  return out;
}

std::vector<Eigen::Vector2d> check_region(Project& p, const CheckArgs& c) {
  const fs::path kept = p.dir() / kTrenchOutlineFile;
  if (!c.outline.empty()) return read_outline(c.outline, p.site(), "--check-outline");
  if (fs::exists(kept)) return read_outline(kept, p.site(), "the kept trench outline");
  return {};
}

std::string describe(const ColourDifference& d) {
  return fmt::format("{} px, |render - photo| median {:.0f} {:.0f} {:.0f} (mean {:.1f}), p90 {:.0f} {:.0f} {:.0f} "
                     "(mean {:.1f}) grey levels (R G B)",
                     d.pixels, d.median[0], d.median[1], d.median[2], d.median_mean, d.p90[0], d.p90[1], d.p90[2],
                     d.p90_mean);
}

nlohmann::ordered_json difference_json(const ColourDifference& d) {
  return {{"pixels", d.pixels}, {"median", d.median}, {"p90", d.p90}, {"median_mean", d.median_mean},
          {"p90_mean", d.p90_mean}};
}

void write_check_images(const PhotoCheck& c, const fs::path& dir) {
  fs::create_directories(dir);
  const std::string stem = fs::path(c.view).stem().string();
  for (const auto& [suffix, image] : {std::pair{"render", &c.rendered}, std::pair{"difference", &c.difference}}) {
    const fs::path file = dir / fmt::format("{}_{}.png", stem, suffix);
    write_bytes_atomically(file, "export model --check-images", encode_texture_image(*image, 0));
  }
}

void check_textured_model_command(Project& p, const TexturedMesh& model, const std::vector<OrthoView>& views,
                                  const CheckArgs& c) {
  ModelCheckOptions o;
  o.scale = c.scale;
  o.region = check_region(p, c);
  o.images = !c.images_dir.empty();
  const ModelCheckSummary sum = check_textured_model(model, views, spread_views(views, c.photos), o);
  const bool region = !o.region.empty();
  nlohmann::ordered_json photos = nlohmann::ordered_json::array();
  for (const PhotoCheck& pc : sum.photos) {
    if (o.images) write_check_images(pc, c.images_dir);
    photos.push_back({{"photo", pc.view}, {"all", difference_json(pc.all)}, {"own", difference_json(pc.own)},
                      {"untextured_pixels", pc.untextured_pixels}, {"seconds", pc.seconds}});
    if (region) photos.back()["trench"] = difference_json(pc.inside);
    log::info("check {}: {}{}; on faces textured from this photo {}; {} px on untextured faces, {:.1f} s", pc.view,
              describe(pc.all), region ? fmt::format("; in the trench {}", describe(pc.inside)) : "",
              describe(pc.own), pc.untextured_pixels, pc.seconds);
  }
  log::info("check, {} photos: {}", sum.photos.size(), describe(sum.all));
  log::info("check, {} photos, on faces textured from the photo itself: {}", sum.photos.size(), describe(sum.own));
  if (region) log::info("check, {} photos, in the trench: {}", sum.photos.size(), describe(sum.inside));
  if (o.images) log::info("check: rendered and difference images in {}", c.images_dir);
  if (c.json) {
    nlohmann::ordered_json j = {{"photos_checked", sum.photos.size()}, {"scale", o.scale}, {"all", difference_json(sum.all)},
                              {"own", difference_json(sum.own)}};
    if (region) j["trench"] = difference_json(sum.inside);
    j["seconds"] = sum.seconds;
    j["photos"] = photos;
    fmt::print("{}\n", j.dump(2));
  }
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
                       ModelFormat format, const TextureArgs& t, const CheckArgs& check) {
  const SiteInfo site = p.site();
  ExportFrame frame;
  frame.site_origin = site.origin;
  frame.crs = site.crs;
  std::optional<TexturedModel> tex;
  std::vector<OrthoView> views;
  if (t.texture) {
    views = layer_ortho_views(p, layer);
    tex = texture_layer_mesh(views, mesh, t, layer);
  }
  const DenseMesh& written = tex ? tex->textured.mesh : mesh;
  const MeshTexture* texture = tex ? &tex->texture : nullptr;
  const std::string what = fmt::format("{} vertices, {} faces{}", written.vertices.size(), written.faces.size(),
                                       tex ? ", textured" : "");
  if (format == ModelFormat::obj) {
    const ObjModelFiles files = write_obj_model(out, written, frame, texture);
    log::info("wrote {} ({}; local origin E {:.0f} N {:.0f} Z {:.0f}, x = E, y = N, z = up){}", out, what,
              files.origin.x(), files.origin.y(), files.origin.z(),
              files.mtl.empty() ? "" : fmt::format(", {} and {} atlas image(s)", files.mtl.string(), files.images.size()));
  } else {
    GltfMesh gm{layer, &written};
    gm.texture = texture;
    write_glb(out, std::span<const GltfMesh>(&gm, 1), frame);
    log::info("wrote {} ({})", out, what);
  }
  if (tex && check.photos > 0) check_textured_model_command(p, tex->textured, views, check);
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
      "--texture: every layer mesh (or with --layer, that one) textured from the layer's aligned\n"
      "photos instead of vertex colours: each face from its best unoccluded photo, packed into\n"
      "square atlases embedded as JPEG (docs/model.md, Textures), each photo's colours scaled by\n"
      "its gains (one per channel, fitted over the faces several photos see, so that seams\n"
      "between photos of different exposure do not show; --no-colour-gains leaves the photos'\n"
      "colours as they are); a layer without aligned photos keeps its vertex colours. Needs the\n"
      "photos on disk.\n"
      "--lod N: level of detail, each layer mesh simplified to about faces / 4^N (0: the fused\n"
      "mesh; colours and normals kept; refused when fewer than 100 faces would remain).\n"
      "--out FILE.obj (with --layer): Wavefront OBJ relative to the same local origin, in the\n"
      "site's axes (x = E, y = N, z = up; origin, CRS and axes in the comment lines at the top):\n"
      "'v x y z r g b' vertex colours and vn normals, or with --texture vt, FILE.mtl and the\n"
      "atlases as FILE_atlasK.jpg (.png with --jpeg-quality 0) beside it.\n"
      "--check-photos N (with --texture): the textured model rendered from N of the layer's\n"
      "photos, spread over the set, with each photo's own pose and lens, and compared with\n"
      "that photo: pixels compared, median and 90th percentile of |render - photo| per\n"
      "channel (grey levels 0-255) and of their mean, over the whole model, over the\n"
      "trench (--check-outline, default the outline 'strata volume --outline' kept) and on\n"
      "the faces textured from that photo itself (the resampling alone; the rest adds the\n"
      "colour differences between photos and their registration);\n"
      "--check-images DIR writes PHOTO_render.png and PHOTO_difference.png (|difference| x 4)\n"
      "for each, to look at seams; --json prints the figures (docs/model.md, Textures).\n"
      "Unit solids are simplified with the layers (--lod). Not yet: the site model as OBJ.\n"
      "Needs the layers' dense meshes ('strata process DIR --layer L --until dense').");
  const auto a = add_layer_export_options(cmd, "output file, .glb or .obj", "the layer (default: the whole site)");
  const auto lod = std::make_shared<int>(0);
  cmd->add_option("--lod", *lod, "level of detail: 0 the fused mesh, N about faces / 4^N")->capture_default_str();
  const auto t = std::make_shared<TextureArgs>();
  cmd->add_flag("--texture", t->texture, "texture the layer meshes from their aligned photos (the photos must be on disk)");
  cmd->add_option("--jpeg-quality", t->jpeg_quality, "atlas JPEG quality, 1-100; 0 writes PNG (lossless, larger)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  cmd->add_option("--atlas-size", t->atlas_size_px, "side of a square texture atlas, texels (64-16384)")
      ->check(CLI::Range(64, 16384))
      ->capture_default_str();
  cmd->add_flag_callback("--no-colour-gains", [t] { t->colour_gains = false; },
                         "with --texture: each photo's colours as taken, without the gains fitted between photos");
  const auto check = std::make_shared<CheckArgs>();
  cmd->add_option("--check-photos", check->photos,
                  "with --texture: render the model from N of its photos and compare with them (0: no check)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--check-scale", check->scale, "rendered pixels per photo pixel for --check-photos, (0, 1]")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  cmd->add_option("--check-outline", check->outline,
                  "FILE: trench outline (first polygon, site CRS) for the --check-photos figures in the trench")
      ->check(CLI::ExistingFile);
  cmd->add_option("--check-images", check->images_dir, "DIR: write the rendered and difference images of --check-photos");
  cmd->add_flag("--json", check->json, "print the --check-photos figures as JSON on stdout");
  cmd->callback([=] {
    check_level_of_detail(*lod);
    if (check->photos > 0 && (!t->texture || a->layer.empty())) {
      throw InputError("--check-photos needs --texture and --layer (it checks one layer's textured model)");
    }
    const ModelFormat format = model_format(a->out);
    if (a->layer.empty()) {
      if (format == ModelFormat::obj) {
        throw InputError(fmt::format("--out {}: OBJ holds one layer's mesh, give --layer; the site model (unit "
                                     "solids, markers, cameras) is written as .glb", a->out));
      }
      export_site_model(a->dir, a->out, *lod, *t);
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
    write_layer_model(p, l.name, mesh, a->out, format, *t, *check);
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
