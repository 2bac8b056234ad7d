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

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <memory>

namespace strata::cli {
namespace {

// What every per-layer export takes: the project, the layer, where to write.
struct LayerExportArgs {
  std::string dir, layer, out;
};

std::shared_ptr<LayerExportArgs> add_layer_export_options(CLI::App* cmd, const std::string& out_help) {
  auto a = std::make_shared<LayerExportArgs>();
  cmd->add_option("DIR", a->dir, "project folder")->required();
  cmd->add_option("--layer", a->layer, "the layer")->required();
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

void register_model_command(CLI::App& exp) {
  auto* cmd = exp.add_subcommand(
      "model",
      "a layer's surface as a 3D model for viewers (Blender, MeshLab, three.js, Cesium):\n"
      "a glTF 2.0 binary (.glb), one file holding the mesh, its vertex colours and normals.\n"
      "glTF stores float32 and is Y-up: vertices are written relative to a local origin (the\n"
      "mesh's bounding-box centre in site CRS coordinates, rounded to whole metres), which is\n"
      "the node's translation, so millimetres survive at UTM coordinates. Axes: glTF x = E,\n"
      "y = Z (up), z = -N. The CRS, the origin [E, N, Z] and the axes are in asset.extras.\n"
      "Not yet: photo textures, levels of detail, the whole site in one file (--layer is needed).\n"
      "Needs the layer's dense mesh ('strata process DIR --layer L --until dense').");
  const auto a = add_layer_export_options(cmd, "output file, .glb");
  cmd->callback([=] {
    if (lower_extension(a->out) != ".glb") {
      throw InputError(fmt::format("--out {}: export model writes glTF binary (.glb) only so far; OBJ comes later "
                                   "(the plain mesh as PLY: 'strata export mesh')", a->out));
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
