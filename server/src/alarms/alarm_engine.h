// The alarm evaluation of one run (or one clock tick for stale data), pure:
// no storage, no threads, no clock. Given the pump's rules, its alarms and
// each rule's memory, and what the run gave (run_series values and the
// context: run, speed, model speed, analysis status), it returns the
// changes: alarms raised, updated, returned, and their journal entries.
//
// Per rule (alarm_rules.h): a run whose value reaches a level counts 1 in
// the rule's window of its last n evaluated runs, else 0; k ones raise the
// alarm (on-delay). An active alarm returns after off_delay consecutive runs
// beyond the clear limit (hysteresis, off-delay), unless latched. A run that
// gives the rule no value (analysis failed, no reference, the diagnosis
// named another fault, the mode was not identified) is not evaluated for
// it: missing data never moves a window, so it never clears an alarm. A run
// at a speed outside the plant-state band, or a stopped pump, suppresses the
// analysis alarms (every rule but stale_data) with the reason while the
// evaluation goes on.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "alarms/alarm_rules.h"
#include "alarms/alarm_state.h"
#include "ambdiag/storage/alarms.h"
#include "trends/run_series.h"

namespace ambdiag::server::detail {

// A rule's memory between runs (stored as JSON text per pump and rule).
struct ConditionMemory {
  std::string window;  // the last n outcomes, oldest first: '1' reached a level, '0' not
  int clear_runs = 0;  // consecutive evaluated runs beyond the clear limit
  std::string to_text() const;
  static ConditionMemory from_text(const std::string& text);  // empty memory for bad text
};

// The normal value of a series over the pump's reference runs.
struct SeriesReference {
  double mean = 0.0, sd = 0.0;
  int n = 0;
};

struct RunFacts {
  std::string pump_id, run_id;
  std::string time;              // server clock of the evaluation (journal time), iso_ms
  bool analysis_failed = false;  // the analysis job failed
  std::string error;
  double speed_rpm = 0.0;
  std::optional<double> model_speed_rpm;
  bool has_detection = false;    // the pump had a reference: detection ran
  bool detected = false;
  std::optional<std::string> best_fault;  // the diagnosis' best-ranked fault
  std::vector<SeriesValue> values;        // run_series of the analysis result
  std::map<std::string, SeriesReference> reference;  // by series name (mode.LABEL.f_hz, ...)
  std::optional<double> displacement_m;  // the largest orbit displacement since the previous run
  std::optional<double> clearance_m;     // the plant model's touchdown clearance, when it has one
};

// The pump's alarm state the engine works on, updated in place.
struct PumpAlarms {
  std::map<std::string, ConditionMemory> memory;      // by alarm rule id
  std::map<std::string, storage::AlarmRecord> open;   // not normal, by rule id
};

// Evaluates every rule on the run. The returned changes hold each alarm
// that changed (new ones with alarm_id 0), its journal entries, and the
// memory of every rule evaluated; `pump` is updated (closed alarms leave
// `open`, new ones enter it with alarm_id 0 until the caller stores them).
storage::AlarmChanges evaluate_run(const AlarmRuleSet& rules, PumpAlarms& pump, const RunFacts& run);

// stale_data at a clock tick: `age_s` seconds since the pump's last run with
// a usable analysis.
storage::AlarmChanges evaluate_stale(const AlarmRuleSet& rules, PumpAlarms& pump, const std::string& pump_id, double age_s,
                                     const std::string& time);

// Why a run's analysis alarms are suppressed; empty when they are not.
std::string suppression_reason(const AlarmRuleSet& rules, double speed_rpm, std::optional<double> model_speed_rpm);

// ISO 14839-2 zone of displacement / clearance: A < 0.3 <= B < 0.4 <= C < 0.5 <= D.
char orbit_zone(double ratio);

}  // namespace ambdiag::server::detail
