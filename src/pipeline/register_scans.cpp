#include "pipeline/register_scans.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "core/resources.hpp"
#include "importers/scans/scan_targets.hpp"
#include "pipeline/dense_layer.hpp"
#include "pipeline/scan_points.hpp"
#include "project/database.hpp"
#include "project/records.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <tuple>
#include <utility>

namespace fs = std::filesystem;

namespace strata {
namespace {

constexpr const char* kStage = "register.scan";

// The layer that was recorded before `layer` (layers in the order they were added).
LayerRecord previous_layer(Database& db, const LayerRecord& layer) {
  std::optional<LayerRecord> before;
  for (const LayerRecord& l : list_layers(db)) {
    if (l.id == layer.id) break;
    before = l;
  }
  if (!before)
    throw InputError(fmt::format("{}: layer {} is the first layer: there is no previous surface to register "
                                 "against (use --against layer after processing its photos, or --transform)",
                                 kStage, layer.name));
  return *before;
}

// Every point of a file, mapped by `map` (points only; normals are not needed here).
std::vector<Eigen::Vector3d> read_points(const fs::path& file, const ScanFrameMap& map) {
  std::vector<Eigen::Vector3d> out;
  read_scan_points(file, map, [&](const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3f>&, const auto&) {
    out.insert(out.end(), points.begin(), points.end());
  });
  return out;
}

ScanFrameMap shifted_by(const Eigen::Vector3d& offset) {
  ScanFrameMap map;
  map.point = [offset](const Eigen::Vector3d& p) -> Eigen::Vector3d { return p + offset; };
  return map;
}

// The layer whose surface `layer_name`'s clouds are fitted to: its own, or the one
// added before it.
LayerRecord reference_layer(Database& db, const std::string& layer_name, RegistrationReference against) {
  const auto layer = find_layer(db, layer_name);
  if (!layer) throw InputError(fmt::format("{}: no layer '{}' in the project", kStage, layer_name));
  return against == RegistrationReference::layer ? *layer : previous_layer(db, *layer);
}

fs::path photo_surface_file(const Project& project, const std::string& layer) {
  return project.dir() / layer_product_dir(layer) / "dense" / "points.ply";
}

// The dense points of a processed layer in the site frame. The dense stage writes
// site-frame floats unless it was asked for CRS coordinates; its header says which.
std::vector<Eigen::Vector3d> surface_points(Project& project, const LayerRecord& ref, const std::string& layer) {
  const fs::path file = photo_surface_file(project, ref.name);
  if (!fs::exists(file))
    throw InputError(fmt::format("{}: layer {} has no photogrammetric surface yet ({}): run 'strata process "
                                 "DIR --layer {}' first{}, or import the scans with --transform",
                                 kStage, ref.name, file.string(), ref.name,
                                 ref.name == layer ? " (or register --against previous)" : ""));
  std::string header(4096, '\0');
  std::ifstream(file, std::ios::binary).read(header.data(), std::streamsize(header.size()));
  const bool crs = header.find("coordinates: site CRS") != std::string::npos;
  return read_points(file, shifted_by(crs ? Eigen::Vector3d(-project.site().origin) : Eigen::Vector3d::Zero()));
}

// The box of scanner-frame points under `pose` (scanner frame -> site frame), grown.
void grow_under(ScanBounds& box, const std::vector<Eigen::Vector3d>& points, const Eigen::Matrix4d& pose) {
  for (const auto& p : points) {
    const Eigen::Vector3d q = pose.topLeftCorner<3, 3>() * p + pose.topRightCorner<3, 1>();
    box.min = box.min.cwiseMin(q);
    box.max = box.max.cwiseMax(q);
  }
}

ScanBounds empty_bounds() { return {Eigen::Vector3d::Constant(INFINITY), Eigen::Vector3d::Constant(-INFINITY)}; }

ScanBounds bounds_under(const std::vector<Eigen::Vector3d>& raw, const Eigen::Matrix4d& pose) {
  ScanBounds box = empty_bounds();
  grow_under(box, raw, pose);
  return box;
}

// The same from the scan's file, chunk by chunk: the points are not kept (a
// terrestrial scan may hold tens of millions).
ScanBounds bounds_under(const fs::path& file, const Eigen::Matrix4d& pose) {
  ScanBounds box = empty_bounds();
  read_scan_points(file, shifted_by(Eigen::Vector3d::Zero()),
                   [&](const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3f>&, const auto&) {
                     grow_under(box, points, pose);
                   });
  return box;
}

// The layer and its scans to register: `name`, or every unregistered one. Refuses a
// scan whose pose came with its file (its own CRS or transform): strata registers
// only unregistered scans or re-registers its own.
std::pair<LayerRecord, std::vector<ScanRecord>> scans_to_register(Database& db, const std::string& layer_name,
                                                                  const std::optional<std::string>& name) {
  const auto layer = find_layer(db, layer_name);
  if (!layer) throw InputError(fmt::format("{}: no layer '{}' in the project", kStage, layer_name));
  std::vector<ScanRecord> todo;
  for (const ScanRecord& s : list_scans(db, layer->id)) {
    if (name ? s.name == *name : s.registration == ScanRegistration::unregistered) todo.push_back(s);
  }
  if (name && todo.empty())
    throw InputError(fmt::format("{}: layer {} has no scan named '{}'", kStage, layer_name, *name));
  if (name && todo[0].registration != ScanRegistration::unregistered && !todo[0].fit)
    throw InputError(fmt::format("{}: {} is already registered ({}), by the file's own CRS or transform; "
                                 "strata registers only unregistered scans or re-registers its own",
                                 kStage, todo[0].name, to_string(todo[0].registration)));
  if (todo.empty()) throw InputError(fmt::format("{}: layer {} has no unregistered scan", kStage, layer_name));
  return {*layer, std::move(todo)};
}

ScanRegistrationResult register_one(Project& project, const ScanRecord& s, const ReferenceSurface& surface,
                                    const ScanRegistrationOptions& options) {
  const Stopwatch sw;
  ScanRegistrationResult r;
  r.scan = s;
  const std::vector<Eigen::Vector3d> raw = read_points(project.dir() / s.media_path, shifted_by(Eigen::Vector3d::Zero()));
  const std::vector<Eigen::Vector3d> thin = voxel_subsample(raw, options.scan_voxel_m);
  r.points_used = thin.size();
  r.surface_points = surface.oriented.points.size();
  SurfaceFit fit = fit_to_surface(thin, surface, options);
  r.coarse = fit.coarse;
  r.icp = std::move(fit.icp);
  r.pose = r.icp.pose.matrix();
  r.scan.registration = ScanRegistration::transform;
  r.scan.transform = r.pose;
  r.scan.bounds = bounds_under(raw, r.pose);
  r.seconds = sw.seconds();
  return r;
}

}  // namespace

fs::path reference_surface_file(Project& project, const std::string& layer_name, RegistrationReference against) {
  return photo_surface_file(project, reference_layer(project.db(), layer_name, against).name);
}

ReferenceSurface load_reference_surface(Project& project, const std::string& layer_name, RegistrationReference against,
                                        const ScanRegistrationOptions& options) {
  const LayerRecord ref = reference_layer(project.db(), layer_name, against);
  ReferenceSurface out;
  out.layer = ref.name;
  const std::vector<Eigen::Vector3d> raw = surface_points(project, ref, layer_name);
  out.raw_points = raw.size();
  out.points = voxel_subsample(raw, options.surface_voxel_m);
  out.oriented = estimate_normals(out.points, options.normal_radius_m);
  return out;
}

SurfaceFit fit_to_surface(const std::vector<Eigen::Vector3d>& cloud, const ReferenceSurface& surface,
                          const ScanRegistrationOptions& options) {
  SurfaceFit out;
  out.coarse = coarse_yaw_search(cloud, surface.points, options.coarse);
  out.icp = register_point_to_plane(cloud, surface.oriented, out.coarse.pose, options.icp);
  return out;
}

std::string surface_fit_refusal(double sigma_m, const IcpSummary& fit, const ScanRegistrationOptions& o) {
  const double expected = std::hypot(sigma_m, o.surface_sigma_m);
  if (fit.inlier_share < o.min_inlier_share)
    return fmt::format("too little overlap with the surface ({:.0f} % of the scan within {:.0f} mm of it, at least "
                       "{:.0f} % needed)",
                       100 * fit.inlier_share, 1000 * o.icp.min_correspondence_m, 100 * o.min_inlier_share);
  if (fit.degenerate)
    return fmt::format("the surface does not fix the pose (degenerate geometry, e.g. a flat floor: its least "
                       "constrained direction is supported by {:.2f} % of the points, at least {:.0f} % needed)",
                       100 * fit.support_share, 100 * o.icp.min_support_share);
  if (!fit.converged)
    return fmt::format("ICP did not converge in {} iterations", o.icp.max_iterations);
  if (fit.rms_m > o.max_rms_ratio * expected)
    return fmt::format("residual RMS {:.1f} mm is far above the {:.1f} mm expected of its noise (sigma {:.1f} mm "
                       "and the surface's {:.1f} mm; at most {:.1f} x)",
                       1000 * fit.rms_m, 1000 * expected, 1000 * sigma_m, 1000 * o.surface_sigma_m,
                       o.max_rms_ratio);
  return {};
}

void TargetRegistrationOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("{}: {} must be {}", kStage, field, what));
  };
  need(!scan.empty(), "scan", "given (--scan NAME: the targets belong to one scan)");
  need(!targets.empty(), "targets", "a file");
  need(target_sigma_m > 0, "target_sigma_m", "> 0 (metres)");
  need(gate_sigmas > 0, "gate_sigmas", "> 0");
  need(min_gate_m > 0, "min_gate_m", "> 0 (metres)");
  need(max_scale_error > 0 && max_scale_error < 1, "max_scale_error", "in (0, 1)");
}

void ScanRegistrationOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError(fmt::format("{}: {} must be {}", kStage, field, what));
  };
  need(scan_voxel_m > 0, "scan_voxel_m", "> 0 (metres)");
  need(surface_voxel_m > 0, "surface_voxel_m", "> 0 (metres)");
  need(normal_radius_m > surface_voxel_m, "normal_radius_m", "> surface_voxel_m (metres)");
  need(min_inlier_share > 0 && min_inlier_share < 1, "min_inlier_share", "in (0, 1)");
  need(max_rms_ratio > 0, "max_rms_ratio", "> 0");
  need(surface_sigma_m >= 0, "surface_sigma_m", ">= 0 (metres)");
  icp.validate();
}

LayerRegistrationSummary register_layer_scans(Project& project, const std::string& layer_name,
                                              const ScanRegistrationOptions& options) {
  options.validate();
  Database& db = project.db();
  const auto [layer, todo] = scans_to_register(db, layer_name, options.scan);

  LayerRegistrationSummary out;
  out.layer = layer_name;
  const ReferenceSurface surface = load_reference_surface(project, layer.name, options.against, options);
  out.reference_layer = surface.layer;
  log::info("{}: layer {}: {} scan(s) against the surface of layer {} ({} points, {} after thinning to {:.0f} mm)",
            kStage, layer_name, todo.size(), surface.layer, surface.raw_points, surface.oriented.points.size(),
            1000 * options.surface_voxel_m);

  for (const ScanRecord& s : todo) {
    ScanRegistrationResult r = register_one(project, s, surface, options);
    if (const std::string why = surface_fit_refusal(s.sigma_m, r.icp, options); !why.empty())
      throw InputError(fmt::format("{}: {}: cannot register it against the surface of layer {}: {}. Nothing was "
                                   "changed. Give its pose instead (strata import scan --transform FILE, from "
                                   "the scanner's registration software or surveyed targets)",
                                   kStage, s.name, surface.layer, why));
    r.scan.fit = ScanFit{options.against == RegistrationReference::layer ? "icp-layer" : "icp-previous", surface.layer,
                         r.icp.rms_m, r.icp.inlier_share, r.icp.sigma_translation_m, r.icp.sigma_rotation_rad};
    out.scans.push_back(std::move(r));
  }
  fault::point("register.scans.fitted");
  Transaction tx(db);
  for (const ScanRegistrationResult& r : out.scans) {
    set_scan_registered(db, r.scan.id, r.pose, *r.scan.bounds, *r.scan.fit);
    fault::point("register.scans.scan_written");
  }
  fault::point("register.scans.before_commit");
  tx.commit();
  return out;
}

TargetRegistrationResult register_scan_on_targets(Project& project, const std::string& layer_name,
                                                  const TargetRegistrationOptions& options) {
  options.validate();
  const Stopwatch sw;
  Database& db = project.db();
  const ScanRecord scan = scans_to_register(db, layer_name, options.scan).second.front();
  const std::string file = options.targets.filename().string();
  if (!project.site().origin_set)
    throw InputError(fmt::format("{}: {}: the site has no surveyed markers yet: import them first (strata import "
                                 "markers), the targets are matched to them by name",
                                 kStage, scan.name));
  std::vector<NamedPoint> measured;
  for (const ScanTarget& t : read_scan_targets(options.targets)) measured.push_back({t.name, t.scanner});
  const MarkerPairs pairs = pair_with_markers(project, measured);
  if (pairs.names.size() < 3)
    throw InputError(fmt::format("{}: {}: {} of the {} targets in {} name a surveyed marker, at least 3 needed{}",
                                 kStage, scan.name, pairs.names.size(), pairs.names.size() + pairs.unmatched.size(),
                                 options.targets.string(),
                                 pairs.unmatched.empty()
                                     ? std::string()
                                     : fmt::format(" (no marker named {})", fmt::join(pairs.unmatched, ", "))));
  const MarkerFit fit = fit_on_markers(
      pairs, MarkerFitOptions{options.target_sigma_m, options.gate_sigmas, options.min_gate_m, options.max_scale_error},
      fmt::format("{}: {}", kStage, scan.name), fmt::format("the targets of {}", file));
  TargetRegistrationResult r;
  r.scan = scan;
  r.unmatched = pairs.unmatched;
  r.pose = fit.pose;
  r.scale = fit.scale;
  r.gate_m = fit.gate_m;
  r.rms_m = fit.rms_m;
  r.inliers = fit.inliers;
  r.targets = fit.targets;
  r.sigma_translation_m = fit.sigma_translation_m;
  r.sigma_rotation_rad = fit.sigma_rotation_rad;
  for (const TargetResidual& t : r.targets) {
    if (!t.inlier)
      log::warn("{}: {}: target {} is {:.1f} mm from its marker, beyond the {:.1f} mm gate: left out", kStage,
                scan.name, t.name, 1000 * t.residual_m, 1000 * r.gate_m);
  }
  if (!r.unmatched.empty())
    log::warn("{}: {}: no surveyed marker named {}: left out", kStage, scan.name, fmt::join(r.unmatched, ", "));

  r.scan.registration = ScanRegistration::transform;
  r.scan.transform = r.pose;
  r.scan.bounds = bounds_under(project.dir() / scan.media_path, r.pose);
  r.scan.fit = ScanFit{"targets", file, r.rms_m, double(r.inliers) / double(r.targets.size()),
                       r.sigma_translation_m, r.sigma_rotation_rad};
  fault::point("register.scans.fitted");
  Transaction tx(db);
  set_scan_registered(db, r.scan.id, r.pose, *r.scan.bounds, *r.scan.fit);
  fault::point("register.scans.scan_written");
  fault::point("register.scans.before_commit");
  tx.commit();
  r.seconds = sw.seconds();
  return r;
}

}  // namespace strata
