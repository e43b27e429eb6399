#include "sql/postgres/pg_db.h"

#include <bit>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::storage::detail {

namespace {

// Type Oids (PostgreSQL's catalog/pg_type_d.h, stable across versions).
constexpr Oid kBool = 16, kBytea = 17, kName = 19, kInt8 = 20, kInt2 = 21, kInt4 = 23, kText = 25, kOid = 26,
              kJson = 114, kFloat4 = 700, kFloat8 = 701, kUnknown = 705, kBpchar = 1042, kVarchar = 1043;

bool is_text_type(Oid t) {
  return t == kText || t == kVarchar || t == kBpchar || t == kName || t == kJson || t == kUnknown;
}

template <class T>
void put_be(std::string& out, T v) {
  const auto u = std::bit_cast<std::make_unsigned_t<T>>(v);
  out.resize(sizeof(T));
  for (size_t k = 0; k < sizeof(T); ++k) out[k] = static_cast<char>((u >> (8 * (sizeof(T) - 1 - k))) & 0xff);
}

std::uint64_t get_be(const char* p, int n) {
  std::uint64_t u = 0;
  for (int k = 0; k < n; ++k) u = (u << 8) | static_cast<std::uint8_t>(p[k]);
  return u;
}

std::string double_text(double v) {
  if (v != v) return "NaN";
  if (v == std::numeric_limits<double>::infinity()) return "Infinity";
  if (v == -std::numeric_limits<double>::infinity()) return "-Infinity";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Notices ("relation already exists, skipping") are not errors: not printed.
void ignore_notice(void*, const char*) {}

const char kEmpty[1] = {0};

// How long a restart or failover may take before a reconnect gives up
// (ensure_connected, open of a location reached before).
constexpr auto kReconnectFor = std::chrono::seconds(10);  // a non-null pointer for an empty value (nullptr is NULL)

// libpq's messages end with a newline.
std::string trimmed(std::string msg) {
  while (!msg.empty() && (msg.back() == '\n' || msg.back() == ' ')) msg.pop_back();
  return msg;
}

}  // namespace

std::string numbered_placeholders(std::string_view sql) {
  std::string out;
  out.reserve(sql.size() + 16);
  int highest = 0;
  char quote = 0;  // inside '...' or "..."
  for (size_t i = 0; i < sql.size(); ++i) {
    const char c = sql[i];
    if (quote) {
      out += c;
      if (c == quote) quote = 0;  // a doubled quote re-enters at once: same result
      continue;
    }
    if (c == '\'' || c == '"') {
      quote = c;
      out += c;
      continue;
    }
    if (c != '?') {
      out += c;
      continue;
    }
    size_t j = i + 1;
    while (j < sql.size() && sql[j] >= '0' && sql[j] <= '9') ++j;
    const int n = j > i + 1 ? std::atoi(std::string(sql.substr(i + 1, j - i - 1)).c_str()) : highest + 1;
    highest = std::max(highest, n);
    out += '$' + std::to_string(n);
    i = j - 1;
  }
  return out;
}

namespace {

// The locations this process has connected to.
std::mutex reached_mu;
std::set<std::string> reached;

}  // namespace

bool PgDb::reached_before(const std::string& uri) {
  std::lock_guard l(reached_mu);
  return reached.count(uri) != 0;
}

std::unique_ptr<PgDb> PgDb::open(const std::string& uri, bool read_only) {
  // A location this process has reached before that refuses now is taken
  // for a restart or a failover: tried again for up to kReconnectFor; so is
  // any server that says it is starting or stopping (SQLSTATE 57P03) or
  // closes the connection while it is being set up. Otherwise the first
  // connection fails at once: then the location is what is wrong.
  const bool known = reached_before(uri);
  const auto deadline = std::chrono::steady_clock::now() + kReconnectFor;
  for (;;) {
    PGconn* conn = PQconnectdb(uri.c_str());
    std::unique_ptr<PgDb> db(new PgDb(conn, uri, read_only));  // owns conn even when it failed
    if (!conn) throw StorageError(db->display_ + ": cannot connect: out of memory");
    if (PQstatus(conn) == CONNECTION_OK) {
      db->configure();
      std::lock_guard l(reached_mu);
      reached.insert(uri);
      return db;
    }
    const std::string msg = PQerrorMessage(conn);
    const bool restarting = msg.find("the database system is") != std::string::npos ||
                            msg.find("server closed the connection unexpectedly") != std::string::npos;
    if (!(known || restarting) || std::chrono::steady_clock::now() >= deadline)
      throw InputError(db->display_ + ": cannot connect to PostgreSQL: " + trimmed(PQerrorMessage(conn)));
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

PgDb::PgDb(PGconn* conn, std::string uri, bool read_only)
    : conn_(conn), uri_(std::move(uri)), display_(display_location(uri_)), read_only_(read_only) {}

PgDb::~PgDb() {
  if (conn_) PQfinish(conn_);
}

// Per session, again after a reconnect: UTF-8 text both ways; a reader
// cannot write (as SQLite's query_only); a lock is waited for at most 10 s
// (as SQLite's busy timeout), then the write fails with StorageError.
void PgDb::configure() {
  PQsetNoticeProcessor(conn_, ignore_notice, nullptr);
  if (PQsetClientEncoding(conn_, "UTF8") != 0) fail("set client_encoding", PQerrorMessage(conn_));
  exec(read_only_ ? "SET default_transaction_read_only = on; SET lock_timeout = '10s'" : "SET lock_timeout = '10s'",
       "session settings");
}

// A server restarting (or a standby being promoted) refuses connections for
// a moment ("the database system is shutting down / starting up"), or
// closes a new one while it is being set up: the reconnect is tried again
// for up to kReconnectFor before the caller's statement fails, so a restart
// is a pause for every thread of a process (its start-up too), not an error
// each must handle.
void PgDb::ensure_connected() {
  if (PQstatus(conn_) == CONNECTION_OK || in_tx_ || reconnecting_) return;  // a lost transaction fails; its rollback ends it
  reconnecting_ = true;  // configure()'s own statements must not reconnect again
  const auto deadline = std::chrono::steady_clock::now() + kReconnectFor;
  for (;;) {
    PQreset(conn_);
    if (PQstatus(conn_) == CONNECTION_OK) {
      ++generation_;  // the server forgot this session's prepared statements
      try {
        configure();
        break;
      } catch (const StorageError&) {
        if (PQstatus(conn_) == CONNECTION_OK || std::chrono::steady_clock::now() >= deadline) {
          reconnecting_ = false;
          throw;
        }
      }
    } else if (std::chrono::steady_clock::now() >= deadline) {
      reconnecting_ = false;
      fail("reconnect", PQerrorMessage(conn_));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  reconnecting_ = false;
}

bool PgDb::in_transaction() const {
  if (in_tx_) return true;
  const auto s = PQtransactionStatus(conn_);
  return s == PQTRANS_INTRANS || s == PQTRANS_INERROR || s == PQTRANS_ACTIVE;
}

void PgDb::track_transaction(const char* sql) {
  if (std::strncmp(sql, "BEGIN", 5) == 0) in_tx_ = true;
  if (std::strcmp(sql, "COMMIT") == 0 || std::strcmp(sql, "ROLLBACK") == 0) in_tx_ = false;
}

bool PgDb::lost_outside_transaction(bool was_in_transaction) const {
  return !was_in_transaction && PQstatus(conn_) == CONNECTION_BAD;
}

void PgDb::exec(const char* sql, const char* what) {
  PgResult r;
  for (int attempt = 0;; ++attempt) {  // e.g. BEGIN on a connection the server ended: again, on a new one
    ensure_connected();
    const bool was_in_tx = in_tx_;
    r.reset(PQexec(conn_, sql));
    if (attempt == kLostRetries || !lost_outside_transaction(was_in_tx)) break;
  }
  // A failed COMMIT ends the transaction too; a failed BEGIN (the
  // connection lost under it, e.g. PostgreSQL restarting) opens none: else
  // every later transaction on this connection would be refused as nested.
  const bool failed = !r || (PQresultStatus(r.get()) != PGRES_COMMAND_OK && PQresultStatus(r.get()) != PGRES_TUPLES_OK);
  if (!(failed && std::strncmp(sql, "BEGIN", 5) == 0)) track_transaction(sql);
  check(r.get(), what);
  // COMMIT of a transaction that had an error rolls back and says so only here.
  if (std::strcmp(sql, "COMMIT") == 0 && std::strcmp(PQcmdStatus(r.get()), "ROLLBACK") == 0)
    fail(what, "the transaction had failed and was rolled back");
}

void PgDb::exec_quietly(const char* sql) noexcept {
  track_transaction(sql);
  if (PQstatus(conn_) != CONNECTION_OK) return;
  PQclear(PQexec(conn_, sql));
}

void PgDb::check(const PGresult* r, const char* what) const {
  const auto st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK || st == PGRES_SINGLE_TUPLE || st == PGRES_EMPTY_QUERY) return;
  const char* state = r ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : nullptr;
  const char* primary = r ? PQresultErrorField(r, PG_DIAG_MESSAGE_PRIMARY) : nullptr;
  std::string msg = trimmed(primary ? primary : PQerrorMessage(conn_));
  if (state) msg += std::string(" (SQLSTATE ") + state + ")";
  // Text PostgreSQL cannot hold (bytes that are not UTF-8, a NUL): the
  // value is what is wrong, as for any other bad input.
  if (state && (std::strcmp(state, "22021") == 0 || std::strcmp(state, "22P05") == 0))
    throw InputError(display_ + ": " + what + ": " + msg);
  // A deadlock broken, a serialization conflict: the same transaction again may pass.
  if (state && (std::strcmp(state, "40P01") == 0 || std::strcmp(state, "40001") == 0))
    throw TransientError(display_ + ": " + what + ": " + msg);
  fail(what, msg);
}

void PgDb::fail(const char* what, const std::string& detail) const {
  throw StorageError(display_ + ": " + what + ": " + trimmed(detail));
}

std::unique_ptr<Stmt> PgDb::prepare(const char* sql, Fetch fetch) { return std::make_unique<PgStmt>(*this, sql, fetch); }

PgStmt::PgStmt(PgDb& db, const char* sql, Fetch fetch) : db_(db), sql_(numbered_placeholders(sql)), fetch_(fetch) {
  db_.ensure_connected();
  prepare_on_server();
}

PgStmt::~PgStmt() {
  finish_stream();
  abandon_pipeline();
}

void PgStmt::prepare_on_server() {
  PgResult d;
  for (int attempt = 0;; ++attempt) {  // a connection lost outside a transaction: again, on a new one
    const bool was_in_tx = db_.in_transaction();
    name_ = db_.next_statement_name();
    PgResult p(PQprepare(db_.get(), name_.c_str(), sql_.c_str(), 0, nullptr));
    const bool prepared = p && PQresultStatus(p.get()) == PGRES_COMMAND_OK;
    if (prepared) d.reset(PQdescribePrepared(db_.get(), name_.c_str()));
    if (attempt < PgDb::kLostRetries && db_.lost_outside_transaction(was_in_tx)) {
      db_.ensure_connected();
      continue;
    }
    if (!prepared) db_.check(p.get(), ("prepare " + sql_).c_str());  // this program's SQL: say which
    db_.check(d.get(), "describe");
    break;
  }
  const int n = PQnparams(d.get());
  param_types_.resize(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) param_types_[static_cast<size_t>(k)] = PQparamtype(d.get(), k);
  params_.resize(static_cast<size_t>(n));
  prepared_generation_ = db_.generation();
}

PgStmt& PgStmt::reset() {
  finish_stream();
  abandon_pipeline();
  result_.reset();
  row_ = -1;
  executed_ = false;
  for (auto& p : params_) p.value = nullptr;
  return *this;
}

PgStmt::Param& PgStmt::param(int i) {
  if (i < 1 || i > static_cast<int>(params_.size()))
    throw std::logic_error("bind: parameter " + std::to_string(i) + " of a statement with " +
                           std::to_string(params_.size()) + ": " + sql_);
  return params_[static_cast<size_t>(i - 1)];
}

void PgStmt::set_owned(Param& p, int format) {
  p.value = p.owned.c_str();  // NUL-terminated, as text format needs
  p.length = static_cast<int>(p.owned.size());
  p.format = format;
}

PgStmt& PgStmt::bind(int i, std::int64_t v) {
  auto& p = param(i);
  switch (param_types_[static_cast<size_t>(i - 1)]) {
    case kInt8: put_be(p.owned, v); return set_owned(p, 1), *this;
    case kInt4:
      if (v < INT32_MIN || v > INT32_MAX) break;  // the server says out of range
      put_be(p.owned, static_cast<std::int32_t>(v));
      return set_owned(p, 1), *this;
    case kFloat8: put_be(p.owned, std::bit_cast<std::int64_t>(static_cast<double>(v))); return set_owned(p, 1), *this;
    default: break;
  }
  p.owned = std::to_string(v);
  set_owned(p, 0);
  return *this;
}

PgStmt& PgStmt::bind(int i, double v) {
  auto& p = param(i);
  if (param_types_[static_cast<size_t>(i - 1)] == kFloat8) {
    put_be(p.owned, std::bit_cast<std::int64_t>(v));
    set_owned(p, 1);
  } else {
    p.owned = double_text(v);
    set_owned(p, 0);
  }
  return *this;
}

PgStmt& PgStmt::bind(int i, std::string_view v) {
  auto& p = param(i);
  const Oid t = param_types_[static_cast<size_t>(i - 1)];
  if (is_text_type(t) || t == kBytea) {  // binary text is its bytes: no copy
    p.value = v.empty() ? kEmpty : v.data();
    p.length = static_cast<int>(v.size());
    p.format = 1;
  } else {  // e.g. a timestamp: the server parses the text
    p.owned.assign(v);
    set_owned(p, 0);
  }
  return *this;
}

PgStmt& PgStmt::bind_blob(int i, std::span<const std::uint8_t> v) {
  auto& p = param(i);
  p.value = v.empty() ? kEmpty : reinterpret_cast<const char*>(v.data());
  p.length = static_cast<int>(v.size());
  p.format = 1;
  return *this;
}

PgStmt& PgStmt::bind_null(int i) {
  param(i).value = nullptr;
  return *this;
}

PgStmt::Args PgStmt::args() const {
  Args a;
  for (const auto& p : params_) {
    a.values.push_back(p.value);
    a.lengths.push_back(p.length);
    a.formats.push_back(p.format);
  }
  return a;
}

void PgStmt::execute() {
  if (db_.streaming && db_.streaming != this)
    throw std::logic_error("a statement ran while another read its rows one by one or pipelined: " + sql_);
  const auto connect = [this] {
    db_.ensure_connected();
    if (prepared_generation_ != db_.generation()) prepare_on_server();  // reconnected: the same types again
  };
  connect();
  const Args a = args();
  const int n = static_cast<int>(params_.size());
  if (fetch_ == Fetch::all) {
    for (int attempt = 0;; ++attempt) {  // a read on a connection the server ended: again, on a new one
      const bool was_in_tx = db_.in_transaction();
      result_.reset(PQexecPrepared(db_.get(), name_.c_str(), n, a.values.data(), a.lengths.data(), a.formats.data(), 1));
      if (attempt == PgDb::kLostRetries || !db_.lost_outside_transaction(was_in_tx)) break;
      connect();
    }
    db_.check(result_.get(), "statement");
    db_.set_changes(std::atoll(PQcmdTuples(result_.get())));
    return;
  }
  if (!PQsendQueryPrepared(db_.get(), name_.c_str(), n, a.values.data(), a.lengths.data(), a.formats.data(), 1))
    db_.fail("statement", PQerrorMessage(db_.get()));
  streaming_ = true;
  db_.streaming = this;
  PQsetSingleRowMode(db_.get());
}

void PgStmt::send() {
  if (!pipelined_) {
    if (db_.streaming) throw std::logic_error("a pipeline began while another statement was busy: " + sql_);
    db_.ensure_connected();
    if (prepared_generation_ != db_.generation()) prepare_on_server();
    if (!PQenterPipelineMode(db_.get())) db_.fail("pipeline", PQerrorMessage(db_.get()));
    db_.streaming = this;
  }
  const Args a = args();
  // libpq copies the values into its buffer here: the bindings may change.
  if (!PQsendQueryPrepared(db_.get(), name_.c_str(), static_cast<int>(params_.size()), a.values.data(),
                           a.lengths.data(), a.formats.data(), 1)) {
    const std::string msg = PQerrorMessage(db_.get());
    abandon_pipeline();
    db_.fail("statement", msg);
  }
  ++pipelined_;
}

std::vector<std::int64_t> PgStmt::sent() {
  std::vector<std::int64_t> changes;
  if (!pipelined_) return changes;
  PQpipelineSync(db_.get());
  PgResult error;
  // Each run's result then a nullptr; after an error the rest are
  // "aborted" (the transaction is); then the sync's own result.
  for (int done = 0; done < pipelined_;) {
    PgResult r(PQgetResult(db_.get()));
    if (!r) {
      ++done;
      continue;
    }
    const auto st = PQresultStatus(r.get());
    if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK)
      changes.push_back(std::atoll(PQcmdTuples(r.get())));
    else if (!error && st != PGRES_PIPELINE_ABORTED)
      error = std::move(r);
  }
  PgResult sync(PQgetResult(db_.get()));
  PQexitPipelineMode(db_.get());
  const auto runs = static_cast<size_t>(pipelined_);
  pipelined_ = 0;
  db_.streaming = nullptr;
  if (error) db_.check(error.get(), "statement");
  if (changes.size() != runs) db_.fail("statement", PQerrorMessage(db_.get()));  // the connection was lost
  return changes;
}

void PgStmt::abandon_pipeline() noexcept {
  if (!pipelined_) return;
  try {
    sent();
  } catch (...) {  // the caller is failing already
  }
}

bool PgStmt::step() {
  if (!executed_) {
    executed_ = true;
    execute();
  }
  if (fetch_ == Fetch::all) return ++row_ < PQntuples(result_.get());
  if (!streaming_) return false;
  result_.reset(PQgetResult(db_.get()));
  const auto st = result_ ? PQresultStatus(result_.get()) : PGRES_FATAL_ERROR;
  if (st == PGRES_SINGLE_TUPLE) {
    row_ = 0;
    return true;
  }
  PgResult last = std::move(result_);
  finish_stream();
  db_.check(last.get(), "statement");
  db_.set_changes(std::atoll(PQcmdTuples(last.get())));
  return false;
}

// Reads what is left of a row-by-row result: libpq has no way to drop it,
// and the connection takes no other statement until it is read.
void PgStmt::finish_stream() noexcept {
  if (!streaming_) return;
  while (PGresult* r = PQgetResult(db_.get())) PQclear(r);
  streaming_ = false;
  db_.streaming = nullptr;
}

std::span<const char> PgStmt::raw(int i) const {
  if (!result_ || row_ < 0 || row_ >= PQntuples(result_.get()) || i < 0 || i >= PQnfields(result_.get()))
    throw std::logic_error("column " + std::to_string(i) + " read without a row: " + sql_);
  return {PQgetvalue(result_.get(), row_, i), static_cast<size_t>(PQgetlength(result_.get(), row_, i))};
}

bool PgStmt::col_null(int i) const {
  raw(i);
  return PQgetisnull(result_.get(), row_, i) != 0;
}

std::int64_t PgStmt::col_int(int i) const {
  const auto v = raw(i);
  if (col_null(i)) return 0;  // as SQLite
  switch (PQftype(result_.get(), i)) {
    case kInt8: return static_cast<std::int64_t>(get_be(v.data(), 8));
    case kInt4: return static_cast<std::int32_t>(get_be(v.data(), 4));
    case kInt2: return static_cast<std::int16_t>(get_be(v.data(), 2));
    case kOid: return static_cast<std::uint32_t>(get_be(v.data(), 4));
    case kBool: return v[0] != 0;
    case kFloat8: return static_cast<std::int64_t>(col_double(i));
    default:
      if (is_text_type(PQftype(result_.get(), i))) return std::strtoll(std::string(v.data(), v.size()).c_str(), nullptr, 10);
  }
  throw std::logic_error("column " + std::to_string(i) + " of type " + std::to_string(PQftype(result_.get(), i)) +
                         " read as an integer (cast it in SQL): " + sql_);
}

double PgStmt::col_double(int i) const {
  const auto v = raw(i);
  if (col_null(i)) return 0.0;
  switch (PQftype(result_.get(), i)) {
    case kFloat8: return std::bit_cast<double>(get_be(v.data(), 8));
    case kFloat4: return std::bit_cast<float>(static_cast<std::uint32_t>(get_be(v.data(), 4)));
    case kInt8:
    case kInt4:
    case kInt2: return static_cast<double>(col_int(i));
    default:
      if (is_text_type(PQftype(result_.get(), i))) return std::strtod(std::string(v.data(), v.size()).c_str(), nullptr);
  }
  throw std::logic_error("column " + std::to_string(i) + " of type " + std::to_string(PQftype(result_.get(), i)) +
                         " read as a number (cast it in SQL): " + sql_);
}

std::string PgStmt::col_text(int i) const {
  const auto v = raw(i);
  if (col_null(i)) return {};
  const Oid t = PQftype(result_.get(), i);
  if (is_text_type(t) || t == kBytea) return {v.data(), v.size()};
  if (t == kFloat8 || t == kFloat4) return double_text(col_double(i));
  return std::to_string(col_int(i));
}

std::span<const std::uint8_t> PgStmt::col_blob(int i) const {
  const auto v = raw(i);
  return {reinterpret_cast<const std::uint8_t*>(v.data()), v.size()};
}

}  // namespace ambdiag::storage::detail
