// Historian: alarms (tables alarm_rules, alarms, alarm_events,
// alarm_conditions, alarm_cursors; schema v6). Storage keeps what the
// server's alarm engine decided; it checks only what the schema promises:
// one open alarm per pump and rule (the partial unique index) and an
// append-only journal (triggers), whose seq only grows (AUTOINCREMENT never
// reuses a number, even after the newest row's transaction rolled back).
#include <map>

#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

// After alarm_id: what an insert gives (alarm_id is the database's).
#define AMBDIAG_ALARM_VALUE_COLUMNS                                                                   \
  "pump_id, rule, severity, state, active, acknowledged, latched, shelved_until, suppressed_reason, " \
  "out_of_service, raised_at, cleared_at, updated_at, run_id, message, fault, value"
#define AMBDIAG_ALARM_COLUMNS "alarm_id, " AMBDIAG_ALARM_VALUE_COLUMNS

AlarmRecord read_alarm_row(const Stmt& s) {
  AlarmRecord a;
  a.alarm_id = s.col_int(0);
  a.pump_id = s.col_text(1);
  a.rule = s.col_text(2);
  a.severity = s.col_text(3);
  a.state = s.col_text(4);
  a.active = s.col_int(5) != 0;
  a.acknowledged = s.col_int(6) != 0;
  a.latched = s.col_int(7) != 0;
  a.shelved_until = s.col_opt_text(8);
  a.suppressed_reason = s.col_text(9);
  a.out_of_service = s.col_int(10) != 0;
  a.raised_at = s.col_text(11);
  a.cleared_at = s.col_opt_text(12);
  a.updated_at = s.col_text(13);
  a.run_id = s.col_text(14);
  a.message = s.col_text(15);
  a.fault = s.col_opt_text(16);
  if (!s.col_null(17)) a.value = s.col_double(17);
  return a;
}

#define AMBDIAG_EVENT_COLUMNS "seq, alarm_id, pump_id, rule, kind, time, from_state, to_state, by, comment, run_id"

AlarmEvent read_event_row(const Stmt& s) {
  return {s.col_int(0),   s.col_int(1),   s.col_text(2), s.col_text(3), s.col_text(4), s.col_text(5),
          s.col_text(6), s.col_text(7), s.col_text(8), s.col_text(9), s.col_text(10)};
}

// Binds the alarm's columns in AMBDIAG_ALARM_VALUE_COLUMNS order to
// parameters first, first + 1, ...
void bind_alarm(Stmt& s, const AlarmRecord& a, int first) {
  const int o = first - 2;  // the numbers below are those of first = 2
  s.bind(o + 2, a.pump_id)
      .bind(o + 3, a.rule)
      .bind(o + 4, a.severity)
      .bind(o + 5, a.state)
      .bind(o + 6, std::int64_t{a.active})
      .bind(o + 7, std::int64_t{a.acknowledged})
      .bind(o + 8, std::int64_t{a.latched})
      .bind(o + 10, a.suppressed_reason)
      .bind(o + 11, std::int64_t{a.out_of_service})
      .bind(o + 12, a.raised_at)
      .bind(o + 14, a.updated_at)
      .bind(o + 15, a.run_id)
      .bind(o + 16, a.message);
  if (a.shelved_until) s.bind(o + 9, *a.shelved_until); else s.bind_null(o + 9);
  if (a.cleared_at) s.bind(o + 13, *a.cleared_at); else s.bind_null(o + 13);
  if (a.fault) s.bind(o + 17, *a.fault); else s.bind_null(o + 17);
  if (a.value) s.bind(o + 18, *a.value); else s.bind_null(o + 18);
}

// Every row of a stepped-through statement, read by `read_row`.
template <class Row>
std::vector<Row> all_rows(Stmt& s, Row (*read_row)(const Stmt&)) {
  std::vector<Row> out;
  while (s.step()) out.push_back(read_row(s));
  return out;
}

std::string alarm_ref(const AlarmRecord& a) { return "alarm " + quoted(a.rule) + " of pump " + quoted(a.pump_id); }

}  // namespace

int Historian::put_alarm_rules(const std::string& pump_id, const std::string& rules_json, const std::string& created_by) {
  impl_->require_writer("put_alarm_rules");
  if (pump_id.empty()) throw InputError("put_alarm_rules: empty pump_id");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  impl_->register_pump(pump_id, now);
  const auto version = impl_->next_version("SELECT coalesce(max(version), 0) + 1 FROM alarm_rules WHERE pump_id = ?", pump_id);
  impl_->stmt("INSERT INTO alarm_rules (pump_id, version, rules_json, created_at, created_by) VALUES (?, ?, ?, ?, ?)")
      .bind(1, pump_id)
      .bind(2, version)
      .bind(3, rules_json)
      .bind(4, now)
      .bind(5, created_by)
      .run();
  tx.commit();
  return static_cast<int>(version);
}

std::optional<AlarmRulesVersion> Historian::find_alarm_rules(const std::string& pump_id) {
  auto& s = impl_->stmt(
      "SELECT version, rules_json, created_at, created_by FROM alarm_rules WHERE pump_id = ? ORDER BY version DESC LIMIT 1");
  s.bind(1, pump_id);
  if (!s.step()) return std::nullopt;
  AlarmRulesVersion v{pump_id, static_cast<int>(s.col_int(0)), s.col_text(1), s.col_text(2), s.col_text(3)};
  s.reset();
  return v;
}

void Historian::lock_pump_alarms(const std::string& pump_id) {
  impl_->require_writer("lock_pump_alarms");
  if (!impl_->db.in_transaction()) throw std::logic_error("Historian::lock_pump_alarms outside a write transaction");
  impl_->lock(Impl::LockSpace::pump_alarms, pump_id);
}

void Historian::apply_alarm_changes(AlarmChanges& c) {
  impl_->require_writer("apply_alarm_changes");
  for (const auto& [index, e] : c.events)
    if (index >= c.alarms.size()) throw InputError("apply_alarm_changes: an event names no alarm");
  Transaction tx(impl_->db, Transaction::Kind::write);
  // One journal writer at a time (PostgreSQL; SQLite's writers are one
  // anyway): the seqs then grow in commit order, so a reader polling
  // "after seq N" never misses one committed later with a smaller number;
  // and the open-alarm check below stays true until the insert.
  impl_->lock(Impl::LockSpace::alarm_journal, "");
  for (auto& a : c.alarms) {
    if (a.alarm_id == 0) {
      auto& open = impl_->stmt("SELECT alarm_id FROM alarms WHERE pump_id = ? AND rule = ? AND state <> 'normal'");
      open.bind(1, a.pump_id).bind(2, a.rule);
      if (a.state != "normal" && open.step())
        throw InputError("apply_alarm_changes: " + alarm_ref(a) + " is open already (alarm " +
                         std::to_string(open.col_int(0)) + ")");
      open.reset();
      auto& ins = impl_->stmt("INSERT INTO alarms (" AMBDIAG_ALARM_VALUE_COLUMNS
                              ") VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
                              "RETURNING alarm_id");
      bind_alarm(ins, a, 1);
      if (!ins.step()) throw StorageError("apply_alarm_changes: the insert returned no alarm_id");
      a.alarm_id = ins.col_int(0);
      ins.reset();
    } else {
      auto& up = impl_->stmt(
          "UPDATE alarms SET pump_id = ?2, rule = ?3, severity = ?4, state = ?5, active = ?6, acknowledged = ?7, "
          "latched = ?8, shelved_until = ?9, suppressed_reason = ?10, out_of_service = ?11, raised_at = ?12, "
          "cleared_at = ?13, updated_at = ?14, run_id = ?15, message = ?16, fault = ?17, value = ?18 WHERE alarm_id = ?1");
      up.bind(1, a.alarm_id);
      bind_alarm(up, a, 2);
      up.run();
      if (impl_->db.changes() != 1) throw InputError("apply_alarm_changes: no alarm " + std::to_string(a.alarm_id));
    }
  }
  auto& ev = impl_->stmt("INSERT INTO alarm_events (alarm_id, pump_id, rule, kind, time, from_state, to_state, by, comment, run_id) "
                         "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?) RETURNING seq");
  for (auto& [index, e] : c.events) {
    const AlarmRecord& a = c.alarms[index];
    e.alarm_id = a.alarm_id;
    e.pump_id = a.pump_id;
    e.rule = a.rule;
    ev.reset()
        .bind(1, e.alarm_id)
        .bind(2, e.pump_id)
        .bind(3, e.rule)
        .bind(4, e.kind)
        .bind(5, e.time)
        .bind(6, e.from)
        .bind(7, e.to)
        .bind(8, e.by)
        .bind(9, e.comment)
        .bind(10, e.run_id);
    if (!ev.step()) throw StorageError("apply_alarm_changes: the journal insert returned no seq");
    e.seq = ev.col_int(0);
  }
  ev.reset();
  auto& mem = impl_->stmt(
      "INSERT INTO alarm_conditions (pump_id, rule, memory) VALUES (?, ?, ?) "
      "ON CONFLICT (pump_id, rule) DO UPDATE SET memory = excluded.memory");
  for (const auto& [rule, memory] : c.memories) mem.reset().bind(1, c.pump_id).bind(2, rule).bind(3, memory).run();
  if (c.cursor) {
    auto& cur = impl_->stmt(
        "INSERT INTO alarm_cursors (pump_id, started_at, run_id, model_version, reference_version, last_valid_at) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6) ON CONFLICT (pump_id) DO UPDATE SET started_at = ?2, run_id = ?3, "
        "model_version = ?4, reference_version = ?5, last_valid_at = ?6");
    cur.bind(1, c.cursor->pump_id)
        .bind(2, c.cursor->started_at)
        .bind(3, c.cursor->run_id)
        .bind(4, std::int64_t{c.cursor->model_version})
        .bind(5, std::int64_t{c.cursor->reference_version});
    if (c.cursor->last_valid_at) cur.bind(6, *c.cursor->last_valid_at); else cur.bind_null(6);
    cur.run();
  }
  tx.commit();
}

std::optional<AlarmRecord> Historian::find_alarm(std::int64_t alarm_id) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_ALARM_COLUMNS " FROM alarms WHERE alarm_id = ?");
  s.bind(1, alarm_id);
  if (!s.step()) return std::nullopt;
  auto a = read_alarm_row(s);
  s.reset();
  return a;
}

std::vector<AlarmRecord> Historian::list_alarms(const AlarmFilter& f) {
  if (f.limit < 1) throw InputError("list_alarms: limit must be >= 1");
  auto& s = impl_->stmt("SELECT " AMBDIAG_ALARM_COLUMNS " FROM alarms WHERE (pump_id = ?1 OR ?1 IS NULL) "
                        "AND (state = ?2 OR ?2 IS NULL) AND (active = ?3 OR ?3 IS NULL) ORDER BY alarm_id DESC LIMIT ?4");
  if (f.pump_id) s.bind(1, *f.pump_id); else s.bind_null(1);
  if (f.state) s.bind(2, *f.state); else s.bind_null(2);
  if (f.active) s.bind(3, std::int64_t{*f.active}); else s.bind_null(3);
  s.bind(4, std::int64_t{f.limit});
  return all_rows(s, read_alarm_row);
}

std::vector<AlarmRecord> Historian::open_alarms(const std::string& pump_id) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_ALARM_COLUMNS " FROM alarms WHERE pump_id = ? AND state <> 'normal' ORDER BY rule");
  s.bind(1, pump_id);
  return all_rows(s, read_alarm_row);
}

std::vector<AlarmRecord> Historian::expired_shelves(const std::string& time) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_ALARM_COLUMNS " FROM alarms WHERE state = 'shelved' AND shelved_until <= ? ORDER BY alarm_id");
  s.bind(1, time);
  return all_rows(s, read_alarm_row);
}

std::vector<AlarmEvent> Historian::alarm_history(std::int64_t alarm_id) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_EVENT_COLUMNS " FROM alarm_events WHERE alarm_id = ? ORDER BY seq");
  s.bind(1, alarm_id);
  return all_rows(s, read_event_row);
}

std::vector<AlarmEvent> Historian::alarm_events(std::int64_t after_seq, int limit) {
  if (limit < 1) throw InputError("alarm_events: limit must be >= 1");
  auto& s = impl_->stmt("SELECT " AMBDIAG_EVENT_COLUMNS " FROM alarm_events WHERE seq > ? ORDER BY seq LIMIT ?");
  s.bind(1, after_seq).bind(2, std::int64_t{limit});
  return all_rows(s, read_event_row);
}

std::vector<AlarmEvent> Historian::alarm_events_between(const std::string& from, const std::string& to) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_EVENT_COLUMNS " FROM alarm_events WHERE time >= ? AND time < ? ORDER BY seq");
  s.bind(1, from).bind(2, to);
  return all_rows(s, read_event_row);
}

std::map<std::string, std::int64_t> Historian::count_active_alarms_by_severity() {
  auto& s = impl_->stmt("SELECT severity, count(*) FROM alarms WHERE active = 1 GROUP BY severity");
  std::map<std::string, std::int64_t> out;
  while (s.step()) out[s.col_text(0)] = s.col_int(1);
  s.reset();
  return out;
}

std::int64_t Historian::last_alarm_seq() {
  auto& s = impl_->stmt("SELECT coalesce(max(seq), 0) FROM alarm_events");
  s.step();
  const auto n = s.col_int(0);
  s.reset();
  return n;
}

std::vector<std::pair<std::string, std::string>> Historian::alarm_memories(const std::string& pump_id) {
  auto& s = impl_->stmt("SELECT rule, memory FROM alarm_conditions WHERE pump_id = ? ORDER BY rule");
  s.bind(1, pump_id);
  std::vector<std::pair<std::string, std::string>> out;
  while (s.step()) out.emplace_back(s.col_text(0), s.col_text(1));
  return out;
}

namespace {

AlarmCursor read_cursor_row(const Stmt& s) {
  return {s.col_text(0), s.col_text(1), s.col_text(2), static_cast<int>(s.col_int(3)), static_cast<int>(s.col_int(4)),
          s.col_opt_text(5)};
}

}  // namespace

std::optional<AlarmCursor> Historian::find_alarm_cursor(const std::string& pump_id) {
  auto& s = impl_->stmt(
      "SELECT pump_id, started_at, run_id, model_version, reference_version, last_valid_at FROM alarm_cursors WHERE pump_id = ?");
  s.bind(1, pump_id);
  if (!s.step()) return std::nullopt;
  auto c = read_cursor_row(s);
  s.reset();
  return c;
}

std::vector<AlarmCursor> Historian::list_alarm_cursors() {
  auto& s = impl_->stmt(
      "SELECT pump_id, started_at, run_id, model_version, reference_version, last_valid_at FROM alarm_cursors ORDER BY pump_id");
  return all_rows(s, read_cursor_row);
}

std::optional<RunInfo> Historian::next_run_for_alarms(const std::string& pump_id,
                                                      const std::optional<std::pair<std::string, std::string>>& after) {
  auto& s = impl_->stmt(
      "SELECT run_id FROM runs WHERE pump_id = ?1 AND status = 'complete' AND kind = 'identification' "
      "AND ((started_at, run_id) > (?2, ?3) OR ?2 IS NULL) ORDER BY started_at, run_id LIMIT 1");
  s.bind(1, pump_id);
  if (after) s.bind(2, after->first).bind(3, after->second); else s.bind_null(2).bind_null(3);
  if (!s.step()) return std::nullopt;
  const std::string run_id = s.col_text(0);
  s.reset();
  return find_run(run_id);
}

}  // namespace ambdiag::storage
