// The historian's connection to a PostgreSQL database (sql/connection.h):
// move-only owners of PGconn* and PGresult*, and the one place where libpq
// results become exceptions. Private to ambdiag_storage.
//
// Statements: `?` / `?N` become `$n` once, at prepare time; each is a named
// server-side prepared statement of this connection (described once, so
// that a bound value is sent in the parameter's own type: int8, float8 and
// bytea in binary, text as its bytes). Results come back in binary and are
// decoded by column type. A lost connection is re-opened at the next
// statement outside a transaction, which is tried again on it (up to
// kLostRetries times; statements then prepare again); inside a transaction
// the call fails.
#pragma once

#include <libpq-fe.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sql/connection.h"

namespace ambdiag::storage::detail {

// Owns a PGresult.
struct PgResultFree {
  void operator()(PGresult* r) const { PQclear(r); }
};
using PgResult = std::unique_ptr<PGresult, PgResultFree>;

class PgDb final : public Connection {
 public:
  // Connects (client_encoding UTF8). InputError naming the location (its
  // password masked) when the server cannot be reached or refuses the
  // login: the location is what is wrong.
  // A location this process connected to before is tried again for up to
  // 10 s (a restart or failover), a new one fails at once (a wrong URI).
  static std::unique_ptr<PgDb> open(const std::string& uri, bool read_only);
  // This process has connected to `uri`.
  static bool reached_before(const std::string& uri);
  ~PgDb() override;

  PGconn* get() const { return conn_; }
  Dialect dialect() const override { return Dialect::postgres; }
  const std::string& path() const override { return uri_; }
  const std::string& display() const override { return display_; }
  std::unique_ptr<Stmt> prepare(const char* sql, Fetch fetch) override;
  void exec(const char* sql, const char* what) override;
  bool in_transaction() const override;
  std::int64_t changes() const override { return changes_; }
  // write: READ COMMITTED, PostgreSQL's default; each write method takes
  // the locks its checks need. read: one snapshot for every statement.
  const char* begin_sql(TxKind kind) const override {
    return kind == TxKind::write ? "BEGIN" : "BEGIN ISOLATION LEVEL REPEATABLE READ";
  }
  void exec_quietly(const char* sql) noexcept override;

  // Throws for a result that is not `ok` (nullptr: the connection failed):
  // StorageError, or InputError for text PostgreSQL cannot hold (not UTF-8,
  // a NUL byte). The message names the location and `what`.
  void check(const PGresult* r, const char* what) const;
  [[noreturn]] void fail(const char* what, const std::string& detail) const;

  // For the statements: the connection's generation (bumped by a
  // reconnect, which forgets the prepared statements), a fresh statement
  // name, and whether a Fetch::one_by_one statement is reading rows.
  void ensure_connected();
  // After a call: the connection was lost and no transaction was open
  // before it, so the call may be made again on a new connection (outside
  // a transaction the historian only reads, or begins one).
  bool lost_outside_transaction(bool was_in_transaction) const;
  // How often such a call is made again: a server going down (pg_ctl
  // restart, a failover) may still accept the reconnect, then close it.
  static constexpr int kLostRetries = 3;
  std::uint64_t generation() const { return generation_; }
  std::string next_statement_name() { return "ambdiag_" + std::to_string(++statements_); }
  void set_changes(std::int64_t n) { changes_ = n; }
  const void* streaming = nullptr;

 private:
  PgDb(PGconn* conn, std::string uri, bool read_only);
  void configure();
  // Follows BEGIN, COMMIT and ROLLBACK: a connection lost inside a
  // transaction is not re-opened until the transaction's rollback (the
  // statements after it would otherwise run outside it).
  void track_transaction(const char* sql);
  PGconn* conn_ = nullptr;
  std::string uri_, display_;
  bool read_only_;
  bool in_tx_ = false;
  bool reconnecting_ = false;  // inside ensure_connected (configure's statements)
  std::int64_t changes_ = 0;
  std::uint64_t generation_ = 1, statements_ = 0;
};

class PgStmt final : public Stmt {
 public:
  PgStmt(PgDb& db, const char* sql, Fetch fetch);
  ~PgStmt() override;

  PgStmt& reset() override;
  PgStmt& bind(int i, std::int64_t v) override;
  PgStmt& bind(int i, double v) override;
  PgStmt& bind(int i, std::string_view v) override;
  PgStmt& bind_blob(int i, std::span<const std::uint8_t> v) override;
  PgStmt& bind_null(int i) override;
  bool step() override;
  void send() override;
  std::vector<std::int64_t> sent() override;

  std::int64_t col_int(int i) const override;
  double col_double(int i) const override;
  bool col_null(int i) const override;
  std::string col_text(int i) const override;
  std::span<const std::uint8_t> col_blob(int i) const override;

 private:
  void prepare_on_server();
  struct Param {
    const char* value = nullptr;  // nullptr: NULL
    int length = 0;
    int format = 0;  // 0 text (NUL-terminated), 1 binary
    std::string owned;  // the value's bytes when converted here
  };
  Param& param(int i);
  void set_owned(Param& p, int format);
  void execute();
  // The values, lengths and formats PQexecPrepared and its kin take.
  struct Args {
    std::vector<const char*> values;
    std::vector<int> lengths, formats;
  };
  Args args() const;
  void finish_stream() noexcept;
  void abandon_pipeline() noexcept;
  std::span<const char> raw(int i) const;

  PgDb& db_;
  std::string sql_;  // with $n placeholders
  Fetch fetch_;
  std::string name_;
  std::uint64_t prepared_generation_ = 0;
  std::vector<unsigned> param_types_;  // Oids, from the server's description
  std::vector<Param> params_;
  PgResult result_;
  int row_ = -1;
  bool executed_ = false, streaming_ = false;
  int pipelined_ = 0;  // runs send() queued, their results not yet read
};

// `?` and `?N` placeholders (SQLite's) as `$n` (PostgreSQL's), outside
// quoted text: `?` is one more than the highest number so far.
std::string numbered_placeholders(std::string_view sql);

}  // namespace ambdiag::storage::detail
