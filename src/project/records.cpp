#include "project/records.hpp"

#include "core/error.hpp"
#include "project/gpkg.hpp"

namespace strata {
namespace {

std::optional<std::string> optional_text(const Statement& st, int col) {
  if (st.is_null(col)) return std::nullopt;
  return st.get_text(col);
}

UnitRecord read_unit(const Statement& st) {
  return UnitRecord{st.get_int(0), st.get_text(1), st.get_text(2), st.get_text(3)};
}

LayerRecord read_layer(const Statement& st) {
  return LayerRecord{st.get_int(0), st.get_text(1), st.get_text(2), optional_text(st, 3)};
}

constexpr const char* kLayerSelect =
    "SELECT l.id, l.name, u.code, l.captured_at FROM layers l JOIN units u ON u.id = l.unit_id ";

constexpr const char* kImageSelect =
    "SELECT id, layer_id, name, sha256, media_path, bytes, width, height, camera_id, "
    "captured_at, exif_ok FROM images ";

ImageRecord read_image(const Statement& st) {
  ImageRecord im;
  im.id = st.get_int(0);
  im.layer_id = st.get_int(1);
  im.name = st.get_text(2);
  im.sha256 = st.get_text(3);
  im.media_path = st.get_text(4);
  im.bytes = st.get_int(5);
  im.width = int(st.get_int(6));
  im.height = int(st.get_int(7));
  if (!st.is_null(8)) im.camera_id = st.get_int(8);
  im.captured_at = optional_text(st, 9);
  im.exif_ok = st.get_int(10) != 0;
  return im;
}

constexpr const char* kMarkerSelect =
    "SELECT fid, name, e, n, z, sigma_e, sigma_n, sigma_z, kind, source, sigma_stated FROM markers ";

MarkerRecord read_marker(const Statement& st) {
  MarkerRecord m;
  m.id = st.get_int(0);
  m.name = st.get_text(1);
  m.position = {st.get_double(2), st.get_double(3), st.get_double(4)};
  m.sigma = {st.get_double(5), st.get_double(6), st.get_double(7)};
  m.kind = st.get_text(8);
  m.source = st.get_text(9);
  m.sigma_stated = st.get_int(10) != 0;
  return m;
}

}  // namespace

const std::vector<std::string>& unit_types() {
  static const std::vector<std::string> types = {"deposit", "cut", "structure", "interface"};
  return types;
}

void update_unit(Database& db, const UnitRecord& u) {
  db.prepare("UPDATE units SET type = ?, description = ? WHERE code = ?").bind_all(u.type, u.description, u.code).run();
}

std::int64_t insert_unit(Database& db, const UnitRecord& u) {
  if (find_unit(db, u.code)) throw InputError(fmt::format("unit '{}' already exists", u.code));
  db.prepare("INSERT INTO units(code, type, description) VALUES (?, ?, ?)")
      .bind_all(u.code, u.type, u.description)
      .run();
  return db.last_insert_id();
}

std::optional<UnitRecord> find_unit(Database& db, const std::string& code) {
  auto st = db.prepare("SELECT id, code, type, description FROM units WHERE code = ?");
  st.bind(1, code);
  if (!st.step()) return std::nullopt;
  return read_unit(st);
}

UnitRecord require_unit(Database& db, const std::string& code) {
  auto u = find_unit(db, code);
  if (!u) throw InputError(fmt::format("unit '{}' does not exist (add it with 'strata unit add')", code));
  return *u;
}

std::vector<UnitRecord> list_units(Database& db) {
  auto st = db.prepare("SELECT id, code, type, description FROM units ORDER BY id");
  std::vector<UnitRecord> out;
  while (st.step()) out.push_back(read_unit(st));
  return out;
}

std::int64_t insert_relation(Database& db, const RelationRecord& r) {
  const auto a = require_unit(db, r.unit_a);
  const auto b = require_unit(db, r.unit_b);
  db.prepare("INSERT OR IGNORE INTO relations(unit_a, kind, unit_b) VALUES (?, ?, ?)")
      .bind_all(a.id, r.kind, b.id)
      .run();
  return db.changes() ? db.last_insert_id() : 0;
}

std::vector<RelationRecord> list_relations(Database& db) {
  auto st = db.prepare(
      "SELECT r.id, a.code, r.kind, b.code FROM relations r JOIN units a ON a.id = r.unit_a "
      "JOIN units b ON b.id = r.unit_b ORDER BY r.id");
  std::vector<RelationRecord> out;
  while (st.step()) out.push_back({st.get_int(0), st.get_text(1), st.get_text(2), st.get_text(3)});
  return out;
}

std::int64_t insert_layer(Database& db, const LayerRecord& l) {
  if (find_layer(db, l.name)) throw InputError(fmt::format("layer '{}' already exists", l.name));
  const auto unit = require_unit(db, l.unit);
  db.prepare("INSERT INTO layers(name, unit_id, captured_at) VALUES (?, ?, ?)")
      .bind_all(l.name, unit.id, l.captured_at)
      .run();
  return db.last_insert_id();
}

std::optional<LayerRecord> find_layer(Database& db, const std::string& name) {
  auto st = db.prepare(std::string(kLayerSelect) + "WHERE l.name = ?");
  st.bind(1, name);
  if (!st.step()) return std::nullopt;
  return read_layer(st);
}

LayerRecord require_layer(Database& db, const std::string& name) {
  auto l = find_layer(db, name);
  if (!l) throw InputError(fmt::format("layer '{}' does not exist (add it with 'strata layer add')", name));
  return *l;
}

std::vector<LayerRecord> list_layers(Database& db) {
  auto st = db.prepare(std::string(kLayerSelect) + "ORDER BY l.id");
  std::vector<LayerRecord> out;
  while (st.step()) out.push_back(read_layer(st));
  return out;
}

std::vector<MarkerResidualRecord> list_marker_residuals(Database& db, const std::string& layer) {
  auto st = db.prepare(
      "SELECT l.name, m.name, mr.role, mr.triangulated, mr.de, mr.dn, mr.dz, mr.reprojection_px, mr.images "
      "FROM marker_residuals mr JOIN markers m ON m.fid = mr.marker_id "
      "JOIN reconstructions r ON r.id = mr.reconstruction_id JOIN layers l ON l.id = r.layer_id "
      "WHERE ?1 = '' OR l.name = ?1 ORDER BY l.id, m.name");
  st.bind(1, layer);
  std::vector<MarkerResidualRecord> out;
  while (st.step()) {
    MarkerResidualRecord r;
    r.layer = st.get_text(0);
    r.marker = st.get_text(1);
    r.role = st.get_text(2);
    r.triangulated = st.get_int(3) != 0;
    if (r.triangulated) {
      r.residual_m = {st.get_optional_double(4).value_or(0), st.get_optional_double(5).value_or(0),
                      st.get_optional_double(6).value_or(0)};
      r.reprojection_px = st.get_optional_double(7).value_or(0);
    }
    r.images = int(st.get_int(8));
    out.push_back(std::move(r));
  }
  return out;
}

std::int64_t find_or_insert_camera(Database& db, const CameraRecord& c) {
  auto st = db.prepare(
      "SELECT id FROM cameras WHERE make = ? AND model = ? AND width = ? AND height = ? AND "
      "focal_mm IS ?");
  st.bind_all(c.make, c.model, c.width, c.height, c.focal_mm);
  if (st.step()) return st.get_int(0);
  db.prepare(
        "INSERT INTO cameras(make, model, width, height, focal_mm, focal_35mm, sensor_width_mm, "
        "focal_px, focal_source) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)")
      .bind_all(c.make, c.model, c.width, c.height, c.focal_mm, c.focal_35mm, c.sensor_width_mm,
                c.focal_px, c.focal_source)
      .run();
  return db.last_insert_id();
}

std::optional<CameraRecord> find_camera(Database& db, std::int64_t id) {
  auto st = db.prepare(
      "SELECT id, make, model, width, height, focal_mm, focal_35mm, sensor_width_mm, focal_px, "
      "focal_source FROM cameras WHERE id = ?");
  st.bind(1, id);
  if (!st.step()) return std::nullopt;
  CameraRecord c;
  c.id = st.get_int(0);
  c.make = st.get_text(1);
  c.model = st.get_text(2);
  c.width = int(st.get_int(3));
  c.height = int(st.get_int(4));
  c.focal_mm = st.get_optional_double(5);
  c.focal_35mm = st.get_optional_double(6);
  c.sensor_width_mm = st.get_optional_double(7);
  c.focal_px = st.get_optional_double(8);
  c.focal_source = st.get_text(9);
  return c;
}

std::int64_t insert_image(Database& db, const ImageRecord& im) {
  db.prepare(
        "INSERT INTO images(layer_id, name, sha256, media_path, bytes, width, height, camera_id, "
        "captured_at, exif_ok, imported_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
        "strftime('%Y-%m-%dT%H:%M:%SZ','now'))")
      .bind_all(im.layer_id, im.name, im.sha256, im.media_path, im.bytes, im.width, im.height,
                im.camera_id, im.captured_at, im.exif_ok ? 1 : 0)
      .run();
  return db.last_insert_id();
}

std::optional<ImageRecord> find_image_by_sha(Database& db, const std::string& sha256) {
  auto st = db.prepare(std::string(kImageSelect) + "WHERE sha256 = ?");
  st.bind(1, sha256);
  if (!st.step()) return std::nullopt;
  return read_image(st);
}

std::vector<ImageRecord> find_images_by_name(Database& db, const std::string& name) {
  auto st = db.prepare(std::string(kImageSelect) + "WHERE name = ? ORDER BY id");
  st.bind(1, name);
  std::vector<ImageRecord> out;
  while (st.step()) out.push_back(read_image(st));
  return out;
}

std::vector<ImageRecord> list_images(Database& db, std::optional<std::int64_t> layer_id) {
  auto st = db.prepare(std::string(kImageSelect) +
                       (layer_id ? "WHERE layer_id = ? ORDER BY name" : "ORDER BY layer_id, name"));
  if (layer_id) st.bind(1, *layer_id);
  std::vector<ImageRecord> out;
  while (st.step()) out.push_back(read_image(st));
  return out;
}

std::optional<MarkerRecord> find_marker(Database& db, const std::string& name) {
  auto st = db.prepare(std::string(kMarkerSelect) + "WHERE name = ?");
  st.bind(1, name);
  if (!st.step()) return std::nullopt;
  return read_marker(st);
}

std::int64_t upsert_marker(Database& db, const MarkerRecord& m, int srs_id) {
  const auto geom = gpkg_point_z(srs_id, m.position);
  if (auto existing = find_marker(db, m.name)) {
    auto st = db.prepare(
        "UPDATE markers SET geom = ?, e = ?, n = ?, z = ?, sigma_e = ?, sigma_n = ?, sigma_z = ?, "
        "kind = ?, source = ?, sigma_stated = ? WHERE fid = ?");
    st.bind_blob(1, geom);
    st.bind(2, m.position.x()).bind(3, m.position.y()).bind(4, m.position.z());
    st.bind(5, m.sigma.x()).bind(6, m.sigma.y()).bind(7, m.sigma.z());
    st.bind(8, m.kind).bind(9, m.source).bind(10, m.sigma_stated ? 1 : 0).bind(11, existing->id);
    st.run();
    return existing->id;
  }
  auto st = db.prepare(
      "INSERT INTO markers(geom, name, e, n, z, sigma_e, sigma_n, sigma_z, kind, source, sigma_stated) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  st.bind_blob(1, geom);
  st.bind(2, m.name);
  st.bind(3, m.position.x()).bind(4, m.position.y()).bind(5, m.position.z());
  st.bind(6, m.sigma.x()).bind(7, m.sigma.y()).bind(8, m.sigma.z());
  st.bind(9, m.kind).bind(10, m.source).bind(11, m.sigma_stated ? 1 : 0);
  st.run();
  return db.last_insert_id();
}

std::vector<MarkerRecord> list_markers(Database& db) {
  auto st = db.prepare(std::string(kMarkerSelect) + "ORDER BY name");
  std::vector<MarkerRecord> out;
  while (st.step()) out.push_back(read_marker(st));
  return out;
}

bool upsert_observation(Database& db, const ObservationRecord& o) {
  auto existing = db.prepare(
      "SELECT 1 FROM observations WHERE marker_id = ? AND image_id = ? AND source = ?");
  existing.bind_all(o.marker_id, o.image_id, o.source);
  const bool existed = existing.step();
  db.prepare(
        "INSERT INTO observations(marker_id, image_id, x, y, source) VALUES (?, ?, ?, ?, ?) "
        "ON CONFLICT(marker_id, image_id, source) DO UPDATE SET x = excluded.x, y = excluded.y")
      .bind_all(o.marker_id, o.image_id, o.pixel.x(), o.pixel.y(), o.source)
      .run();
  return !existed;
}

std::vector<ObservationRecord> list_observations(Database& db, std::optional<std::int64_t> layer_id) {
  std::string sql =
      "SELECT o.id, o.marker_id, o.image_id, o.x, o.y, o.source FROM observations o "
      "JOIN images i ON i.id = o.image_id ";
  if (layer_id) sql += "WHERE i.layer_id = ? ";
  sql += "ORDER BY o.image_id, o.marker_id";
  auto st = db.prepare(sql);
  if (layer_id) st.bind(1, *layer_id);
  std::vector<ObservationRecord> out;
  while (st.step()) {
    out.push_back({st.get_int(0), st.get_int(1), st.get_int(2),
                   Eigen::Vector2d(st.get_double(3), st.get_double(4)), st.get_text(5)});
  }
  return out;
}

}  // namespace strata

#include "core/hash.hpp"

namespace strata {
namespace {
constexpr const char* kProductSelect =
    "SELECT id, layer_id, unit_id, kind, path, sha256, bytes, params_json FROM products ";
ProductRecord read_product(const Statement& st) {
  ProductRecord p;
  p.id = st.get_int(0);
  if (!st.is_null(1)) p.layer_id = st.get_int(1);
  if (!st.is_null(2)) p.unit_id = st.get_int(2);
  p.kind = st.get_text(3);
  p.path = st.get_text(4);
  p.sha256 = st.get_text(5);
  p.bytes = st.get_int(6);
  p.params_json = st.get_text(7);
  return p;
}
}  // namespace

std::int64_t record_product(Database& db, const std::filesystem::path& project_dir, ProductRecord p) {
  const auto file = project_dir / p.path;
  p.sha256 = sha256_file(file);
  p.bytes = std::int64_t(std::filesystem::file_size(file));
  db.prepare("DELETE FROM products WHERE path = ?").bind_all(p.path).run();
  db.prepare(
        "INSERT INTO products(layer_id, unit_id, kind, path, sha256, bytes, params_json, created_at) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ','now'))")
      .bind_all(p.layer_id, p.unit_id, p.kind, p.path, p.sha256, p.bytes, p.params_json)
      .run();
  return db.last_insert_id();
}

std::vector<ProductRecord> list_products(Database& db, std::optional<std::int64_t> layer_id,
                                         const std::string& kind) {
  std::string sql = std::string(kProductSelect) + "WHERE 1 ";
  if (layer_id) sql += "AND layer_id = ? ";
  if (!kind.empty()) sql += "AND kind = ? ";
  sql += "ORDER BY id";
  auto st = db.prepare(sql);
  int i = 1;
  if (layer_id) st.bind(i++, *layer_id);
  if (!kind.empty()) st.bind(i++, kind);
  std::vector<ProductRecord> out;
  while (st.step()) out.push_back(read_product(st));
  return out;
}

std::optional<ProductRecord> find_product(Database& db, std::int64_t layer_id, const std::string& kind) {
  auto all = list_products(db, layer_id, kind);
  if (all.empty()) return std::nullopt;
  return all.back();
}

}  // namespace strata
