#include "project/find_records.hpp"

#include "project/gpkg.hpp"

namespace strata {
namespace {

constexpr const char* kFindSelect =
    "SELECT fid, find_id, unit, type, description, e, n, z, source, imported_at FROM finds ";

FindRecord read_find(const Statement& st) {
  FindRecord f;
  f.fid = st.get_int(0);
  f.id = st.get_text(1);
  f.unit = st.get_text(2);
  f.type = st.get_text(3);
  f.description = st.get_text(4);
  f.position = {st.get_double(5), st.get_double(6), st.get_double(7)};
  f.source = st.get_text(8);
  f.imported_at = st.get_text(9);
  return f;
}

}  // namespace

std::optional<FindRecord> find_find(Database& db, const std::string& id) {
  auto st = db.prepare(std::string(kFindSelect) + "WHERE find_id = ?");
  st.bind(1, id);
  if (!st.step()) return std::nullopt;
  return read_find(st);
}

std::int64_t upsert_find(Database& db, const FindRecord& f, int srs_id) {
  auto st = db.prepare(
      "INSERT INTO finds(geom, find_id, unit, type, description, e, n, z, source, imported_at) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ','now')) "
      "ON CONFLICT(find_id) DO UPDATE SET geom = excluded.geom, unit = excluded.unit, type = excluded.type, "
      "description = excluded.description, e = excluded.e, n = excluded.n, z = excluded.z, "
      "source = excluded.source, imported_at = excluded.imported_at");
  st.bind_blob(1, gpkg_point_z(srs_id, f.position));
  st.bind(2, f.id).bind(3, f.unit).bind(4, f.type).bind(5, f.description);
  st.bind(6, f.position.x()).bind(7, f.position.y()).bind(8, f.position.z());
  st.bind(9, f.source);
  st.run();
  return find_find(db, f.id)->fid;
}

std::vector<FindRecord> list_finds(Database& db) {
  auto st = db.prepare(std::string(kFindSelect) + "ORDER BY find_id");
  std::vector<FindRecord> out;
  while (st.step()) out.push_back(read_find(st));
  return out;
}

}  // namespace strata
