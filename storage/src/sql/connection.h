// The historian's database connection, private to ambdiag_storage: one
// interface, two implementations (sql/sqlite/sqlite_db.h: a file;
// sql/postgres/pg_db.h: a PostgreSQL database). historian*.cc write their
// SQL once, with `?` or `?N` placeholders bound from 1, and run it through
// these classes; where the dialects differ they ask `dialect()` (see
// docs/storage.md, "PostgreSQL", for the list of those places).
//
// For PostgreSQL, which types each parameter from the SQL: the first use of
// a parameter must give its type, i.e. `(run_id = ?1 OR ?1 IS NULL)`, not
// `(?1 IS NULL OR run_id = ?1)` ("could not determine data type"); and a
// parameter is one type throughout (not a number here and text in a `||`).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ambdiag::storage::detail {

enum class Dialect { sqlite, postgres };

// How a statement's rows come back. `all`: the whole result at the first
// step (another statement may run while its rows are read). `one_by_one`:
// rows as they arrive, for results too big to hold twice (a run's chunks);
// no other statement may run on the connection until the last row is read
// or the statement is reset. SQLite always steps row by row.
enum class Fetch { all, one_by_one };

// A prepared statement. Text and blobs bound are not copied: they must
// outlive the step that runs the statement.
class Stmt {
 public:
  virtual ~Stmt() = default;
  Stmt() = default;
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  // Ready for new bindings: ends the previous run and clears its bindings.
  virtual Stmt& reset() = 0;
  virtual Stmt& bind(int i, std::int64_t v) = 0;
  virtual Stmt& bind(int i, double v) = 0;
  virtual Stmt& bind(int i, std::string_view v) = 0;
  virtual Stmt& bind_blob(int i, std::span<const std::uint8_t> v) = 0;
  virtual Stmt& bind_null(int i) = 0;
  // true: a row is ready; false: done.
  virtual bool step() = 0;
  void run() {
    while (step()) {
    }
  }
  // Many runs of a statement that returns no rows, with the results
  // collected at the end: send() runs it with the current bindings (which
  // may change right after), sent() gives each run's count of changed rows
  // in order, then the first error, if any, is thrown. PostgreSQL pipelines
  // them (one round trip for all, instead of one each: 1.1 to 1.8 times the
  // ingest rate, docs/benchmarks.md); SQLite runs each at once. No other
  // statement may run on the connection in between.
  virtual void send() = 0;
  virtual std::vector<std::int64_t> sent() = 0;

  virtual std::int64_t col_int(int i) const = 0;
  virtual double col_double(int i) const = 0;
  virtual bool col_null(int i) const = 0;
  virtual std::string col_text(int i) const = 0;
  virtual std::span<const std::uint8_t> col_blob(int i) const = 0;  // valid until the next step/reset
  std::optional<std::int64_t> col_opt_int(int i) const {
    if (col_null(i)) return std::nullopt;
    return col_int(i);
  }
  std::optional<std::string> col_opt_text(int i) const {
    if (col_null(i)) return std::nullopt;
    return col_text(i);
  }
};

class Connection {
 public:
  virtual ~Connection() = default;
  Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  virtual Dialect dialect() const = 0;
  // What the historian was opened with (a file path or a URI): enough to
  // open another connection to the same database.
  virtual const std::string& path() const = 0;
  // The same for messages: a URI's password masked.
  virtual const std::string& display() const = 0;

  virtual std::unique_ptr<Stmt> prepare(const char* sql, Fetch fetch) = 0;
  // Runs SQL text written in this program (never built from values).
  virtual void exec(const char* sql, const char* what) = 0;
  virtual bool in_transaction() const = 0;
  // Rows changed by the last INSERT/UPDATE/DELETE.
  virtual std::int64_t changes() const = 0;

  // Transactions (used by Transaction below).
  enum class TxKind { read, write };
  // The statement that begins a transaction of that kind.
  virtual const char* begin_sql(TxKind kind) const = 0;
  // No throw: after an error the database may have rolled back already.
  virtual void exec_quietly(const char* sql) noexcept = 0;
  // Called after the outermost write transaction committed: the commit
  // listener's turn (PostgreSQL's durability tracker; SQLite's is its WAL hook).
  void committed() {
    if (on_commit_) on_commit_();
  }
  void set_on_commit(std::function<void()> f) { on_commit_ = std::move(f); }

 private:
  std::function<void()> on_commit_;
};

// A transaction that rolls back in its destructor unless committed. Nested
// in an open transaction, a read one joins it (neither begins nor commits)
// and a write one is a SAVEPOINT: its own changes roll back on failure, the
// outer transaction goes on (a WriteBatch of many all-or-nothing calls).
// read: a snapshot (SQLite BEGIN; PostgreSQL REPEATABLE READ). write: SQLite
// BEGIN IMMEDIATE (the only writer); PostgreSQL READ COMMITTED, whose
// writers run at once: each write method takes the locks it needs
// (Historian::Impl::lock, docs/storage.md "What guards each write").
class Transaction {
 public:
  using Kind = Connection::TxKind;
  Transaction(Connection& db, Kind kind);
  Transaction(Transaction&& o) noexcept : db_(o.db_), kind_(o.kind_), owns_(o.owns_), savepoint_(o.savepoint_) {
    o.owns_ = false;
  }
  Transaction& operator=(Transaction&&) = delete;
  ~Transaction();
  void commit();

 private:
  Connection* db_;
  Kind kind_;
  bool owns_ = false;
  bool savepoint_ = false;
};

}  // namespace ambdiag::storage::detail
