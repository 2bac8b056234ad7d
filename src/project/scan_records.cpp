#include "project/scan_records.hpp"

#include "core/error.hpp"
#include "project/matrix_text.hpp"

namespace strata {
namespace {

constexpr const char* kScanSelect =
    "SELECT id, layer_id, name, sha256, media_path, bytes, format, points, has_colour, has_intensity, has_normals, "
    "sigma_m, registration, crs, transform, min_x, min_y, min_z, max_x, max_y, max_z, imported_at, "
    "registered_by, registered_against, registration_rms_m, registration_inliers, registration_sigma_t_m, "
    "registration_sigma_r_rad FROM scans ";

Eigen::Matrix4d parse_matrix(const std::string& text, std::int64_t id) {
  return parse_matrix_text(text, fmt::format("scans: the transform of scan {}", id));
}

ScanRecord read_scan(const Statement& st) {
  ScanRecord s;
  s.id = st.get_int(0);
  s.layer_id = st.get_int(1);
  s.name = st.get_text(2);
  s.sha256 = st.get_text(3);
  s.media_path = st.get_text(4);
  s.bytes = st.get_int(5);
  s.format = st.get_text(6);
  s.points = st.get_int(7);
  s.has_colour = st.get_int(8) != 0;
  s.has_intensity = st.get_int(9) != 0;
  s.has_normals = st.get_int(10) != 0;
  s.sigma_m = st.get_double(11);
  s.registration = parse_scan_registration(st.get_text(12));
  if (!st.is_null(13)) s.crs = st.get_text(13);
  if (!st.is_null(14)) s.transform = parse_matrix(st.get_text(14), s.id);
  if (!st.is_null(15)) {
    s.bounds = ScanBounds{{st.get_double(15), st.get_double(16), st.get_double(17)},
                          {st.get_double(18), st.get_double(19), st.get_double(20)}};
  }
  s.imported_at = st.get_text(21);
  if (!st.is_null(22)) {
    s.fit = ScanFit{st.get_text(22), st.is_null(23) ? "" : st.get_text(23), st.get_double(24), st.get_double(25),
                    st.get_double(26), st.get_double(27)};
  }
  return s;
}

}  // namespace

const char* to_string(ScanRegistration r) {
  switch (r) {
    case ScanRegistration::survey: return "survey";
    case ScanRegistration::transform: return "transform";
    case ScanRegistration::unregistered: return "unregistered";
  }
  return "unregistered";
}

ScanRegistration parse_scan_registration(const std::string& text) {
  for (auto r : {ScanRegistration::survey, ScanRegistration::transform, ScanRegistration::unregistered})
    if (text == to_string(r)) return r;
  throw IoError(fmt::format("scans: unknown registration state '{}'", text));
}

std::int64_t insert_scan(Database& db, const ScanRecord& s) {
  auto st = db.prepare(
      "INSERT INTO scans(layer_id, name, sha256, media_path, bytes, format, points, has_colour, has_intensity, "
      "has_normals, sigma_m, registration, crs, transform, min_x, min_y, min_z, max_x, max_y, max_z, imported_at) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ','now'))");
  st.bind_all(s.layer_id, s.name, s.sha256, s.media_path, s.bytes, s.format, s.points, int(s.has_colour),
              int(s.has_intensity), int(s.has_normals), s.sigma_m, to_string(s.registration), s.crs);
  if (s.transform) st.bind(14, matrix_text(*s.transform));
  else st.bind_null(14);
  for (int a = 0; a < 3; ++a) {
    st.bind(15 + a, s.bounds ? std::optional<double>(s.bounds->min[a]) : std::nullopt);
    st.bind(18 + a, s.bounds ? std::optional<double>(s.bounds->max[a]) : std::nullopt);
  }
  st.run();
  return db.last_insert_id();
}

void set_scan_registered(Database& db, std::int64_t scan_id, const Eigen::Matrix4d& transform,
                         const ScanBounds& bounds, const ScanFit& fit) {
  auto st = db.prepare(
      "UPDATE scans SET registration = 'transform', crs = NULL, transform = ?, min_x = ?, min_y = ?, min_z = ?, "
      "max_x = ?, max_y = ?, max_z = ?, registered_by = ?, registered_against = ?, registration_rms_m = ?, "
      "registration_inliers = ?, registration_sigma_t_m = ?, registration_sigma_r_rad = ? WHERE id = ?");
  st.bind_all(matrix_text(transform), bounds.min.x(), bounds.min.y(), bounds.min.z(), bounds.max.x(), bounds.max.y(),
              bounds.max.z(), fit.method, fit.against, fit.rms_m, fit.inlier_share, fit.sigma_translation_m,
              fit.sigma_rotation_rad, scan_id);
  st.run();
  STRATA_CHECK(db.changes() == 1, "scan to register not found");
}

std::optional<ScanRecord> find_scan_by_sha(Database& db, const std::string& sha256) {
  auto st = db.prepare(std::string(kScanSelect) + "WHERE sha256 = ?");
  st.bind(1, sha256);
  if (!st.step()) return std::nullopt;
  return read_scan(st);
}

std::vector<ScanRecord> list_scans(Database& db, std::optional<std::int64_t> layer_id) {
  auto st = db.prepare(std::string(kScanSelect) + (layer_id ? "WHERE layer_id = ? " : "") + "ORDER BY id");
  if (layer_id) st.bind(1, *layer_id);
  std::vector<ScanRecord> out;
  while (st.step()) out.push_back(read_scan(st));
  return out;
}

}  // namespace strata
