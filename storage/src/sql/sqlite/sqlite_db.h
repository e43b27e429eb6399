// The historian's connection to an SQLite file (sql/connection.h): move-only
// owners of sqlite3* and sqlite3_stmt*, and the one place where SQLite
// return codes become exceptions. Private to ambdiag_storage.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sql/connection.h"

namespace ambdiag::storage::detail {

// Throws if `rc` is not SQLITE_OK/ROW/DONE: InputError when the file is not a
// database or is corrupt (bad input), StorageError otherwise. `what` says
// which operation failed; the message carries the path and SQLite's text.
void check(sqlite3* db, int rc, const std::string& path, const char* what);

class Db final : public Connection {
 public:
  // flags: SQLITE_OPEN_READWRITE [| SQLITE_OPEN_CREATE]; always FULLMUTEX off
  // (one thread at a time, documented in historian.h).
  static Db open(const std::string& path, int flags);
  Db(Db&& o) noexcept : db_(o.db_), path_(std::move(o.path_)) { o.db_ = nullptr; }
  Db& operator=(Db&& o) noexcept;
  ~Db() override;

  sqlite3* get() const { return db_; }
  void check(int rc, const char* what) const { detail::check(db_, rc, path_, what); }

  Dialect dialect() const override { return Dialect::sqlite; }
  const std::string& path() const override { return path_; }
  const std::string& display() const override { return path_; }
  std::unique_ptr<detail::Stmt> prepare(const char* sql, Fetch fetch) override;
  void exec(const char* sql, const char* what) override;
  bool in_transaction() const override { return sqlite3_get_autocommit(db_) == 0; }
  std::int64_t changes() const override { return sqlite3_changes64(db_); }
  // write: BEGIN IMMEDIATE takes the file's write lock at once, so the
  // checks a write method makes inside stay true until it commits.
  const char* begin_sql(TxKind kind) const override { return kind == TxKind::write ? "BEGIN IMMEDIATE" : "BEGIN"; }
  void exec_quietly(const char* sql) noexcept override { sqlite3_exec(db_, sql, nullptr, nullptr, nullptr); }

 private:
  Db(sqlite3* db, std::string path) : db_(db), path_(std::move(path)) {}
  sqlite3* db_ = nullptr;
  std::string path_;
};

class SqliteStmt final : public detail::Stmt {
 public:
  SqliteStmt(const Db& db, const char* sql);
  ~SqliteStmt() override;

  SqliteStmt& reset() override;
  SqliteStmt& bind(int i, std::int64_t v) override;
  SqliteStmt& bind(int i, double v) override;
  SqliteStmt& bind(int i, std::string_view v) override;
  SqliteStmt& bind_blob(int i, std::span<const std::uint8_t> v) override;
  SqliteStmt& bind_null(int i) override;
  bool step() override;
  void send() override;
  std::vector<std::int64_t> sent() override { return std::exchange(changes_, {}); }

  std::int64_t col_int(int i) const override { return sqlite3_column_int64(s_, i); }
  double col_double(int i) const override { return sqlite3_column_double(s_, i); }
  bool col_null(int i) const override { return sqlite3_column_type(s_, i) == SQLITE_NULL; }
  std::string col_text(int i) const override;
  std::span<const std::uint8_t> col_blob(int i) const override;

 private:
  sqlite3_stmt* s_ = nullptr;
  const Db* db_;
  std::vector<std::int64_t> changes_;  // of the runs send() made
};

}  // namespace ambdiag::storage::detail
