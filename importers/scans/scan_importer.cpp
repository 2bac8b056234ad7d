#include "importers/scans/scan_importer.hpp"

#include "core/door.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/hash.hpp"
#include "core/progress.hpp"
#include "crs/crs.hpp"
#include "importers/scans/scan_formats.hpp"
#include "project/media.hpp"
#include "project/records.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <cmath>
#include <fstream>
#include <map>

namespace fs = std::filesystem;

namespace strata {
namespace {

using scan_formats::kStage;
constexpr const char* kTransformStage = "importer.scans.transform";

// A transform file's 3x3 part must be s R to this (relative to s^2, per entry of
// M^T M / s^2 - I, and per entry of the last row): six printed decimals, as most
// registration tools write, round R's entries by 5e-7, well inside it.
constexpr double kSimilarityTolerance = 1e-5;
// An excavation's site frame spans at most a few hundred metres: a registered scan
// whose box lies farther than this from the site origin was given the wrong CRS, or
// a transform into CRS coordinates instead of the site frame.
constexpr double kMaxDistanceFromOriginM = 10000.0;

struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Constant(HUGE_VAL);
  Eigen::Vector3d max = Eigen::Vector3d::Constant(-HUGE_VAL);
  void extend(const Eigen::Vector3d& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  Eigen::Vector3d corner(int k) const {
    return {(k & 1) ? max.x() : min.x(), (k & 2) ? max.y() : min.y(), (k & 4) ? max.z() : min.z()};
  }
};

struct Candidate {
  fs::path path;
  std::string sha;
  PointCloudInfo info;
  Box frame_box;  // 'transform': exact box of the transformed points, site frame
  Box crs_box;    // 'survey': box in the site CRS (absolute coordinates)
};

void validate(const ScanImportOptions& o, const std::vector<fs::path>& files) {
  if (files.empty()) throw InputError(fmt::format("{}: no scan files given", kStage));
  if (!std::isfinite(o.sigma_m) || o.sigma_m <= 0) {
    throw InputError(fmt::format("{}: --sigma {} must be a range noise in metres > 0 (e.g. 0.005)", kStage, o.sigma_m));
  }
  if (o.crs && o.transform) {
    throw InputError(fmt::format("{}: --crs and --transform exclude each other: --crs for a scan already in a "
                                 "surveyed CRS, --transform for one in its own frame with a known pose",
                                 kStage));
  }
}

// A survey-registered scan's box in the site CRS: its 8 corners transformed. Over
// the tens of metres a scan spans a projection change bends straight lines by far
// less than a millimetre, so the corners bound the transformed points.
Box box_in_site_crs(const PointCloudInfo& info, const CrsTransform& to_site, const fs::path& file,
                    const std::string& crs, const std::string& site_crs) {
  Box source{info.min, info.max}, out;
  for (int k = 0; k < 8; ++k) {
    try {
      out.extend(to_site.apply(source.corner(k)));
    } catch (const CrsError& e) {
      throw InputError(fmt::format("{}: {}: its bounding box does not transform from {} into the site CRS {}: {}",
                                   kStage, file.string(), crs, site_crs, e.what()));
    }
  }
  return out;
}

// Reads and checks every point of a file: the count, the box (in the site frame
// when a transform is given).
void read_points(Candidate& c, const std::optional<ScanTransform>& transform) {
  c.info = read_point_cloud_chunks(c.path, [&](const PointCloud& chunk, std::uint64_t) {
    check_cancelled();
    if (!transform) return;
    for (const auto& p : chunk.positions) c.frame_box.extend(transform->similarity.apply(p));
  });
}

void require_near_site(const ImportedScan& s, const std::string& how) {
  const double far = std::max(s.bounds->min.cwiseAbs().maxCoeff(), s.bounds->max.cwiseAbs().maxCoeff());
  if (far > kMaxDistanceFromOriginM) {
    throw InputError(fmt::format("{}: {}: the scan lies {:.1f} km from the site origin; {}", kStage, s.file,
                                 far / 1000.0, how));
  }
}

// Refuses a scan whose content is in another layer, or another scan of this layer
// with the same file name; true when the same content is already in this layer.
bool already_in_layer(Database& db, const LayerRecord& layer, const Candidate& c) {
  if (auto existing = find_scan_by_sha(db, c.sha)) {
    if (existing->layer_id == layer.id) return true;
    std::string other = "another layer";
    for (const auto& l : list_layers(db))
      if (l.id == existing->layer_id) other = "layer " + l.name;
    throw InputError(fmt::format("{}: {}: the same scan is already in {} (as {}); a scan records one layer; "
                                 "nothing was imported",
                                 kStage, c.path.string(), other, existing->name));
  }
  const std::string name = c.path.filename().string();
  for (const auto& s : list_scans(db, layer.id)) {
    if (s.name == name) {
      throw InputError(fmt::format("{}: {}: a different scan named '{}' is already in layer {}; rename one of them",
                                   kStage, c.path.string(), name, layer.name));
    }
  }
  return false;
}

}  // namespace

ScanTransform read_scan_transform(const fs::path& file) {
  const scan_formats::SourceFile source(kTransformStage, file);
  std::ifstream in(file);
  if (!in) throw IoError(fmt::format("{}: {}: cannot be opened for reading", kTransformStage, file.string()));
  std::vector<double> v;
  scan_formats::TextLines lines(in);
  while (lines.next()) {
    for (const auto& f : lines.fields()) {
      if (v.size() == 16) throw source.error(lines.position(), "more than 16 numbers (a 4x4 matrix, row-major)");
      v.push_back(scan_formats::parse_number(f, "matrix entry", source, lines.position()));
      if (!std::isfinite(v.back())) throw source.error(lines.position(), "a matrix entry is not finite");
    }
  }
  if (v.size() != 16) throw source.error(fmt::format("expected 16 numbers (a 4x4 matrix, row-major), found {}", v.size()));
  ScanTransform t;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) t.matrix(r, c) = v[std::size_t(4 * r + c)];
  const Eigen::RowVector4d last = t.matrix.row(3);
  if ((last - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kSimilarityTolerance) {
    throw source.error(fmt::format("not a rigid or similarity transform: the last row is {} {} {} {}, not 0 0 0 1",
                                   last[0], last[1], last[2], last[3]));
  }
  const Eigen::Matrix3d m = t.matrix.topLeftCorner<3, 3>();
  const double det = m.determinant();
  if (!(det > 0)) {
    throw source.error(fmt::format("not a rigid or similarity transform: the 3x3 part has determinant {} (a "
                                   "reflection or a collapse)",
                                   det));
  }
  const double scale = std::cbrt(det);
  const double shear = (m.transpose() * m / (scale * scale) - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (shear > kSimilarityTolerance) {
    throw source.error(fmt::format("not a rigid or similarity transform: the 3x3 part is not a scale times a "
                                   "rotation (|M^T M / s^2 - I| = {:.2g}, tolerance {:.0e})",
                                   shear, kSimilarityTolerance));
  }
  // The nearest rotation (polar decomposition through the SVD), so that the pose is
  // exactly a similarity.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m / scale, Eigen::ComputeFullU | Eigen::ComputeFullV);
  t.similarity.scale = scale;
  t.similarity.R = svd.matrixU() * svd.matrixV().transpose();
  t.similarity.t = t.matrix.topRightCorner<3, 1>();
  return t;
}

ScanImportSummary import_scans(Project& project, const ScanImportOptions& options, const std::vector<fs::path>& files) {
  validate(options, files);
  auto& db = project.db();
  const LayerRecord layer = require_layer(db, options.layer);
  SiteInfo site = project.site();

  std::optional<CrsTransform> to_site;
  std::string crs_label;
  if (options.crs) {
    to_site = transform_into_site(*options.crs, site.crs, fmt::format("{}: --crs", kStage));
    crs_label = describe_crs(*options.crs).label();
  }
  std::optional<ScanTransform> transform;
  if (options.transform) {
    if (!site.origin_set) {
      throw InputError(fmt::format("{}: --transform {}: the site frame has no origin yet; import the markers "
                                   "first (or give 'strata init' an --origin)",
                                   kStage, options.transform->string()));
    }
    transform = read_scan_transform(*options.transform);
  }
  const ScanRegistration registration = options.crs        ? ScanRegistration::survey
                                        : options.transform ? ScanRegistration::transform
                                                            : ScanRegistration::unregistered;

  ScanImportSummary summary;
  std::vector<Candidate> good;
  std::map<std::string, std::string> seen_in_batch;  // sha -> file
  {
    Progress progress("reading scans", files.size());
    for (const auto& f : files) {
      progress.step();
      std::error_code ec;
      door::input_file(f, fmt::format("{}: scan", kStage));
      Candidate c{f, sha256_file(f), {}, {}, {}};
      if (auto it = seen_in_batch.find(c.sha); it != seen_in_batch.end()) {
        summary.already_present.push_back(fmt::format("{} (same content as {} in this batch)", f.string(), it->second));
        continue;
      }
      seen_in_batch[c.sha] = f.string();
      // The same content again is not read through: it was checked when first imported.
      if (already_in_layer(db, layer, c)) {
        summary.already_present.push_back(fmt::format("{} (already imported in layer {})", f.string(), layer.name));
        continue;
      }
      read_points(c, transform);
      if (to_site) c.crs_box = box_in_site_crs(c.info, *to_site, f, crs_label, site.crs);
      good.push_back(std::move(c));
    }
    progress.finish();
  }
  fault::point("import.scans.checked");

  Transaction tx(db);
  MediaBatch media(project.media_dir());
  if (to_site && !good.empty()) {
    project.set_origin_if_unset(0.5 * (good.front().crs_box.min + good.front().crs_box.max));
    site = project.site();
  }
  for (const auto& c : good) {
    check_cancelled();
    ImportedScan s{c.path.string(), c.info, registration, std::nullopt};
    if (registration == ScanRegistration::survey) {
      s.bounds = ScanBounds{c.crs_box.min - site.origin, c.crs_box.max - site.origin};
      require_near_site(s, fmt::format("are its coordinates really in {}?", crs_label));
    } else if (registration == ScanRegistration::transform) {
      s.bounds = ScanBounds{c.frame_box.min, c.frame_box.max};
      require_near_site(s, fmt::format("does {} map into the site frame (site CRS minus the origin {:.1f}, {:.1f}, "
                                       "{:.1f})?",
                                       options.transform->string(), site.origin.x(), site.origin.y(), site.origin.z()));
    }
    ScanRecord r;
    r.layer_id = layer.id;
    r.name = c.path.filename().string();
    r.sha256 = c.sha;
    r.media_path = media.store(c.path, c.sha);
    fault::point("import.scans.media_stored");
    r.bytes = std::int64_t(fs::file_size(c.path));
    r.format = c.info.format;
    r.points = std::int64_t(c.info.points);
    r.has_colour = c.info.has_colour;
    r.has_intensity = c.info.has_intensity;
    r.has_normals = c.info.has_normals;
    r.sigma_m = options.sigma_m;
    r.registration = registration;
    if (options.crs) r.crs = crs_label;
    if (transform) r.transform = transform->matrix;
    r.bounds = s.bounds;
    insert_scan(db, r);
    fault::point("import.scans.row_inserted");
    summary.imported.push_back(std::move(s));
  }
  fault::point("import.scans.before_commit");
  tx.commit();
  fault::point("import.scans.after_commit");
  media.commit();
  return summary;
}

}  // namespace strata
