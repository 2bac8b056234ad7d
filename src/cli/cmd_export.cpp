// strata export ...
#include "cli/commands.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/log.hpp"
#include "exporters/cameras/camera_export.hpp"
#include "pipeline/alignment_store.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <fmt/format.h>

#include <memory>

namespace strata::cli {

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
    auto dir = std::make_shared<std::string>();
    auto layer = std::make_shared<std::string>();
    auto format = std::make_shared<std::string>("csv");
    auto out = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("--layer", *layer, "the layer")->required();
    cmd->add_option("--format", *format, "csv (default), csv-lens or colmap")
        ->check(CLI::IsMember({"csv", "csv-lens", "colmap"}));
    cmd->add_option("--out", *out, "output file (csv) or folder (colmap)")->required();
    cmd->callback([=] {
      Project p = Project::open(*dir);
      const LayerRecord l = require_layer(p.db(), *layer);
      const auto a = load_alignment(p.db(), l);
      if (!a) throw InputError(fmt::format("layer {} is not aligned yet; run 'strata process {} --layer {}'",
                                           l.name, *dir, l.name));
      const SiteInfo site = p.site();
      if (*format == "csv") {
        write_cameras_csv(a->rec, site.origin, *out);
        for (const auto& g : a->rec.groups) {
          if (g.intrinsics.model != CameraModel::radial) {
            log::warn("layer {}: its {} lens terms (k3, k4, p1, p2) are not in the csv format; "
                      "--format csv-lens has them", l.name, to_string(g.intrinsics.model));
            break;
          }
        }
      } else if (*format == "csv-lens") {
        write_cameras_lens_csv(a->rec, site.origin, *out);
      } else {
        write_colmap_model(a->rec, *out);
      }
      log::info("wrote {}", *out);
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
    auto dir = std::make_shared<std::string>();
    auto layer = std::make_shared<std::string>();
    auto out = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("--layer", *layer, "the layer")->required();
    cmd->add_option("--out", *out, "output file")->required();
    cmd->callback([=] {
      Project p = Project::open(*dir);
      const LayerRecord l = require_layer(p.db(), *layer);
      const bool obj = std::filesystem::path(*out).extension() == ".obj";
      auto product = find_product(p.db(), l.id, obj ? "mesh_obj" : kind);
      if (!product) {
        throw InputError(fmt::format("layer {} has no {} yet; run 'strata process {} --layer {} --until dense'{}",
                                     l.name, obj ? "OBJ mesh" : kind, *dir, l.name,
                                     obj ? " (OBJ meshes need the dense stage's OBJ option)" : ""));
      }
      const auto src = p.dir() / product->path;
      if (!std::filesystem::exists(src) || sha256_file(src) != product->sha256) {
        throw IoError(fmt::format("{}: missing or changed since it was recorded; rerun 'strata process {} --layer "
                                  "{} --force'", src.string(), *dir, l.name));
      }
      const std::string tmp = *out + ".tmp";
      std::filesystem::copy_file(src, tmp, std::filesystem::copy_options::overwrite_existing);
      fault::point("export.copy.temp_written");
      std::filesystem::rename(tmp, *out);
      log::info("wrote {}", *out);
    });
  }
}

}  // namespace strata::cli
