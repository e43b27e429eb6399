// Alarm rules (rest.md "Alarms"; docs/service.md "Alarms"): what raises and
// clears a pump's alarms, as plain JSON. A rule set is
//
//   {"plant_state": {"speed_band": 0.05, "stopped_below_rpm": 60},
//    "rules": [{"id": "detection", "levels": [{"severity": "medium", "raise": 1.0}], "clear": 0.8,
//               "on_delay": {"k": 2, "n": 3}, "off_delay": 3, "latch": null, "enabled": true}, ...]}
//
// Every rule turns a run into one value (detection.ratio, a fault parameter,
// a mode's normalised shift, the orbit over the touchdown clearance, the data
// age over its limit, the NRMSE over its limit) and compares it with its
// levels: the alarm is raised at the highest level's severity the value
// reaches ("direction": "below" for parameters that fall with a fault),
// after k of the last n evaluated runs reached a level (on-delay), and
// returns after `off_delay` consecutive runs beyond the lower `clear` limit
// (hysteresis). Once `latch` severity is reached it stays active until an
// engineer resets it.
//
// The server's defaults are built in (default_rule_set_json), optionally
// overridden by `ambdiag serve --alarm-defaults FILE`; a pump's PUT overrides
// the defaults rule by rule: a rule of the same id is the default with the
// given keys replaced; rules not named keep the default. Both are validated
// here with messages naming the field ("rules[2].on_delay.k: must be <= n").
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::server::detail {

enum class Severity { low = 0, medium = 1, high = 2, critical = 3 };
std::string to_string(Severity s);
std::optional<Severity> severity_from(const std::string& s);

enum class RuleKind { detection, fault, mode_f, mode_zeta, orbit_zone, stale_data, poor_data };

struct AlarmLevel {
  Severity severity = Severity::medium;
  double raise = 0.0;  // reached when value >= raise (direction above) or <= raise (below)
};

struct AlarmRule {
  std::string id;  // "detection", "fault.NAME", "mode.LABEL.f_hz" or the template "mode.*.f_hz", ...
  RuleKind kind = RuleKind::detection;
  bool enabled = true;  // false: its alarm is out_of_service
  std::vector<AlarmLevel> levels;  // ordered by severity, each beyond the one before
  double clear = 0.0;              // returns once beyond this (below it for direction above)
  bool below = false;              // direction: a fault parameter that falls (EI_factor, fluid_factor)
  int on_k = 1, on_n = 1;          // raised when k of the last n evaluated runs reached a level
  int off_delay = 1;               // returns after this many consecutive runs beyond `clear`
  std::optional<Severity> latch;   // latched once this severity is reached
  // fault.NAME: the parameter compared; with `nominal`, |parameter - nominal|.
  std::string parameter;
  std::optional<double> nominal;
  // mode.*: value = |x / x_ref - 1| / max(min_relative_shift, k_sd * sd_ref / x_ref), x_ref and sd_ref
  // the mean and sd of the mode's value over the pump's reference runs.
  double min_relative_shift = 0.05;
  double k_sd = 6.0;
  std::optional<double> clearance_m;  // orbit_zone: the touchdown (retainer) bearing clearance
  double limit_s = 86400.0;           // stale_data: value = seconds without a valid run / limit_s
  double nrmse_limit = 0.3;           // poor_data: value = fit.nrmse / nrmse_limit (a failed analysis: above all)

  bool is_template() const { return id.find('*') != std::string::npos; }
  nlohmann::json to_json() const;
};

struct AlarmRuleSet {
  double speed_band = 0.05;          // analysis alarms suppressed outside model speed * (1 +- band)
  double stopped_below_rpm = 60.0;   // ... and for a run below this speed (pump stopped)
  std::vector<AlarmRule> rules;

  // The rule for an alarm id: the exact one, else the template it matches
  // ("mode.*.f_hz" for "mode.X.f_hz"). nullptr when none.
  const AlarmRule* find(const std::string& id) const;
  nlohmann::json to_json() const;
};

// The built-in defaults (docs/service.md says why each number).
nlohmann::json default_rule_set_json();

// `base` (a valid rule set's JSON) with `overrides` applied rule by rule and
// validated: InputError naming the field of `overrides` ("rules[2].clear:
// ...") or, prefixed with `what`, of the result.
AlarmRuleSet merge_rule_sets(const nlohmann::json& base, const nlohmann::json& overrides, const std::string& what);
// The same, returning the merged JSON (what a pump's GET shows).
nlohmann::json merged_rule_set_json(const nlohmann::json& base, const nlohmann::json& overrides, const std::string& what);
// Parses and validates a full rule set.
AlarmRuleSet rule_set_from_json(const nlohmann::json& j, const std::string& what);

}  // namespace ambdiag::server::detail
