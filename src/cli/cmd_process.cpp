// strata process
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "features/targets.hpp"
#include "pipeline/align_layer.hpp"
#include "pipeline/dense_layer.hpp"
#include "pipeline/products_layer.hpp"
#include "report/report.hpp"
#include "project/media.hpp"
#include "project/project.hpp"
#include "project/records.hpp"
#include "project/scan_records.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace strata::cli {
namespace {

// The lens model of each camera, why, and what self-calibration found; the focal
// search of photos without EXIF when it ran.
void print_cameras(const nlohmann::json& q) {
  if (!q.contains("cameras")) return;  // stored by an earlier version
  for (const auto& c : q["cameras"]) {
    const std::string model = c["model"].get<std::string>();
    std::string terms = fmt::format("k1 {:.4f} k2 {:.4f}", c["k1"].get<double>(), c["k2"].get<double>());
    if (c.contains("k3")) terms += fmt::format(" k3 {:.4f}", c["k3"].get<double>());
    if (c.contains("k4")) terms += fmt::format(" k4 {:.4f}", c["k4"].get<double>());
    if (c.contains("p1")) terms += fmt::format(" p1 {:.5f} p2 {:.5f}", c["p1"].get<double>(), c["p2"].get<double>());
    fmt::print("  camera {:<12} {} x {}: {}, f {:.1f} px, pp ({:.1f}, {:.1f}), {}{}\n",
               c["camera_id"].is_null() ? std::string("-") : std::to_string(c["camera_id"].get<std::int64_t>()),
               c["width"].get<int>(), c["height"].get<int>(), model, c["fx"].get<double>(),
               c["cx"].get<double>(), c["cy"].get<double>(), terms,
               c["calibration_fixed"].get<bool>() ? " (fixed calibration)" : "");
    if (c.contains("model_reason")) fmt::print("    lens model        {}\n", c["model_reason"].get<std::string>());
  }
  if (q.contains("focal_search")) {
    for (const auto& a : q["focal_search"]["attempts"]) {
      const std::string outcome =
          a["failure"].is_null()
              ? fmt::format("{} photos, RMSE {:.3f} px, focal {:.0f} px", a["registered"].get<int>(),
                            a["rmse_px"].is_null() ? 0.0 : a["rmse_px"].get<double>(),
                            a["focal_px"].empty() ? 0.0 : a["focal_px"][0].get<double>())
              : "failed: " + a["failure"].get<std::string>();
      fmt::print("    focal prior       {:.1f} x long side: {}{}\n", a["factor"].get<double>(), outcome,
                 a["chosen"].get<bool>() ? "  (kept)" : "");
    }
  }
}

void print_quality(const nlohmann::json& q, bool skipped) {
  fmt::print("layer {}{}\n", q["layer"].get<std::string>(), skipped ? " (up to date, not recomputed)" : "");
  fmt::print("  photos aligned      {} / {}\n", q["images_registered"].get<int>(), q["images_total"].get<int>());
  fmt::print("  sparse points       {} (mean track {:.1f} photos)\n", q["points"].get<int>(),
             q["mean_track_length"].get<double>());
  fmt::print("  reprojection RMSE   {:.3f} px\n", q["reprojection_rmse_px"].get<double>());
  fmt::print("  ground sampling     {:.2f} mm/px\n", 1000 * q["gsd_m"].get<double>());
  print_cameras(q);
  if (!q["georeferenced"].get<bool>()) {
    fmt::print("  NOT georeferenced: arbitrary local frame and scale\n");
    return;
  }
  auto rmse = [](const nlohmann::json& r) {
    if (r["markers"].get<int>() == 0) return std::string("-");
    return fmt::format("E {:.1f}  N {:.1f}  Z {:.1f}  3D {:.1f} mm ({} markers)", 1000 * r["e_m"].get<double>(),
                       1000 * r["n_m"].get<double>(), 1000 * r["z_m"].get<double>(),
                       1000 * r["xyz_m"].get<double>(), r["markers"].get<int>());
  };
  fmt::print("  control RMSE        {}\n", rmse(q["control_rmse"]));
  fmt::print("  check RMSE          {}\n", rmse(q["check_rmse"]));
  // Photos: agreeing of observed; spread: the marker's own dispersion (a marker object
  // clicked from different sides scatters; its observations are weighed by it).
  fmt::print("  {:<10} {:<9} {:>8} {:>8} {:>8} {:>8} {:>7} {:>9}\n", "marker", "role", "dE mm", "dN mm", "dZ mm",
             "px", "photos", "spread mm");
  std::vector<std::string> notes;
  for (const auto& m : q["markers"]) {
    const int observed = m.value("observed", m["images"].get<int>());
    const std::string photos = fmt::format("{}/{}", m["images"].get<int>(), observed);
    const std::string diagnosis = m.value("diagnosis", std::string());
    if (!diagnosis.empty()) notes.push_back(fmt::format("{}: {}", m["marker"].get<std::string>(), diagnosis));
    if (!m["triangulated"].get<bool>()) {
      fmt::print("  {:<10} {:<9} {:>35} {:>7}\n", m["marker"].get<std::string>(), m["role"].get<std::string>(),
                 "not triangulated", photos);
      continue;
    }
    fmt::print("  {:<10} {:<9} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.2f} {:>7} {:>9.1f}\n", m["marker"].get<std::string>(),
               m["role"].get<std::string>(), 1000 * m["dE"].get<double>(), 1000 * m["dN"].get<double>(),
               1000 * m["dZ"].get<double>(), m["reprojection_px"].get<double>(), photos,
               1000 * m.value("dispersion_m", 0.0));
  }
  for (const auto& n : notes) fmt::print("    {}\n", n);
  if (q.contains("georeference_diagnosis")) {
    for (const auto& d : q["georeference_diagnosis"]) fmt::print("  note: {}\n", d.get<std::string>());
  }
  if (q.contains("calibration_check")) {
    for (const auto& c : q["calibration_check"]) {
      if (!c.value("finding", std::string()).empty()) fmt::print("  note: camera {}: {}\n", c.value("group", 0), c["finding"].get<std::string>());
    }
  }
}

void print_dense(const nlohmann::json& q, bool skipped) {
  fmt::print("  dense surface{}\n", skipped ? " (up to date, not recomputed)" : "");
  const bool photos = q.value("photos", true);
  if (photos) {
    fmt::print("    depth maps          {} / {} photos at scale {}\n", q["images_with_depth"].get<int>(),
               q["images_total"].get<int>(), q["depth_scale"].get<double>());
  }
  if (q.value("scans_fused", 0) > 0) {
    fmt::print("    range scans         {} fused, {} points, {:.0f} % of the weight (unit sigma {:.1f} mm)\n",
               q["scans_fused"].get<int>(), q["scan_points"].get<std::uint64_t>(),
               100 * q["scan_weight_share"].get<double>(), 1000 * q["unit_sigma_m"].get<double>());
  }
  fmt::print("    voxel size          {:.1f} mm\n", 1000 * q["voxel_size_m"].get<double>());
  fmt::print("    completeness        {:.1f} % of {:.2f} m2\n", 100 * q["completeness"].get<double>(),
             q["area_m2"].get<double>());
  if (q["median_distance_sparse_m"].is_number()) {
    fmt::print("    to sparse points    median {:.1f} mm, 95% {:.1f} mm\n",
               1000 * q["median_distance_sparse_m"].get<double>(), 1000 * q["p95_distance_sparse_m"].get<double>());
  }
  fmt::print("    mesh                {} faces; {} points\n", q["mesh_faces"].get<int>(), q["points"].get<int>());
  fmt::print("    time                {:.1f} s\n", q["steps"]["total"]["seconds"].get<double>());
}

void print_products(const nlohmann::json& q, bool skipped) {
  fmt::print("  products{}\n", skipped ? " (up to date, not recomputed)" : "");
  const auto& d = q["dtm"];
  fmt::print("    DTM                 {}  {}x{} cells of {:.1f} mm, {:.2f} m2, heights {:.3f}..{:.3f} m\n",
             d["path"].get<std::string>(), d["width"].get<int>(), d["height"].get<int>(),
             1000 * d["cell_m"].get<double>(), d["area_m2"].get<double>(), d["min_m"].get<double>(),
             d["max_m"].get<double>());
  const auto& o = q["ortho"];
  if (o.is_null()) {
    fmt::print("    orthophoto          none: the layer has no photos to drape on its surface\n");
  } else {
    fmt::print("    orthophoto          {}  coverage {:.1f} %, {} photos used\n", o["path"].get<std::string>(),
               100 * o["coverage"].get<double>(), o["views_used"].get<int>());
  }
  if (q.contains("ortho_markers")) {
    // Coded targets found in the orthophoto against their survey.
    const auto& m = q["ortho_markers"];
    const double tol = m["tolerance_px"].get<double>();
    if (m["detected"].get<int>() == 0) {
      fmt::print("    ortho vs markers    none of {} markers found in the orthophoto\n", m["surveyed"].get<int>());
    } else {
      fmt::print("    ortho vs markers    {} of {} found; offset max {:.2f} px ({:.1f} mm), RMSE {:.2f} px ({:.1f} mm){}\n",
                 m["detected"].get<int>(), m["surveyed"].get<int>(), m["max_px"].get<double>(),
                 m["max_mm"].get<double>(), m["rmse_px"].get<double>(), m["rmse_mm"].get<double>(),
                 m["over_tolerance"].get<int>() > 0
                     ? fmt::format("; {} OVER {:.0f} px", m["over_tolerance"].get<int>(), tol)
                     : fmt::format(", all within {:.0f} px", tol));
    }
    fmt::print("      {:<10} {:<9} {:>8} {:>8} {:>8} {:>7}\n", "marker", "role", "dE mm", "dN mm", "off mm", "px");
    for (const auto& k : m["markers"]) {
      const std::string status = k["status"].get<std::string>();
      if (status != "detected") {
        const std::string pixel =
            k.contains("source_pixel_mm") ? fmt::format(", photo pixel {:.1f} mm", k["source_pixel_mm"].get<double>()) : "";
        const std::string why = status == "outside"      ? "outside the orthophoto"
                                : status == "not_seen"    ? "not seen (no photo covers it)"
                                : status == "partly_seen" ? "holes in the orthophoto around it"
                                : status == "coarse"      ? "photos too coarse there" + pixel
                                                          : "NOT DETECTED (fully covered" + pixel + ")";
        fmt::print("      {:<10} {:<9} {:>34}\n", k["marker"].get<std::string>(), k["role"].get<std::string>(), why);
        continue;
      }
      const double px = k["offset_px"].get<double>();
      fmt::print("      {:<10} {:<9} {:>8.1f} {:>8.1f} {:>8.1f} {:>7.2f}{}\n", k["marker"].get<std::string>(),
                 k["role"].get<std::string>(), k["dE_mm"].get<double>(), k["dN_mm"].get<double>(),
                 k["offset_mm"].get<double>(), px, px > tol ? "  OVER" : "");
    }
  }
  fmt::print("    contours            {} lines every {:.0f} mm\n", q["contours"]["lines"].get<int>(),
             1000 * q["contours"]["interval_m"].get<double>());
  fmt::print("    footprint           {:.2f} m2\n", q["footprint"]["area_m2"].get<double>());
}

}  // namespace

void register_process_commands(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "process",
      "reconstruct layers from their photos: features -> matches -> coded targets -> incremental\n"
      "structure from motion with self-calibration -> georeference on the surveyed markers.\n"
      "Stages whose inputs and options are unchanged are not recomputed; features and matches\n"
      "are cached under cache/.");
  auto dir = std::make_shared<std::string>();
  auto layer = std::make_shared<std::string>();
  auto all = std::make_shared<bool>(false);
  auto until = std::make_shared<std::string>("products");
  auto products = std::make_shared<ProductsOptions>();
  auto dense = std::make_shared<DenseOptions>();
  auto json = std::make_shared<bool>(false);
  auto options = std::make_shared<AlignOptions>();
  auto target_names = std::make_shared<std::string>();
  cmd->add_option("DIR", *dir, "project folder")->required();
  auto* layer_opt = cmd->add_option("--layer", *layer, "the layer to process");
  auto* all_opt = cmd->add_flag("--all", *all, "process every layer");
  layer_opt->excludes(all_opt);
  cmd->add_option("--until", *until,
                  "last stage to run: sparse (alignment and georeference), dense (depth maps, "
                  "fused surface, mesh, point cloud) or products (DTM, true orthophoto, contours, "
                  "footprint; the default)")
      ->check(CLI::IsMember({"sparse", "dense", "products"}));
  auto* cell_opt = cmd->add_option("--cell", products->dtm.cell_m,
                                   "DTM and orthophoto cell size in metres (default: the dense surface's ground "
                                   "sampling distance, at least 0.005)");
  cmd->add_option("--contour-interval", products->contours.interval_m, "contour interval in metres (default 0.05)");
  cmd->add_option("--dense-scale", dense->patch_match.scale,
                  "depth-map resolution relative to the photos: 1, 0.5 or 0.25 (default: the coarsest "
                  "whose ground sampling distance is at most 8 mm)");
  cmd->add_option("--voxel-size", dense->fusion.voxel_size_m,
                  "fusion voxel size in metres (default: from the ground sampling distance)");
  cmd->add_option("--target-faces", dense->mesh.target_faces,
                  "simplify the mesh to this many faces with CGAL (default: keep all)");
  cmd->add_flag("--json", *json, "print the quality figures as JSON");
  cmd->add_flag("--force", options->force, "recompute even when up to date");
  cmd->add_option("--max-image-size", options->features.max_image_size,
                  "long side (px) photos are reduced to for feature detection (default 2000)");
  cmd->add_option("--max-features", options->features.max_features, "SIFT features per photo (default 8000)");
  cmd->add_option("--camera-model", options->lens.model,
                  "lens model of every camera: auto (default: from the lens, see docs/cameras.md), "
                  "radial (k1, k2), brown (k1-k3, p1, p2; wide lenses) or fisheye (equidistant, k1-k4)")
      ->check(CLI::IsMember({"auto", "radial", "brown", "fisheye"}));
  cmd->add_flag("!--no-focal-search", options->focal_search.enabled,
                "photos without EXIF focal length: keep the default prior (1.2 x long side) even when "
                "the alignment with it is poor");
  cmd->add_flag("!--no-targets", options->detect_targets, "do not detect coded targets");
  cmd->add_option("--target-dictionary", options->targets.dictionary,
                  "coded target family: DICT_4X4_50 (default), DICT_APRILTAG_36h11, ...");
  cmd->add_option("--target-rule", options->naming.rule,
                  "marker name of a coded target id (default 'GCP{id}')");
  cmd->add_option("--target-names", *target_names,
                  "explicit id=name list, e.g. '3=NW,4=NE'; wins over --target-rule");
  cmd->footer("Example: strata process site --layer L101 --json");
  cmd->callback([=] {
    if (layer->empty() && !*all) throw InputError("process: give --layer LAYER or --all");
    const ProjectLock lock = lock_project(*dir);
    Project p = Project::open(*dir);
    if (!target_names->empty()) options->naming.names = parse_target_names(*target_names);
    std::vector<std::string> layers;
    if (*all) {
      for (const auto& l : list_layers(p.db())) layers.push_back(l.name);
    } else {
      layers.push_back(require_layer(p.db(), *layer).name);
    }
    // Every photo the run will read still holds what was imported, before anything
    // is computed from any layer (project/media.hpp).
    for (const auto& name : layers) {
      const auto photos = list_images(p.db(), require_layer(p.db(), name).id);
      const MediaCheckSummary checked = verify_media(p.dir(), photos);
      log::info("layer {}: {} photos match their SHA-256 ({} read in full)", name, checked.photos, checked.hashed);
    }
    nlohmann::json out = nlohmann::json::array();
    for (const auto& name : layers) {
      // A layer recorded by range scans alone has nothing to align: its registered
      // scans are fused directly (docs/range.md).
      const LayerRecord rec = require_layer(p.db(), name);
      const bool scans_only = list_images(p.db(), rec.id).empty() && !list_scans(p.db(), rec.id).empty();
      AlignResult r;
      if (scans_only) {
        log::info("== layer {}: no photos, {} range scan(s): no alignment", name, list_scans(p.db(), rec.id).size());
        r.skipped = true;  // nothing upstream changed: the dense stage decides by its own inputs
        r.quality = {{"layer", name}, {"photos", false}};
        if (!*json) fmt::print("layer {}\n  no photos: the surface comes from its range scans\n", name);
      } else {
        log::info("== layer {}: alignment", name);
        r = align_layer(p, name, *options);
        if (!*json) print_quality(r.quality, r.skipped);
      }
      nlohmann::json q = r.quality;
      if (*until != "sparse") {
        log::info("== layer {}: dense surface", name);
        const DenseLayerResult d = dense_layer(p, name, *dense, options->force || !r.skipped);
        q["dense"] = d.quality;
        if (!*json) print_dense(d.quality, d.skipped);
        if (*until == "products") {
          log::info("== layer {}: DTM, orthophoto, site plan", name);
          ProductsOptions po = *products;
          // Targets in the orthophoto are read as in the photos.
          po.ortho_markers.targets = options->targets;
          po.ortho_markers.naming = options->naming;
          if (cell_opt->count() == 0) {
            // Cells finer than the dense surface's sampling only interpolate; coarser
            // ones lose detail. Round to the millimetre so reruns agree.
            const double gsd = d.quality.value("gsd_m", 0.0);
            po.dtm.cell_m = std::max(0.005, std::round(gsd * 1000.0) / 1000.0);
          }
          const ProductsLayerResult pr = products_layer(p, name, po, options->force || !d.skipped);
          q["products"] = pr.quality;
          if (!*json) print_products(pr.quality, pr.skipped);
        }
      }
      // The field report is rewritten after every run, so the trench edge always
      // has the current verdict. A report failure is said, but does not undo the
      // processing that succeeded.
      try {
        const auto report = write_layer_report_product(p, name);
        log::info("field report: {}", report.string());
      } catch (const Error& e) {
        log::warn("layer {}: the field report could not be written: {}", name, e.what());
      }
      out.push_back(q);
    }
    if (*json) fmt::print("{}\n", (*all ? out : out.front()).dump(2));
  });
}

}  // namespace strata::cli
