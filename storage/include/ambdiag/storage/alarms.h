// What the historian keeps of alarms (schema v6; docs/storage.md): each
// pump's alarm rule versions, the alarms with their ANSI/ISA-18.2 state, the
// append-only journal of their transitions, and the evaluation's own memory
// (each rule's recent outcomes, the last run evaluated). The rules and the
// state machine live in the server (server/src/alarms); storage keeps what
// they decide and does not interpret it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace ambdiag::storage {

struct AlarmRulesVersion {
  std::string pump_id;
  int version = 0;
  std::string rules_json;  // as the engineer PUT it (the server validated it)
  std::string created_at, created_by;
};

// One alarm of one pump and rule. While its state is not `normal` it is the
// pump's only alarm of that rule (a later raise updates it); once `normal`
// it is closed and a new raise opens a new alarm.
struct AlarmRecord {
  std::int64_t alarm_id = 0;  // 0: not stored yet
  std::string pump_id, rule;
  std::string severity;       // low | medium | high | critical
  std::string state;          // rest.md's states
  bool active = false;        // the condition holds (or is latched)
  bool acknowledged = false;
  bool latched = false;       // stays active until an engineer resets it
  std::optional<std::string> shelved_until;  // shelved until then (ISO 8601 UTC)
  std::string suppressed_reason;             // plant-state suppression; empty: not suppressed
  bool out_of_service = false;               // its rule is disabled
  std::string raised_at;                     // server clock, ISO 8601 UTC
  std::optional<std::string> cleared_at;     // when it became normal (closed)
  std::string updated_at;
  std::string run_id;                        // the run that raised or last updated it
  std::string message;
  std::optional<std::string> fault;          // fault rules: the fault's name
  std::optional<double> value;               // the rule's value at the last update
};

// One journal entry: a transition of one alarm.
struct AlarmEvent {
  std::int64_t seq = 0;  // global, strictly increasing; 0: not stored yet
  std::int64_t alarm_id = 0;
  std::string pump_id, rule;
  std::string kind;  // raise, clear, ack, shelve, unshelve, shelve_expired, suppress, release, reset, update,
                     // out_of_service, in_service
  std::string time;  // server clock, ISO 8601 UTC with milliseconds
  std::string from, to;
  std::string by;       // the token's name, or "server"
  std::string comment;  // empty: none
  std::string run_id;   // empty: none
};

struct AlarmFilter {
  std::optional<std::string> pump_id;
  std::optional<std::string> state;
  std::optional<bool> active;
  int limit = 1000;
};

// Where a pump's alarm evaluation stands: the last run evaluated (runs are
// evaluated in (started_at, run_id) order) and the versions it ran against.
struct AlarmCursor {
  std::string pump_id;
  std::string started_at, run_id;
  int model_version = 0, reference_version = 0;
  std::optional<std::string> last_valid_at;  // server clock of the last run with a usable analysis
};

// What one evaluation or one operator action changes, written in one
// transaction by Historian::apply_alarm_changes.
struct AlarmChanges {
  std::vector<AlarmRecord> alarms;  // alarm_id 0: inserted (the id is filled in)
  // Each event names its alarm by index into `alarms` (its alarm_id, pump
  // and rule are taken from there); seq is filled in.
  std::vector<std::pair<std::size_t, AlarmEvent>> events;
  std::vector<std::pair<std::string, std::string>> memories;  // (rule, memory) of `pump_id`
  std::string pump_id;
  std::optional<AlarmCursor> cursor;
  bool empty() const { return alarms.empty() && events.empty() && memories.empty() && !cursor; }
};

}  // namespace ambdiag::storage
