// strata camera list|set|clear, strata import calibration
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "importers/calibration/calibration_importer.hpp"
#include "pipeline/alignment_store.hpp"
#include "pipeline/camera_calibration.hpp"
#include "project/calibration_records.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <memory>

namespace strata::cli {
namespace {

// "a,b[,c...]" -> numbers; InputError naming the option.
std::vector<double> parse_list(const std::string& text, const std::string& option) {
  return parse_numbers(text, std::size_t(std::count(text.begin(), text.end(), ',')) + 1, option);
}

nlohmann::json intrinsics_json(const Intrinsics& k) {
  return {{"model", to_string(k.model)}, {"width", k.width}, {"height", k.height}, {"fx", k.fx},
          {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"k1", k.k1}, {"k2", k.k2}, {"k3", k.k3},
          {"k4", k.k4}, {"p1", k.p1}, {"p2", k.p2}};
}

std::string intrinsics_text(const Intrinsics& k) {
  std::string s = fmt::format("{} f {:.2f},{:.2f} pp {:.2f},{:.2f} k {:.5g},{:.5g}", to_string(k.model), k.fx,
                              k.fy, k.cx, k.cy, k.k1, k.k2);
  if (k.model != CameraModel::radial) s += fmt::format(",{:.5g}", k.k3);
  if (k.model == CameraModel::fisheye) s += fmt::format(",{:.5g}", k.k4);
  if (k.model == CameraModel::brown) s += fmt::format(" p {:.5g},{:.5g}", k.p1, k.p2);
  return s;
}

void print_record(const char* verb, const CalibrationRecord& c, bool replaced) {
  fmt::print("camera {}: calibration {}{} ({}, {}): {}\n", c.camera_id, verb, replaced ? " (replaced)" : "",
             c.source, c.fixed ? "fixed" : "starting value", intrinsics_text(c.intrinsics));
}

// Every layer's latest alignment: camera id -> (layer, solved intrinsics).
std::map<std::int64_t, std::vector<std::pair<std::string, Intrinsics>>> solved_by_camera(Database& db) {
  std::map<std::int64_t, std::vector<std::pair<std::string, Intrinsics>>> out;
  for (const auto& layer : list_layers(db)) {
    const auto a = load_alignment(db, layer);
    if (!a) continue;
    for (std::size_t g = 0; g < a->camera_ids.size(); ++g) {
      out[a->camera_ids[g]].emplace_back(layer.name, a->rec.groups[g].intrinsics);
    }
  }
  return out;
}

void list_cameras_command(const std::string& dir, bool json) {
  Project p = Project::open(dir);
  Database& db = p.db();
  std::map<std::int64_t, std::string> layer_name;
  for (const auto& l : list_layers(db)) layer_name[l.id] = l.name;
  std::map<std::int64_t, std::map<std::string, int>> photos;  // camera -> layer -> count
  for (const auto& im : list_images(db)) {
    if (im.camera_id) photos[*im.camera_id][layer_name[im.layer_id]]++;
  }
  const auto solved = solved_by_camera(db);
  const auto cameras = list_cameras(db);
  nlohmann::json j = nlohmann::json::array();
  for (const auto& c : cameras) {
    nlohmann::json row = {{"id", c.id}, {"make", c.make}, {"model", c.model}, {"width", c.width},
                          {"height", c.height}};
    row["focal_mm"] = c.focal_mm ? nlohmann::json(*c.focal_mm) : nlohmann::json(nullptr);
    row["focal_35mm"] = c.focal_35mm ? nlohmann::json(*c.focal_35mm) : nlohmann::json(nullptr);
    row["prior_focal_px"] = c.focal_px ? nlohmann::json(*c.focal_px) : nlohmann::json(nullptr);
    row["prior_focal_source"] = c.focal_source;
    row["photos"] = photos.count(c.id) ? nlohmann::json(photos.at(c.id)) : nlohmann::json::object();
    if (const auto cal = find_calibration(db, c.id)) {
      row["calibration"] = intrinsics_json(cal->intrinsics);
      row["calibration"]["fixed"] = cal->fixed;
      row["calibration"]["source"] = cal->source;
      row["calibration"]["set_at"] = cal->set_at;
    } else {
      row["calibration"] = nullptr;
    }
    nlohmann::json s = nlohmann::json::object();
    if (solved.count(c.id)) {
      for (const auto& [layer, k] : solved.at(c.id)) s[layer] = intrinsics_json(k);
    }
    row["solved"] = s;
    j.push_back(row);
  }
  if (json) {
    fmt::print("{}\n", j.dump(2));
    return;
  }
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const CameraRecord& c = cameras[i];
    const nlohmann::json& row = j[i];
    const std::string name = c.make.empty() && c.model.empty() ? "(no EXIF make/model)" : c.make + " " + c.model;
    fmt::print("camera {}: {} {}x{} px", c.id, name, c.width, c.height);
    if (c.focal_mm) fmt::print(", EXIF focal {:.1f} mm", *c.focal_mm);
    if (c.focal_px) {
      fmt::print(", prior {:.1f} px ({})", *c.focal_px, c.focal_source);
    } else {
      fmt::print(", no focal prior");
    }
    fmt::print("\n  photos:");
    for (const auto& [layer, n] : row["photos"].items()) fmt::print(" {} {}", layer, n.get<int>());
    fmt::print("\n");
    if (const auto cal = find_calibration(db, c.id)) {
      fmt::print("  calibration: {} ({}, {}, {})\n", intrinsics_text(cal->intrinsics),
                 cal->fixed ? "fixed" : "starting value", cal->source, cal->set_at);
    } else {
      fmt::print("  calibration: none (self-calibrated)\n");
    }
    if (solved.count(c.id)) {
      for (const auto& [layer, k] : solved.at(c.id)) fmt::print("  solved in {}: {}\n", layer, intrinsics_text(k));
    }
  }
  fmt::print("{} camera(s).\n", cameras.size());
}

void register_set(CLI::App* camera) {
  auto* cmd = camera->add_subcommand(
      "set",
      "give a camera a known calibration: values (--focal-px ...) or the intrinsics another\n"
      "layer's alignment solved (--from-layer). The alignment starts the camera from it and,\n"
      "with --fixed, holds it constant; without, it is refined like a self-calibration.\n"
      "Pixels have (0,0) at the centre of the top-left pixel; --p is in OpenCV's order.");
  auto dir = std::make_shared<std::string>();
  auto options = std::make_shared<CameraSetOptions>();
  auto focal = std::make_shared<double>(0);
  auto fy = std::make_shared<double>(0);
  auto pp = std::make_shared<std::string>();
  auto model = std::make_shared<std::string>("radial");
  auto k = std::make_shared<std::string>();
  auto tangential = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("CAMERA", options->camera, "camera id (strata camera list) or the name of one of its photos")
      ->required();
  auto* focal_opt = cmd->add_option("--focal-px", *focal, "focal length in pixels (fx, and fy unless --fy)");
  auto* fy_opt = cmd->add_option("--fy", *fy, "vertical focal length in pixels (default: --focal-px)");
  cmd->add_option("--pp", *pp, "principal point X,Y in pixels (default: the image centre)");
  auto* model_opt = cmd->add_option("--model", *model, "radial (k1,k2), brown (k1-k3, p1,p2) or fisheye (k1-k4)");
  cmd->add_option("--k", *k, "radial coefficients K1,K2[,K3[,K4]] (radial: 2; brown: 2-3; fisheye: 2-4)");
  cmd->add_option("--p", *tangential, "tangential coefficients P1,P2 (brown; OpenCV's order)");
  cmd->add_option("--from-layer", options->from_layer, "reuse the intrinsics solved by this layer's alignment");
  cmd->add_flag("--fixed", options->fixed, "hold the calibration constant in every adjustment");
  cmd->footer(
      "Examples:\n"
      "  strata camera set site 1 --focal-px 3650 --pp 2011.5,1497.2 --model brown --k -0.11,0.09,-0.01 "
      "--p 0.0004,-0.0002 --fixed\n"
      "  strata camera set site IMG_0042.JPG --from-layer L3 --fixed");
  cmd->callback([=] {
    CameraSetOptions o = *options;
    if (*focal_opt) o.focal_px = *focal;
    if (*fy_opt) o.fy_px = *fy;
    if (!pp->empty()) {
      const auto v = parse_numbers(*pp, 2, "--pp");
      o.principal_point = Eigen::Vector2d(v[0], v[1]);
    }
    if (*model_opt && !o.from_layer.empty()) {
      throw InputError("--model: --from-layer takes the layer's solved model too; give one of them");
    }
    const auto m = camera_model_from_string(*model);
    if (!m) throw InputError(fmt::format("--model: '{}' is not one of radial, brown, fisheye", *model));
    o.model = *m;
    if (!k->empty()) o.k = parse_list(*k, "--k");
    if (!tangential->empty()) o.p = parse_list(*tangential, "--p");
    o.validate();  // before opening: a refused value touches nothing
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    const auto s = set_camera_calibration(p, o);
    print_record("set", s.record, s.replaced);
  });
}

void register_import_calibration(CLI::App& app) {
  auto* import = app.get_subcommand("import");
  auto* cmd = import->add_subcommand(
      "calibration",
      "give a camera the calibration in a file: OpenCV's YAML/XML (camera_matrix,\n"
      "distortion_coefficients, image_width, image_height; 4 coefficients with fisheye_model: 1\n"
      "-> fisheye) or Metashape's calibration XML (frame or fisheye). Converted to strata's\n"
      "conventions (docs/cameras.md); a calibration for another image size of the same aspect\n"
      "ratio is scaled (with a warning), of another aspect ratio refused.");
  auto dir = std::make_shared<std::string>();
  auto file = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("auto");
  auto options = std::make_shared<CalibrationImportOptions>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  cmd->add_option("FILE", *file, "calibration file")->required();
  cmd->add_option("--camera", options->camera, "camera id (strata camera list) or the name of one of its photos")
      ->required();
  cmd->add_option("--format", *format, "opencv, metashape, or auto (default: detected)");
  cmd->add_flag("--fixed", options->fixed, "hold the calibration constant in every adjustment");
  cmd->footer("Example: strata import calibration site lens.yml --camera 1 --fixed");
  cmd->callback([=] {
    options->format = parse_calibration_format(*format);
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    const auto s = import_calibration(p, *options, *file);
    for (const auto& note : s.notes) {
      if (note.rfind("scaled", 0) == 0) {
        log::warn("{}: {}", *file, note);
      } else {
        log::info("{}: {}", *file, note);
      }
    }
    print_record("imported", *find_calibration(p.db(), s.camera_id), s.replaced);
  });
}

}  // namespace

void register_camera_commands(CLI::App& app) {
  auto* camera = app.add_subcommand("camera", "cameras and their known calibrations");
  camera->require_subcommand(1);
  {
    auto* cmd = camera->add_subcommand(
        "list", "the cameras (one per make, model, image size and focal setting), their photos per layer, "
                "calibration and the intrinsics each layer's alignment solved");
    auto dir = std::make_shared<std::string>();
    auto json = std::make_shared<bool>(false);
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_flag("--json", *json, "machine-readable output");
    cmd->callback([=] { list_cameras_command(*dir, *json); });
  }
  register_set(camera);
  {
    auto* cmd = camera->add_subcommand("clear", "remove a camera's known calibration (self-calibrate again)");
    auto dir = std::make_shared<std::string>();
    auto ref = std::make_shared<std::string>();
    cmd->add_option("DIR", *dir, "project folder")->required();
    cmd->add_option("CAMERA", *ref, "camera id or the name of one of its photos")->required();
    cmd->callback([=] {
      const ProjectLock lock = lock_project(*dir);
      Project p = Project::open(*dir);
      const CameraRecord camera = resolve_camera(p.db(), *ref);
      const bool removed = clear_camera_calibration(p, *ref);
      fmt::print("camera {}: {}\n", camera.id, removed ? "calibration removed" : "had no calibration");
    });
  }
  register_import_calibration(app);
}

}  // namespace strata::cli
