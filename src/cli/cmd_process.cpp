// strata process
#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "features/targets.hpp"
#include "pipeline/process_layer.hpp"
#include "pipeline/stage_json.hpp"
#include "project/project.hpp"
#include "project/records.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace strata::cli {
namespace {

// The lens model of each camera, why, and what self-calibration found; the focal
// search of photos without EXIF when it ran.
void print_cameras(const AlignmentQuality& q) {
  for (const auto& c : q.cameras) {
    const Intrinsics& k = c.intrinsics;
    std::string terms = fmt::format("k1 {:.4f} k2 {:.4f}", k.k1, k.k2);
    if (k.model != CameraModel::radial) terms += fmt::format(" k3 {:.4f}", k.k3);
    if (k.model == CameraModel::fisheye) terms += fmt::format(" k4 {:.4f}", k.k4);
    if (k.model == CameraModel::brown) terms += fmt::format(" p1 {:.5f} p2 {:.5f}", k.p1, k.p2);
    fmt::print("  camera {:<12} {} x {}: {}, f {:.1f} px, pp ({:.1f}, {:.1f}), {}{}\n",
               c.camera_id ? std::to_string(*c.camera_id) : std::string("-"), k.width, k.height,
               to_string(k.model), k.fx, k.cx, k.cy, terms, c.calibration_fixed ? " (fixed calibration)" : "");
    if (!c.lens.reason.empty()) fmt::print("    lens model        {}\n", c.lens.reason);
  }
  if (!q.focal_search) return;
  for (const auto& a : q.focal_search->attempts) {
    const std::string outcome =
        a.failure.empty() ? fmt::format("{} photos, RMSE {:.3f} px, focal {:.0f} px", a.registered,
                                        std::isfinite(a.rmse_px) ? a.rmse_px : 0.0,
                                        a.focal_px.empty() ? 0.0 : a.focal_px[0])
                          : "failed: " + a.failure;
    fmt::print("    focal prior       {:.1f} x long side: {}{}\n", a.factor, outcome, a.chosen ? "  (kept)" : "");
  }
}

std::string rmse_line(const AxisRmse& r) {
  if (r.markers == 0) return "-";
  return fmt::format("E {:.1f}  N {:.1f}  Z {:.1f}  3D {:.1f} mm ({} markers)", 1000 * r.e, 1000 * r.n, 1000 * r.z,
                     1000 * r.xyz, r.markers);
}

// Photos: agreeing of observed; spread: the marker's own dispersion (a marker object
// clicked from different sides scatters; its observations are weighed by it).
void print_markers(const AlignmentQuality& q) {
  fmt::print("  {:<10} {:<9} {:>8} {:>8} {:>8} {:>8} {:>7} {:>9}\n", "marker", "role", "dE mm", "dN mm", "dZ mm",
             "px", "photos", "spread mm");
  std::vector<std::string> notes;
  for (const auto& m : q.markers) {
    const std::string photos = fmt::format("{}/{}", m.images, m.observed);
    const std::string role = to_string(m.role);
    if (!m.diagnosis.empty()) notes.push_back(fmt::format("{}: {}", m.name, m.diagnosis));
    if (!m.triangulated) {
      fmt::print("  {:<10} {:<9} {:>35} {:>7}\n", m.name, role, "not triangulated", photos);
      continue;
    }
    fmt::print("  {:<10} {:<9} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.2f} {:>7} {:>9.1f}\n", m.name, role, 1000 * m.dE,
               1000 * m.dN, 1000 * m.dZ, m.reprojection_px, photos, 1000 * m.dispersion_m);
  }
  for (const auto& n : notes) fmt::print("    {}\n", n);
}

void print_quality(const AlignmentQuality& q, bool skipped) {
  fmt::print("layer {}{}\n", q.layer, skipped ? " (up to date, not recomputed)" : "");
  fmt::print("  photos aligned      {} / {}\n", q.sparse.registered_images, q.images_total);
  fmt::print("  sparse points       {} (mean track {:.1f} photos)\n", q.sparse.points, q.sparse.mean_track_length);
  fmt::print("  reprojection RMSE   {:.3f} px\n", q.sparse.reprojection_rmse_px);
  fmt::print("  ground sampling     {:.2f} mm/px\n", 1000 * q.sparse.gsd_m);
  print_cameras(q);
  if (!q.georeferenced) {
    fmt::print("  NOT georeferenced: arbitrary local frame and scale\n");
    return;
  }
  fmt::print("  control RMSE        {}\n", rmse_line(q.control_rmse));
  fmt::print("  check RMSE          {}\n", rmse_line(q.check_rmse));
  print_markers(q);
  for (const auto& d : q.georeference_diagnosis) fmt::print("  note: {}\n", d);
  for (const auto& c : q.calibration_check) {
    if (!c.finding.empty()) fmt::print("  note: camera {}: {}\n", c.group, c.finding);
  }
}

void print_dense(const DenseQuality& q, bool skipped) {
  const DenseSummary& s = q.figures;
  fmt::print("  dense surface{}\n", skipped ? " (up to date, not recomputed)" : "");
  if (q.photos) {
    fmt::print("    depth maps          {} / {} photos at scale {}\n", s.images_with_depth, s.images_total,
               s.depth_scale);
  }
  if (s.scans_fused > 0) {
    fmt::print("    range scans         {} fused, {} points, {:.0f} % of the weight (unit sigma {:.1f} mm)\n",
               s.scans_fused, s.scan_points, 100 * s.scan_weight_share, 1000 * s.unit_sigma_m);
  }
  fmt::print("    voxel size          {:.1f} mm\n", 1000 * s.voxel_size_m);
  fmt::print("    completeness        {:.1f} % of {:.2f} m2\n", 100 * s.completeness, s.area_m2);
  if (std::isfinite(s.median_distance_sparse_m)) {
    fmt::print("    to sparse points    median {:.1f} mm, 95% {:.1f} mm\n", 1000 * s.median_distance_sparse_m,
               1000 * s.p95_distance_sparse_m);
  }
  fmt::print("    mesh                {} faces; {} points ({} seen too little for the cloud)\n", s.mesh_faces,
             s.points, s.points_below_weight);
  fmt::print("    time                {:.1f} s\n", s.total.seconds);
}

// Coded targets found in the orthophoto against their survey.
void print_ortho_markers(const OrthoMarkerCheckFigures& m) {
  const double tol = m.tolerance_px;
  if (m.detected == 0) {
    fmt::print("    ortho vs markers    none of {} markers found in the orthophoto\n", m.surveyed);
  } else {
    fmt::print("    ortho vs markers    {} of {} found; offset max {:.2f} px ({:.1f} mm), RMSE {:.2f} px ({:.1f} mm){}\n",
               m.detected, m.surveyed, m.max_px, m.max_mm, m.rmse_px, m.rmse_mm,
               m.over_tolerance > 0 ? fmt::format("; {} OVER {:.0f} px", m.over_tolerance, tol)
                                    : fmt::format(", all within {:.0f} px", tol));
  }
  fmt::print("      {:<10} {:<9} {:>8} {:>8} {:>8} {:>7}\n", "marker", "role", "dE mm", "dN mm", "off mm", "px");
  for (const auto& k : m.markers) {
    if (k.status != OrthoMarkerStatus::detected) {
      const std::string pixel =
          k.source_pixel_mm ? fmt::format(", photo pixel {:.1f} mm", *k.source_pixel_mm) : "";
      const std::string why = k.status == OrthoMarkerStatus::outside       ? "outside the orthophoto"
                              : k.status == OrthoMarkerStatus::not_seen    ? "not seen (no photo covers it)"
                              : k.status == OrthoMarkerStatus::partly_seen ? "holes in the orthophoto around it"
                              : k.status == OrthoMarkerStatus::coarse      ? "photos too coarse there" + pixel
                                                                           : "NOT DETECTED (fully covered" + pixel + ")";
      fmt::print("      {:<10} {:<9} {:>34}\n", k.marker, k.role, why);
      continue;
    }
    fmt::print("      {:<10} {:<9} {:>8.1f} {:>8.1f} {:>8.1f} {:>7.2f}{}\n", k.marker, k.role, k.de_mm, k.dn_mm,
               k.offset_mm, k.offset_px, k.offset_px > tol ? "  OVER" : "");
  }
}

void print_products(const ProductsQuality& q, bool skipped) {
  fmt::print("  products{}\n", skipped ? " (up to date, not recomputed)" : "");
  const auto& d = q.dtm;
  fmt::print("    DTM                 {}  {}x{} cells of {:.1f} mm, {:.2f} m2, heights {:.3f}..{:.3f} m\n", d.path,
             d.width, d.height, 1000 * d.cell_m, d.area_m2, d.min_m, d.max_m);
  if (!q.ortho) {
    fmt::print("    orthophoto          none: the layer has no photos to drape on its surface\n");
  } else {
    fmt::print("    orthophoto          {}  coverage {:.1f} %, {} photos used\n", q.ortho->path,
               100 * q.ortho->coverage, q.ortho->views_used);
  }
  if (q.ortho_markers) print_ortho_markers(*q.ortho_markers);
  fmt::print("    contours            {} lines every {:.0f} mm\n", q.contours.lines, 1000 * q.contours.interval_m);
  fmt::print("    footprint           {:.2f} m2\n", q.footprint.area_m2);
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
  cmd->add_option("--dense-cover", dense->views.reference_cover,
                  "depth maps over each spot of the surface: the fewest photos whose views hold every "
                  "sparse point this many times get a depth map (default 5; 0 = every photo, slower)")
      ->check(CLI::Range(0, 16));
  cmd->add_option("--voxel-size", dense->fusion.voxel_size_m,
                  "fusion voxel size in metres (default: from the ground sampling distance)");
  cmd->add_option("--target-faces", dense->mesh.target_faces,
                  "simplify the mesh to this many faces with CGAL (default: keep all)");
  cmd->add_flag("--json", *json, "print the quality figures as JSON");
  cmd->add_flag("--force", options->force, "recompute even when up to date");
  cmd->add_option("--max-image-size", options->features.max_image_size,
                  "long side (px) photos are reduced to for feature detection (default 2000)");
  cmd->add_option("--max-features", options->features.max_features, "SIFT features per photo (default 8000)");
  cmd->add_option("--pairs-per-photo", options->pairs.preview_best_per_photo,
                  "layers of 20 photos or more: each photo is matched with at most its K most similar "
                  "photos by a quick preview, a pair when either photo chooses it. 8 matches a 40-photo "
                  "layer in about a third of the time, the check markers within 1 %, the camera shape "
                  "within hundredths of a millimetre (docs/features.md). Default 0: every pair the preview "
                  "passes")
      ->check(CLI::Range(0, 1000));
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
      layers.push_back(*layer);
    }
    const ProcessRun run{*options, *dense, *products, parse_process_until(*until), cell_opt->count() > 0};
    ProcessObserver print;
    if (!*json) {
      print.layer_started = [](const LayerRun& r) {
        if (!r.photos) fmt::print("layer {}\n  no photos: the surface comes from its range scans and depth frames\n", r.layer);
      };
      print.aligned = [](const LayerRun& r) { print_quality(r.align->quality, r.align->skipped); };
      print.densified = [](const LayerRun& r) { print_dense(r.dense->quality, r.dense->skipped); };
      print.products_made = [](const LayerRun& r) { print_products(r.products->quality, r.products->skipped); };
    }
    const std::vector<LayerRun> runs = process_layers(p, layers, run, print);
    if (!*json) return;
    nlohmann::json out = nlohmann::json::array();
    for (const auto& r : runs) out.push_back(to_json(r));
    fmt::print("{}\n", (*all ? out : out.front()).dump(2));
  });
}

}  // namespace strata::cli
