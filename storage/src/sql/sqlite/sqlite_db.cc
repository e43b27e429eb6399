#include "sql/sqlite/sqlite_db.h"

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/power_cut.h"

#include <mutex>

namespace ambdiag::storage::detail {

void check(sqlite3* db, int rc, const std::string& path, const char* what) {
  if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return;
  const int primary = rc & 0xff;
  std::string msg = path + ": " + what + ": " + sqlite3_errstr(rc);
  if (db && sqlite3_errcode(db) == rc) {
    const std::string detail = sqlite3_errmsg(db);
    if (detail != sqlite3_errstr(rc)) msg += " (" + detail + ")";
  }
  switch (primary) {
    case SQLITE_NOTADB:
      throw InputError(path + ": not an SQLite database (" + what + ")");
    case SQLITE_CORRUPT:
      throw InputError(path + ": the database file is corrupt (" + what + ")");
    case SQLITE_CANTOPEN:
      throw InputError(msg);
    default:
      throw StorageError(msg);
  }
}

Db Db::open(const std::string& path, int flags) {
  // Tests may ask for the simulated power cut (power_cut.h) through the
  // environment; read once, before the process' first connection.
  static std::once_flag power_cut_env;
  std::call_once(power_cut_env, [] { power_cut::install_from_env(); });
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  Db owner(db, path);  // sqlite3_open_v2 hands out a handle even on failure
  owner.check(rc, "open");
  sqlite3_extended_result_codes(db, 1);
  return owner;
}

Db& Db::operator=(Db&& o) noexcept {
  if (this != &o) {
    if (db_) sqlite3_close_v2(db_);
    db_ = o.db_;
    path_ = std::move(o.path_);
    o.db_ = nullptr;
  }
  return *this;
}

Db::~Db() {
  if (db_) sqlite3_close_v2(db_);
}

void Db::exec(const char* sql, const char* what) { check(sqlite3_exec(db_, sql, nullptr, nullptr, nullptr), what); }

std::unique_ptr<detail::Stmt> Db::prepare(const char* sql, Fetch) { return std::make_unique<SqliteStmt>(*this, sql); }

SqliteStmt::SqliteStmt(const Db& db, const char* sql) : db_(&db) {
  db.check(sqlite3_prepare_v3(db.get(), sql, -1, SQLITE_PREPARE_PERSISTENT, &s_, nullptr), "prepare");
}

SqliteStmt::~SqliteStmt() {
  if (s_) sqlite3_finalize(s_);
}

SqliteStmt& SqliteStmt::reset() {
  sqlite3_reset(s_);  // returns the last step's error, already reported by step()
  sqlite3_clear_bindings(s_);
  return *this;
}

SqliteStmt& SqliteStmt::bind(int i, std::int64_t v) {
  db_->check(sqlite3_bind_int64(s_, i, v), "bind");
  return *this;
}

SqliteStmt& SqliteStmt::bind(int i, double v) {
  db_->check(sqlite3_bind_double(s_, i, v), "bind");
  return *this;
}

SqliteStmt& SqliteStmt::bind(int i, std::string_view v) {
  db_->check(sqlite3_bind_text64(s_, i, v.data(), v.size(), SQLITE_STATIC, SQLITE_UTF8), "bind");
  return *this;
}

SqliteStmt& SqliteStmt::bind_blob(int i, std::span<const std::uint8_t> v) {
  // A zero-length blob must still be a blob, not NULL.
  static const std::uint8_t kEmpty = 0;
  db_->check(sqlite3_bind_blob64(s_, i, v.empty() ? &kEmpty : v.data(), v.size(), SQLITE_STATIC), "bind");
  return *this;
}

SqliteStmt& SqliteStmt::bind_null(int i) {
  db_->check(sqlite3_bind_null(s_, i), "bind");
  return *this;
}

bool SqliteStmt::step() {
  const int rc = sqlite3_step(s_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  sqlite3_reset(s_);
  db_->check(rc, "step");
  return false;
}

void SqliteStmt::send() {
  while (step()) {
  }
  changes_.push_back(db_->changes());
  sqlite3_reset(s_);  // the bindings stay for the caller to change
}

std::string SqliteStmt::col_text(int i) const {
  const auto* p = sqlite3_column_text(s_, i);
  const int n = sqlite3_column_bytes(s_, i);
  return p ? std::string(reinterpret_cast<const char*>(p), static_cast<size_t>(n)) : std::string();
}

std::span<const std::uint8_t> SqliteStmt::col_blob(int i) const {
  const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(s_, i));
  const int n = sqlite3_column_bytes(s_, i);
  return {p, p ? static_cast<size_t>(n) : 0};
}

}  // namespace ambdiag::storage::detail
