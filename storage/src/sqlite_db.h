// Move-only owners of sqlite3* and sqlite3_stmt*, and the one place where
// SQLite return codes become exceptions. Private to ambdiag_storage.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace ambdiag::storage::detail {

// Throws if `rc` is not SQLITE_OK/ROW/DONE: InputError when the file is not a
// database or is corrupt (bad input), StorageError otherwise. `what` says
// which operation failed; the message carries the path and SQLite's text.
void check(sqlite3* db, int rc, const std::string& path, const char* what);

class Db {
 public:
  // flags: SQLITE_OPEN_READWRITE [| SQLITE_OPEN_CREATE]; always FULLMUTEX off
  // (one thread at a time, documented in historian.h).
  static Db open(const std::string& path, int flags);
  Db(Db&& o) noexcept : db_(o.db_), path_(std::move(o.path_)) { o.db_ = nullptr; }
  Db& operator=(Db&& o) noexcept;
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;
  ~Db();

  sqlite3* get() const { return db_; }
  const std::string& path() const { return path_; }
  // Runs SQL text written in this program (never built from values).
  void exec(const char* sql, const char* what);
  void check(int rc, const char* what) const { detail::check(db_, rc, path_, what); }
  bool in_transaction() const { return sqlite3_get_autocommit(db_) == 0; }
  // Rows changed by the last INSERT/UPDATE/DELETE.
  int changes() const { return sqlite3_changes(db_); }

 private:
  Db(sqlite3* db, std::string path) : db_(db), path_(std::move(path)) {}
  sqlite3* db_ = nullptr;
  std::string path_;
};

class Stmt {
 public:
  Stmt(const Db& db, const char* sql);
  Stmt(Stmt&& o) noexcept : s_(o.s_), db_(o.db_) { o.s_ = nullptr; }
  Stmt& operator=(Stmt&&) = delete;
  Stmt(const Stmt&) = delete;
  ~Stmt();

  // Ready for new bindings: resets and clears the previous ones.
  Stmt& reset();
  // Parameters are 1-based, as in SQLite. Text and blobs are not copied:
  // they must outlive the step.
  Stmt& bind(int i, std::int64_t v);
  Stmt& bind(int i, double v);
  Stmt& bind(int i, std::string_view v);
  Stmt& bind_blob(int i, std::span<const std::uint8_t> v);
  Stmt& bind_null(int i);
  // true: a row is ready; false: done.
  bool step();
  void run() {
    while (step()) {
    }
  }

  std::int64_t col_int(int i) const { return sqlite3_column_int64(s_, i); }
  double col_double(int i) const { return sqlite3_column_double(s_, i); }
  bool col_null(int i) const { return sqlite3_column_type(s_, i) == SQLITE_NULL; }
  std::string col_text(int i) const;
  std::optional<std::int64_t> col_opt_int(int i) const;
  std::optional<std::string> col_opt_text(int i) const;
  std::span<const std::uint8_t> col_blob(int i) const;  // valid until the next step/reset

 private:
  sqlite3_stmt* s_ = nullptr;
  const Db* db_;
};

// A transaction that rolls back in its destructor unless committed. Nested
// in an open transaction, a read one joins it (neither begins nor commits)
// and a write one is a SAVEPOINT: its own changes roll back on failure, the
// outer transaction goes on (a WriteBatch of many all-or-nothing calls).
class Transaction {
 public:
  enum class Kind { read, write };  // read: BEGIN (snapshot); write: BEGIN IMMEDIATE
  Transaction(Db& db, Kind kind);
  Transaction(Transaction&& o) noexcept : db_(o.db_), owns_(o.owns_), savepoint_(o.savepoint_) { o.owns_ = false; }
  Transaction& operator=(Transaction&&) = delete;
  ~Transaction();
  void commit();

 private:
  Db* db_;
  bool owns_ = false;
  bool savepoint_ = false;
};

}  // namespace ambdiag::storage::detail
