// Private to ambdiag_storage: the Historian's connection, its cached
// statements and the helpers historian*.cc share.
#pragma once

#include <bit>
#include <chrono>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "durability.h"
#include "sql/connection.h"

namespace ambdiag::storage {

using detail::Dialect;
using detail::Fetch;
using detail::Stmt;
using detail::Transaction;

std::string now_utc();  // server clock, ISO 8601 UTC with milliseconds
// The same fixed format of any time ("2026-11-26T10:00:00.000Z", e.g. a
// lease's end): text order is time order, so it compares with created_at in SQL.
std::string utc_ms(std::chrono::system_clock::time_point at);
std::string hex64(std::uint64_t v);
RunStatus status_from_text(const std::string& s);
inline std::string quoted(const std::string& id) { return "'" + id + "'"; }

// PostgreSQL: the run_created_at of the chunks retention moved out of their
// day's partition into sample_chunks_kept (pg_schema.cc v10: its range ends
// at 1900-01-01, before any reception time), in created_at's format. A
// macro, to be part of SQL literals.
#define AMBDIAG_KEPT_CHUNKS_AT "1800-01-01T00:00:00.000Z"

struct Historian::Impl {
  std::unique_ptr<detail::Connection> conn;
  detail::Connection& db;  // *conn
  bool read_only;
  int snapshot_depth = 0;
  std::optional<Transaction> snapshot_tx;
  std::optional<Transaction> batch_tx;  // an open WriteBatch
  // Its events (append_event), written at its commit: the events' lock last.
  std::vector<StoredEvent> batch_events;
  std::unordered_map<const char*, std::unique_ptr<Stmt>> stmts;  // keyed by the SQL literal's address
  // Last: stopped (its hook removed) before the connection closes.
  std::unique_ptr<detail::Durability> checkpointer;

  Impl(std::unique_ptr<detail::Connection> c, bool ro) : conn(std::move(c)), db(*conn), read_only(ro) {}

  Dialect dialect() const { return db.dialect(); }

  // A cached prepared statement, reset and ready for bindings. `sql` must be
  // a string literal; one statement is never used twice at once. `fetch`
  // (sql/connection.h) is fixed by the first call.
  Stmt& stmt(const char* sql, Fetch fetch = Fetch::all) {
    auto it = stmts.find(sql);
    if (it == stmts.end()) it = stmts.emplace(sql, db.prepare(sql, fetch)).first;
    return it->second->reset();
  }

  // What a write method serialises on beside the others of the same key.
  // (5 is the schema migration's, pg_schema.cc.) Lock order (docs/storage.md
  // "Lock order"): `events` is taken last, only by write_events, after
  // which a transaction takes no other lock; a WriteBatch's appends wait
  // for its commit.
  enum class LockSpace : std::int64_t {
    pump = 1, run = 2, token = 3, alarm_journal = 4, events = 6, retention = 7, partitions = 8, pump_alarms = 9
  };
  // Inside a write transaction: waits until no other transaction holds the
  // key's lock, and holds it until this one ends. SQLite: nothing to do,
  // BEGIN IMMEDIATE already made this the only writer of the file.
  // PostgreSQL: several processes write at once (READ COMMITTED), so a
  // check followed by a write (the next version number, "unless one
  // exists", a run's state) takes a transaction-scoped advisory lock on the
  // key's hash, with the schema's name: historians in other schemas of
  // the database never wait for this one (a collision only makes two keys
  // wait for each other).
  void lock(LockSpace space, const std::string& key) {
    if (dialect() != Dialect::postgres) return;
    stmt("SELECT pg_advisory_xact_lock(CAST(? AS integer), hashtext(current_schema() || ?))")
        .bind(1, static_cast<std::int64_t>(space))
        .bind(2, key)
        .run();
  }

  // Registers the pump if it is new (first_seen = now).
  void register_pump(const std::string& pump_id, const std::string& now) {
    stmt("INSERT INTO pumps (pump_id, first_seen) VALUES (?, ?) ON CONFLICT (pump_id) DO NOTHING").bind(1, pump_id).bind(2, now).run();
  }
  // The pump's next version number: `sql` (a literal) selects the highest
  // held + 1 for the bound pump. No other writer can take the same number
  // before this transaction ends: SQLite's BEGIN IMMEDIATE, PostgreSQL's
  // lock on the pump.
  std::int64_t next_version(const char* sql, const std::string& pump_id) {
    lock(LockSpace::pump, pump_id);
    auto& next = stmt(sql);
    next.bind(1, pump_id).step();
    const auto version = next.col_int(0);
    next.reset();
    return version;
  }

  // PostgreSQL: sample_chunks' day partitions (historian_partitions.cc).
  // `from`, `to`: the day's bounds in created_at's format.
  struct ChunkPartition {
    std::string name, from, to;
  };
  std::vector<ChunkPartition> chunk_partitions();  // by day
  // Today's and the next two days' partitions, unless this process made
  // them today; nothing on SQLite, read-only or inside a transaction.
  void ensure_chunk_partitions(std::chrono::system_clock::time_point now);
  std::string partitions_through;  // the last day (YYYYMMDD) ensured

  void require_writer(const char* what) const {
    if (read_only) throw std::logic_error(std::string("Historian::") + what + " on a read-only connection");
  }

  struct RunState {
    int n_channels;
    RunStatus status;
    std::optional<std::int64_t> expected_frames;
    std::optional<std::uint64_t> expected_checksum;
    // PostgreSQL: the run_created_at its chunks carry (sample_chunks'
    // partition key): its created_at, or AMBDIAG_KEPT_CHUNKS_AT once
    // retention moved them to sample_chunks_kept.
    std::string chunks_at;
    std::optional<std::string> samples_dropped_at;  // retention dropped (or is dropping) the samples
  };
  // `write`: called inside a write transaction that acts on the state, which
  // then stays as read until it ends (put_chunks, end_run and
  // mark_incomplete of one run take turns).
  RunState run_state(const std::string& run_id, const char* what, bool write = false) {
    if (write) lock(LockSpace::run, run_id);
#define AMBDIAG_RUN_STATE_SQL(CHUNKS_AT) \
  "SELECT n_channels, status, expected_frames, expected_checksum, " CHUNKS_AT ", samples_dropped_at FROM runs WHERE run_id = ?"
    auto& s = dialect() == Dialect::postgres
                  ? stmt(AMBDIAG_RUN_STATE_SQL("CASE WHEN samples_kept_at IS NULL THEN created_at ELSE '" AMBDIAG_KEPT_CHUNKS_AT "' END"))
                  : stmt(AMBDIAG_RUN_STATE_SQL("created_at"));  // a file has no samples_kept_at (schema.cc v10)
#undef AMBDIAG_RUN_STATE_SQL
    s.bind(1, run_id);
    if (!s.step()) throw InputError(std::string(what) + ": unknown run " + quoted(run_id));
    RunState st{static_cast<int>(s.col_int(0)), status_from_text(s.col_text(1)), s.col_opt_int(2), std::nullopt,
                s.col_text(4), s.col_opt_text(5)};
    if (auto c = s.col_opt_int(3)) st.expected_checksum = std::bit_cast<std::uint64_t>(*c);
    s.reset();
    return st;
  }
  // InputError when retention dropped the run's samples: "WHAT 'RUN': its
  // samples were dropped by retention at T".
  static void require_samples(const RunState& st, const std::string& run_id, const char* what) {
    if (st.samples_dropped_at)
      throw InputError(std::string(what) + " " + quoted(run_id) + ": its samples were dropped by retention at " +
                       *st.samples_dropped_at);
  }
};

// historian_events.cc: inside the caller's write transaction, the events
// (their type, pump and data; seq and time given here) under the events'
// lock, NOTIFYing each on PostgreSQL. Returns the last one's seq.
std::int64_t write_events(Historian::Impl& impl, const std::vector<StoredEvent>& events);

// historian_trends.cc: inside the caller's write transaction, the run's
// points from these values, replacing those of an older analysis job (false,
// nothing written, when a newer job's are held or the run is not held).
bool put_run_series(Historian::Impl& impl, std::int64_t job_id, const std::string& pump_id, const std::string& run_id,
                    const std::vector<SeriesValue>& values);
// InputError (prefixed with `what`) for an empty name or a non-finite value or sd.
void check_series_values(const std::vector<SeriesValue>& values, const std::string& what);

}  // namespace ambdiag::storage
