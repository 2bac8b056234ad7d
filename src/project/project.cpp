#include "project/project.hpp"

#include "core/time.hpp"
#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"
#include "crs/crs.hpp"
#include "project/gpkg.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <string_view>
#include <vector>

namespace strata {
namespace schema {
const std::vector<std::pair<std::string_view, std::string_view>>& migration_files();
}

namespace fs = std::filesystem;
namespace {

// "0003_products.sql" -> 3
int migration_number(std::string_view file) {
  int n = 0;
  for (char c : file) {
    if (c < '0' || c > '9') break;
    n = n * 10 + (c - '0');
  }
  return n;
}

bool has_meta_table(Database& db) {
  return db.query_int("SELECT count(*) FROM sqlite_master WHERE type='table' AND name='strata_meta'")
             .value_or(0) > 0;
}

// 0 for a database without strata's tables (one being created). A version that is
// not a whole number comes from a damaged or foreign file: refused, not guessed.
int current_version(Database& db) {
  if (!has_meta_table(db)) return 0;
  const auto v = db.query_text("SELECT value FROM strata_meta WHERE key='schema_version'");
  if (v) {
    int n = 0;
    const auto [end, ec] = std::from_chars(v->data(), v->data() + v->size(), n);
    if (ec == std::errc() && end == v->data() + v->size() && n >= 1) return n;
  }
  throw IoError(fmt::format("{}: the schema version in strata_meta is {}; the file is damaged or was not made "
                            "by strata",
                            db.path().string(), v ? "'" + *v + "', not a version number" : "missing"));
}

// The columns of a table; empty when there is no such table.
std::set<std::string> columns_of(Database& db, const std::string& table) {
  auto st = db.prepare("SELECT name FROM pragma_table_info(?)");
  st.bind(1, table);
  std::set<std::string> names;
  while (st.step()) names.insert(st.get_text(0));
  return names;
}

// Every table strata's migrations create, with its columns: what this build expects
// of a project at the latest schema (read once from an in-memory database).
const std::map<std::string, std::set<std::string>>& expected_tables() {
  static const std::map<std::string, std::set<std::string>> expected = [] {
    Database db(":memory:", true);
    apply_migrations(db);
    std::map<std::string, std::set<std::string>> tables;
    auto st = db.prepare("SELECT name FROM sqlite_master WHERE type='table' AND name NOT LIKE 'sqlite\\_%' ESCAPE '\\'");
    while (st.step()) tables[st.get_text(0)];
    for (auto& [table, columns] : tables) columns = columns_of(db, table);
    return tables;
  }();
  return expected;
}

// A project that another program altered (a table dropped, a column renamed) is
// refused at open with what is missing, rather than failing later in some command.
// Extra tables and columns (QGIS styles, GeoPackage extensions) are fine.
void require_strata_tables(Database& db) {
  for (const auto& [table, expected] : expected_tables()) {
    const std::set<std::string> found = columns_of(db, table);
    if (found.empty()) {
      throw IoError(fmt::format("{}: strata's table '{}' is missing; the file was altered by another program "
                                "or is damaged",
                                db.path().string(), table));
    }
    for (const auto& column : expected) {
      if (!found.count(column)) {
        throw IoError(fmt::format("{}: strata's table '{}' has no column '{}'; the file was altered by another "
                                  "program or is damaged",
                                  db.path().string(), table, column));
      }
    }
  }
}

}  // namespace

int latest_schema_version() {
  int v = 0;
  for (const auto& [name, sql] : schema::migration_files()) v = std::max(v, migration_number(name));
  return v;
}

int apply_migrations(Database& db) {
  const int from = current_version(db);
  const int latest = latest_schema_version();
  if (from > latest) {
    throw IoError(fmt::format(
        "{}: schema version {} is newer than this strata understands ({}); update strata",
        db.path().string(), from, latest));
  }
  auto files = schema::migration_files();
  std::sort(files.begin(), files.end());
  int applied = 0;
  for (const auto& [name, sql] : files) {
    const int n = migration_number(name);
    if (n <= from) continue;
    Transaction tx(db);
    db.exec(sql);
    db.prepare("INSERT OR REPLACE INTO strata_meta(key, value) VALUES ('schema_version', ?)")
        .bind_all(std::to_string(n))
        .run();
    fault::point("db.migration_applied");
    tx.commit();
    ++applied;
  }
  return applied;
}

Project::Project(fs::path dir, std::unique_ptr<Database> db)
    : dir_(std::move(dir)), db_(std::move(db)) {}

Project Project::create(const fs::path& dir, const CreateOptions& options) {
  const CrsInfo crs = describe_crs(options.crs);
  require_site_crs(crs);
  if (fs::exists(dir / kDatabaseName)) {
    throw InputError(fmt::format("{}: already a strata project", dir.string()));
  }
  if (fs::exists(dir) && !fs::is_directory(dir)) {
    throw InputError(fmt::format("{}: exists and is not a folder", dir.string()));
  }
  const bool dir_existed = fs::exists(dir);
  // Build the database under a temporary name and rename it into place last, so a
  // failure leaves no half-made project behind.
  const fs::path tmp = dir / ".project.gpkg.tmp";
  try {
    fs::create_directories(dir);
    fs::remove(tmp);
    {
      auto db = std::make_unique<Database>(tmp, true);
      fault::point("init.database_created");
      // GeoPackage identification (OGC 12-128, requirements 2 and 3).
      db->exec("PRAGMA application_id = 1196444487");  // 'GPKG'
      db->exec("PRAGMA user_version = 10200");          // GeoPackage 1.2.0
      apply_migrations(*db);
      Transaction tx(*db);
      const int srs_id = register_srs(*db, crs);
      const std::string name = options.name.empty() ? fs::absolute(dir).filename().string()
                                                    : options.name;
      const Eigen::Vector3d origin = options.origin.value_or(Eigen::Vector3d::Zero());
      db->prepare(
            "INSERT INTO site(id, name, crs, srs_id, origin_e, origin_n, origin_z, origin_set, "
            "created_at) VALUES (1, ?, ?, ?, ?, ?, ?, ?, ?)")
          .bind_all(name, crs.label(), srs_id, origin.x(), origin.y(), origin.z(),
                    options.origin ? 1 : 0, utc_now_iso())
          .run();
      register_feature_tables(*db, srs_id);
      fault::point("init.before_commit");
      tx.commit();
      db->exec("PRAGMA wal_checkpoint(TRUNCATE)");
    }
    fs::remove(fs::path(tmp.string() + "-wal"));
    fs::remove(fs::path(tmp.string() + "-shm"));
    for (const char* sub : {"media", "cache", "products"}) fs::create_directories(dir / sub);
    fs::rename(tmp, dir / kDatabaseName);
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    if (!dir_existed) fs::remove_all(dir, ec);
    throw;
  }
  return open(dir);
}

Project Project::open(const fs::path& dir) {
  const fs::path db_path = dir / kDatabaseName;
  if (!fs::exists(db_path)) {
    throw InputError(fmt::format("{}: not a strata project (no {}); create one with 'strata init'",
                                 dir.string(), kDatabaseName));
  }
  auto db = std::make_unique<Database>(db_path, false);
  const auto app_id = db->query_int("PRAGMA application_id").value_or(0);
  if (app_id != 1196444487) {
    throw InputError(fmt::format("{}: not a GeoPackage made by strata", db_path.string()));
  }
  // Project::create writes strata_meta before the file gets its name: a GeoPackage
  // without it was made by another program, and migrating it would fail half-way.
  if (!has_meta_table(*db)) {
    throw InputError(fmt::format("{}: a GeoPackage, but not a strata project (it has no strata_meta table)",
                                 db_path.string()));
  }
  const int before = current_version(*db);
  const int applied = apply_migrations(*db);
  if (applied > 0) log::info("upgraded project schema from version {} to {}", before, latest_schema_version());
  require_strata_tables(*db);
  Project p(dir, std::move(db));
  if (applied > 0) register_feature_tables(p.db(), p.site().srs_id);
  return p;
}

SiteInfo Project::site() {
  auto st = db_->prepare(
      "SELECT name, crs, srs_id, origin_e, origin_n, origin_z, origin_set FROM site WHERE id = 1");
  if (!st.step()) throw IoError(fmt::format("{}: the site record is missing", database_path().string()));
  SiteInfo s;
  s.name = st.get_text(0);
  s.crs = st.get_text(1);
  s.srs_id = int(st.get_int(2));
  s.origin = {st.get_double(3), st.get_double(4), st.get_double(5)};
  s.origin_set = st.get_int(6) != 0;
  return s;
}

void Project::set_origin_if_unset(const Eigen::Vector3d& near) {
  if (site().origin_set) return;
  const Eigen::Vector3d origin(std::floor(near.x() / 100.0) * 100.0,
                               std::floor(near.y() / 100.0) * 100.0, std::floor(near.z()));
  db_->prepare("UPDATE site SET origin_e = ?, origin_n = ?, origin_z = ?, origin_set = 1 WHERE id = 1")
      .bind_all(origin.x(), origin.y(), origin.z())
      .run();
}

int Project::schema_version() { return current_version(*db_); }

}  // namespace strata
