#include "project/database.hpp"

#include "core/error.hpp"
#include "core/fault.hpp"
#include "core/log.hpp"

#include <sqlite3.h>

namespace strata {

Database::Database(const std::filesystem::path& path, bool create) : path_(path) {
  const int flags = SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) |
                    SQLITE_OPEN_FULLMUTEX;
  if (sqlite3_open_v2(path.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
    std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw IoError(fmt::format("{}: cannot open database: {}", path.string(), msg));
  }
  sqlite3_extended_result_codes(db_, 1);
  // SQLite reads the file only now: a file that is not a database (or a damaged one)
  // fails here, and the destructor of a half-made object does not run.
  try {
    // A writer that closes the last connection checkpoints the WAL under an exclusive
    // lock: a reader opening meanwhile waits for it rather than failing.
    sqlite3_busy_timeout(db_, 10000);
    exec("PRAGMA foreign_keys = ON");
    // Switching to WAL needs the database to itself. It is done once (the mode is
    // stored in the file); when another program (QGIS, GDAL) has meanwhile set another
    // mode and holds the file open, carry on in that mode rather than fail: it only
    // costs concurrency.
    if (query_text("PRAGMA journal_mode").value_or("") != "wal") {
      sqlite3_busy_timeout(db_, 0);
      if (sqlite3_exec(db_, "PRAGMA journal_mode = WAL", nullptr, nullptr, nullptr) != SQLITE_OK)
        log::warn("{}: in use by another program; staying in its journal mode ({})", path.string(),
                  sqlite3_errmsg(db_));
    }
    sqlite3_busy_timeout(db_, 10000);
    exec("PRAGMA synchronous = NORMAL");
  } catch (...) {
    sqlite3_close_v2(db_);
    db_ = nullptr;
    throw;
  }
}

Database::~Database() { sqlite3_close_v2(db_); }

void Database::throw_error(std::string_view what) const {
  throw IoError(fmt::format("{}: {}: {}", path_.string(), what, sqlite3_errmsg(db_)));
}

void Database::exec(std::string_view sql) {
  char* err = nullptr;
  const std::string s(sql);
  if (sqlite3_exec(db_, s.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : "unknown error";
    sqlite3_free(err);
    throw IoError(fmt::format("{}: SQL error: {} (in: {:.80})", path_.string(), msg, s));
  }
}

std::int64_t Database::last_insert_id() const { return sqlite3_last_insert_rowid(db_); }
std::int64_t Database::changes() const { return sqlite3_changes64(db_); }

std::optional<std::int64_t> Database::query_int(std::string_view sql) {
  Statement st(*this, sql);
  if (!st.step() || st.is_null(0)) return std::nullopt;
  return st.get_int(0);
}

std::optional<std::string> Database::query_text(std::string_view sql) {
  Statement st(*this, sql);
  if (!st.step() || st.is_null(0)) return std::nullopt;
  return st.get_text(0);
}

Statement::Statement(Database& db, std::string_view sql) : db_(&db), sql_(sql) {
  if (sqlite3_prepare_v2(db.handle(), sql_.c_str(), int(sql_.size()), &stmt_, nullptr) !=
      SQLITE_OK) {
    db.throw_error(fmt::format("cannot prepare '{}'", sql_));
  }
}

Statement::Statement(Statement&& o) noexcept : db_(o.db_), stmt_(o.stmt_), sql_(std::move(o.sql_)) {
  o.stmt_ = nullptr;
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement& Statement::bind(int i, std::int64_t v) {
  sqlite3_bind_int64(stmt_, i, v);
  return *this;
}
Statement& Statement::bind(int i, double v) {
  sqlite3_bind_double(stmt_, i, v);
  return *this;
}
Statement& Statement::bind(int i, std::string_view v) {
  sqlite3_bind_text(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT);
  return *this;
}
Statement& Statement::bind_blob(int i, const std::vector<std::uint8_t>& b) {
  sqlite3_bind_blob(stmt_, i, b.data(), int(b.size()), SQLITE_TRANSIENT);
  return *this;
}
Statement& Statement::bind_null(int i) {
  sqlite3_bind_null(stmt_, i);
  return *this;
}

bool Statement::step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  db_->throw_error(fmt::format("cannot run '{:.100}'", sql_));
}

void Statement::run() {
  while (step()) {
  }
  reset();
}

void Statement::reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

bool Statement::is_null(int c) const { return sqlite3_column_type(stmt_, c) == SQLITE_NULL; }
std::int64_t Statement::get_int(int c) const { return sqlite3_column_int64(stmt_, c); }
double Statement::get_double(int c) const { return sqlite3_column_double(stmt_, c); }
std::optional<double> Statement::get_optional_double(int c) const {
  if (is_null(c)) return std::nullopt;
  return get_double(c);
}
std::string Statement::get_text(int c) const {
  const auto* p = sqlite3_column_text(stmt_, c);
  return p ? std::string(reinterpret_cast<const char*>(p), std::size_t(sqlite3_column_bytes(stmt_, c)))
           : std::string();
}
std::vector<std::uint8_t> Statement::get_blob(int c) const {
  const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(stmt_, c));
  return p ? std::vector<std::uint8_t>(p, p + sqlite3_column_bytes(stmt_, c))
           : std::vector<std::uint8_t>();
}

Transaction::Transaction(Database& db) : db_(db) { db_.exec("BEGIN IMMEDIATE"); }

Transaction::~Transaction() {
  if (!done_) {
    try {
      db_.exec("ROLLBACK");
    } catch (...) {
      // Nothing more can be done from a destructor; SQLite rolls back on close too.
    }
  }
}

void Transaction::commit() {
  fault::point("db.before_commit");
  db_.exec("COMMIT");
  done_ = true;
  fault::point("db.after_commit");
}

}  // namespace strata
