// The alarm engine (alarm_engine.h) on the historian: which run is
// evaluated next, what it gives the engine, and storing what the engine
// decided, each run in one write transaction together with the pump's
// evaluation cursor.
//
// Order: a pump's runs are evaluated in (started_at, run_id) order, each
// once its current analysis job has ended (done or failed). An analysis
// that finishes before an older run's (two workers) waits for it: the
// evaluation stops at the first run whose analysis is still queued or
// running, and goes on when that one ends. A run that completes after a
// newer run was evaluated is not evaluated (it is in the history, not in
// the alarms). When a pump gets its first reference, the runs after the
// reference's newest run are evaluated again against it (their analyses are
// redone with detection), so a fault streamed before the reference was set
// still raises its alarm on its own run.
//
// Durability: the cursor is stored in the same transaction as the alarms,
// so an evaluation lost to a crash between an analysis' commit and its
// evaluation is made at the next start (catch_up of every pump).
//
// Threads: an AlarmEvaluator holds caches only; use one per thread, with
// that thread's writer connection. Evaluations of one pump from several
// connections serialise on SQLite's write lock and each re-reads the cursor.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <tuple>

#include <nlohmann/json.hpp>

#include "alarms/alarm_engine.h"
#include "alarms/alarm_rules.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

// Called after each commit with each new journal entry (alarm_event_json).
using AlarmEventSink = std::function<void(const nlohmann::json&)>;

// The pump's effective rules: `defaults` (a validated rule set) with the
// pump's newest PUT applied.
AlarmRuleSet pump_rule_set(storage::Historian& h, const std::string& pump_id, const nlohmann::json& defaults);
// The pump's open alarms and each rule's memory.
PumpAlarms load_pump_alarms(storage::Historian& h, const std::string& pump_id);

class AlarmEvaluator {
 public:
  AlarmEvaluator(const nlohmann::json& defaults, AlarmEventSink sink) : defaults_(defaults), sink_(std::move(sink)) {}

  // Evaluates the pump's runs whose analyses have ended, oldest first.
  // Returns how many runs were evaluated.
  int catch_up(storage::Historian& h, const std::string& pump_id);
  // The clock's part: shelves that expired and, with check_stale, stale data
  // of every evaluated pump.
  void tick(storage::Historian& h, std::int64_t now_ns, bool check_stale);
  // Stores the changes in the caller's open write batch and tells the sink after commit.
  void commit(storage::Historian::WriteBatch& batch, storage::Historian& h, storage::AlarmChanges& changes);

 private:
  RunFacts run_facts(storage::Historian& h, const storage::RunInfo& run, const storage::Job& job, int m, int r,
                     const std::optional<storage::AlarmCursor>& cursor);
  std::map<std::string, SeriesReference> reference_of(storage::Historian& h, const std::string& pump_id, int m, int r);
  const AlarmRuleSet& rules_of(storage::Historian& h, const std::string& pump_id);

  const nlohmann::json& defaults_;
  AlarmEventSink sink_;
  struct Plant {
    std::optional<double> speed_rpm, clearance_m;
  };
  std::map<std::pair<std::string, int>, Plant> plants_;  // by (pump, model version)
  std::map<std::tuple<std::string, int, int>, std::map<std::string, SeriesReference>> references_;
  std::map<std::string, std::pair<int, AlarmRuleSet>> rules_;  // by pump: (rules version, set)
};

// rest.md's alarm and journal entry.
nlohmann::json alarm_json(const storage::AlarmRecord& a);
nlohmann::json alarm_event_json(const storage::AlarmEvent& e, bool fleet);

}  // namespace ambdiag::server::detail
