// Historian: the events table (schema v8; events.h). Appended inside the
// caller's transaction (a WriteBatch: the event commits with what it
// announces), read by seq by each REST process' tail, which PostgreSQL's
// NOTIFY wakes at the commit (event_listener.h).
#include <algorithm>
#include <chrono>

#include "ambdiag/storage/historian.h"
#include "events_channel.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

#define AMBDIAG_EVENT_COLUMNS "seq, time, type, pump_id, data"

StoredEvent read_event_row(const Stmt& s) {
  return {s.col_int(0), s.col_text(1), s.col_text(2), s.col_text(3), s.col_text(4)};
}

// Inside the caller's write transaction.
int prune_events_in(Historian::Impl& impl, std::int64_t keep_rows, const std::string& older_than) {
  // The newest keep_rows by seq (seqs grow by one but for rolled-back
  // inserts, so this keeps at most keep_rows), and nothing older than the
  // cutoff: time grows with seq, so the second walk stops at the first
  // event it keeps.
  impl.stmt(
          "DELETE FROM events WHERE seq <= (SELECT max(seq) FROM events) - ?1 "
          "OR seq < coalesce((SELECT seq FROM events WHERE time >= ?2 ORDER BY seq LIMIT 1), "
          "(SELECT max(seq) + 1 FROM events))")
      .bind(1, std::max<std::int64_t>(0, keep_rows))
      .bind(2, older_than)
      .run();
  return static_cast<int>(impl.db.changes());
}

}  // namespace

std::int64_t write_events(Historian::Impl& impl, const std::vector<StoredEvent>& events) {
  // PostgreSQL hands seqs out at the INSERT but transactions commit in any
  // order: seq 11 could be visible before 10, and a tail that read up to 11
  // would never see 10. Held until the commit, the lock makes the events
  // commit in seq order (SQLite: BEGIN IMMEDIATE already did). Taken last
  // (nothing else is locked after it), it cannot be part of a deadlock.
  impl.lock(Historian::Impl::LockSpace::events, "");
  const std::string now = now_utc();  // inside: time grows with seq (prune_events relies on it)
  std::int64_t seq = 0;
  bool prune = false;
  for (const auto& e : events) {
    auto& ins = impl.stmt("INSERT INTO events (time, type, pump_id, data) VALUES (?, ?, ?, ?) RETURNING seq");
    ins.bind(1, now).bind(2, e.type).bind(3, e.pump_id).bind(4, e.data_json);
    if (!ins.step()) throw StorageError("append_event: the insert returned no seq");
    seq = ins.col_int(0);
    ins.reset();
    prune = prune || seq % kEventsPruneEvery == 0;
  }
  // PostgreSQL: wakes every REST process' tail (EventListener) when this
  // transaction commits, not at its next poll; a rolled-back one sends
  // nothing. One for the transaction's events; the payload is the last
  // seq, for whoever watches the channel.
  if (impl.dialect() == Dialect::postgres)
    impl.stmt("SELECT pg_notify(" AMBDIAG_EVENTS_CHANNEL_SQL ", CAST(CAST(? AS bigint) AS text))").bind(1, seq).run();
  // Bounded: one event in kEventsPruneEvery pays for the pruning (two
  // index walks from the oldest end), so an append stays one insert.
  if (prune) prune_events_in(impl, kEventsKeepRows, utc_ms(std::chrono::system_clock::now() - kEventsKeep));
  return seq;
}

std::int64_t Historian::append_event(const std::string& type, const std::string& pump_id, const std::string& data_json) {
  impl_->require_writer("append_event");
  if (type.empty() || type.find_first_of("\r\n") != std::string::npos)
    throw InputError("append_event: the type must be one non-empty line");
  if (data_json.find_first_of("\r\n") != std::string::npos)
    throw InputError("append_event " + quoted(type) + ": the data must be one line of JSON");
  if (impl_->batch_tx) {  // written by the batch's commit (the events' lock last)
    impl_->batch_events.push_back({0, "", type, pump_id, data_json});
    return 0;
  }
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::int64_t seq = write_events(*impl_, {{0, "", type, pump_id, data_json}});
  tx.commit();
  return seq;
}

int Historian::prune_events(std::int64_t keep_rows, const std::string& older_than) {
  impl_->require_writer("prune_events");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const int n = prune_events_in(*impl_, keep_rows, older_than);
  tx.commit();
  return n;
}

std::vector<StoredEvent> Historian::events_after(std::int64_t after_seq, int limit) {
  if (limit < 1) throw InputError("events_after: limit must be >= 1");
  auto& s = impl_->stmt("SELECT " AMBDIAG_EVENT_COLUMNS " FROM events WHERE seq > ? ORDER BY seq LIMIT ?");
  s.bind(1, after_seq).bind(2, std::int64_t{limit});
  std::vector<StoredEvent> out;
  while (s.step()) out.push_back(read_event_row(s));
  return out;
}

std::vector<StoredEvent> Historian::recent_events(int limit) {
  if (limit < 1) throw InputError("recent_events: limit must be >= 1");
  auto& s = impl_->stmt("SELECT " AMBDIAG_EVENT_COLUMNS " FROM events ORDER BY seq DESC LIMIT ?");
  s.bind(1, std::int64_t{limit});
  std::vector<StoredEvent> out;
  while (s.step()) out.push_back(read_event_row(s));
  std::reverse(out.begin(), out.end());
  return out;
}

std::int64_t Historian::last_event_seq() {
  // The sequence itself, not max(seq): pruning may have emptied the table.
  // PostgreSQL: a sequence is outside transactions and its value may be an
  // append not yet committed, so the newest event the snapshot sees, and
  // only for an empty table the sequence, less the one that may be in
  // flight (appends hold their lock from nextval to commit: one at most).
  auto& s = impl_->dialect() == Dialect::postgres
                ? impl_->stmt("SELECT coalesce((SELECT max(seq) FROM events), (SELECT last_value - 1 FROM events_seq_seq))")
                : impl_->stmt("SELECT coalesce((SELECT seq FROM sqlite_sequence WHERE name = 'events'), 0)");
  s.step();
  const auto seq = s.col_int(0);
  s.reset();
  return seq;
}

std::optional<std::int64_t> Historian::first_event_seq() {
  auto& s = impl_->stmt("SELECT min(seq) FROM events");
  s.step();
  const auto seq = s.col_opt_int(0);
  s.reset();
  return seq;
}

}  // namespace ambdiag::storage
