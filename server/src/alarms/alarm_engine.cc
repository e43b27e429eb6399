#include "alarms/alarm_engine.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;
using storage::AlarmChanges;
using storage::AlarmEvent;
using storage::AlarmRecord;

// What a run tells one rule.
struct Observation {
  enum Kind { missing, healthy, value, failed } kind = missing;
  double v = 0.0;
  std::string message;
  std::optional<std::string> fault;
};

std::string num(double v, const char* format = "%.4g") {
  char b[48];
  std::snprintf(b, sizeof b, format, v);
  return b;
}

const SeriesValue* series(const RunFacts& run, const std::string& name) {
  for (const auto& s : run.values)
    if (s.name == name) return &s;
  return nullptr;
}

// The changes of one evaluation: alarms touched (by rule id) and events.
class Evaluation {
 public:
  Evaluation(PumpAlarms& pump, std::string pump_id, std::string time, std::string run_id)
      : pump_(pump), pump_id_(std::move(pump_id)), time_(std::move(time)), run_id_(std::move(run_id)) {}

  // One rule instance (`id`: "mode.X.f_hz" for the template rule "mode.*.f_hz").
  void step(const AlarmRule& rule, const std::string& id, const Observation& obs, const std::string& suppress) {
    AlarmRecord* open = find_open(id);
    if (!rule.enabled) {
      if (open && !open->out_of_service)
        record(id, change_alarm(*open, "out_of_service", actor("rule disabled"), [](AlarmRecord& a) { a.out_of_service = true; }));
      return;
    }
    if (open && open->out_of_service)
      record(id, change_alarm(*open, "in_service", actor("rule enabled"), [](AlarmRecord& a) { a.out_of_service = false; }));
    if (open && open->suppressed_reason != suppress)
      record(id, change_alarm(*open, suppress.empty() ? "release" : "suppress", actor(suppress.empty() ? "plant state normal" : suppress),
                              [&](AlarmRecord& a) { a.suppressed_reason = suppress; }));
    if (obs.kind == Observation::missing) return;

    ConditionMemory& mem = pump_.memory[id];
    touched_memory_.insert(id);
    // The highest level reached; a failed analysis reaches the first.
    int level = obs.kind == Observation::failed ? 0 : -1;
    if (obs.kind == Observation::value)
      for (size_t i = 0; i < rule.levels.size(); ++i)
        if (rule.below ? obs.v <= rule.levels[i].raise : obs.v >= rule.levels[i].raise) level = static_cast<int>(i);
    const bool beyond_clear = obs.kind == Observation::healthy ||
                              (obs.kind == Observation::value && (rule.below ? obs.v > rule.clear : obs.v < rule.clear));
    mem.window.push_back(level >= 0 ? '1' : '0');
    if (mem.window.size() > static_cast<size_t>(rule.on_n)) mem.window.erase(0, mem.window.size() - rule.on_n);
    const auto reached = std::count(mem.window.begin(), mem.window.end(), '1');
    const std::optional<double> value = obs.kind == Observation::value ? std::optional<double>(obs.v) : std::nullopt;
    const auto update = [&](AlarmRecord& a) {
      a.run_id = run_id_;
      a.message = obs.message;
      a.value = value;
      if (obs.fault) a.fault = obs.fault;
    };
    const auto escalate = [&](AlarmRecord& a, Severity s) {
      if (severity_from(a.severity).value_or(Severity::low) < s) a.severity = to_string(s);
      if (rule.latch && severity_from(a.severity).value_or(Severity::low) >= *rule.latch) a.latched = true;
    };

    if (!(open && open->active)) {
      if (reached < rule.on_k) return;
      const Severity s = rule.levels[static_cast<size_t>(std::max(level, 0))].severity;
      mem.clear_runs = 0;
      if (open) {  // returned but not acknowledged: the same alarm comes back
        record(id, change_alarm(*open, "raise", actor(obs.message), [&](AlarmRecord& a) {
          a.active = true;
          a.severity = to_string(s);
          update(a);
          escalate(a, s);
        }));
        return;
      }
      AlarmRecord a;
      a.pump_id = pump_id_;
      a.rule = id;
      a.raised_at = time_;
      a.suppressed_reason = suppress;
      AlarmEvent e = change_alarm(a, "raise", actor(obs.message), [&](AlarmRecord& x) {
        x.active = true;
        x.severity = to_string(s);
        update(x);
        escalate(x, s);
      });
      pump_.open[id] = a;
      record(id, std::move(e));
      return;
    }
    // Active: the run updates it (no second alarm), escalates it, or counts
    // towards its return.
    mem.clear_runs = beyond_clear ? mem.clear_runs + 1 : 0;
    const Severity before = severity_from(open->severity).value_or(Severity::low);
    update(*open);
    if (level >= 0 && rule.levels[static_cast<size_t>(level)].severity > before)
      record(id, change_alarm(*open, "update", actor("severity " + open->severity + " -> " +
                                                      to_string(rule.levels[static_cast<size_t>(level)].severity) + ": " + obs.message),
                              [&](AlarmRecord& a) { escalate(a, rule.levels[static_cast<size_t>(level)].severity); }));
    else
      touched_.insert(id);
    if (mem.clear_runs >= rule.off_delay && !open->latched) {
      record(id, change_alarm(*open, "clear", actor(obs.message), [](AlarmRecord& a) { a.active = false; }));
      mem.window.clear();
    }
  }

  AlarmChanges finish() {
    AlarmChanges c;
    c.pump_id = pump_id_;
    std::map<std::string, size_t> index;
    for (const auto& id : touched_) {
      index[id] = c.alarms.size();
      c.alarms.push_back(pump_.open.at(id));
    }
    for (auto& [id, e] : events_) c.events.emplace_back(index.at(id), std::move(e));
    for (const auto& id : touched_memory_) c.memories.emplace_back(id, pump_.memory[id].to_text());
    std::erase_if(pump_.open, [](const auto& kv) { return kv.second.state == "normal"; });
    return c;
  }

 private:
  AlarmRecord* find_open(const std::string& id) {
    const auto it = pump_.open.find(id);
    return it == pump_.open.end() ? nullptr : &it->second;
  }
  AlarmActor actor(const std::string& comment) const { return {"server", time_, comment, run_id_}; }
  void record(const std::string& id, AlarmEvent e) {
    touched_.insert(id);
    events_.emplace_back(id, std::move(e));
  }

  PumpAlarms& pump_;
  std::string pump_id_, time_, run_id_;
  std::set<std::string> touched_, touched_memory_;
  std::vector<std::pair<std::string, AlarmEvent>> events_;
};

Observation fault_observation(const AlarmRule& rule, const RunFacts& run) {
  Observation o;
  if (run.analysis_failed || !run.has_detection) return o;
  const std::string name = rule.id.substr(6);
  if (!run.detected) {
    o.kind = Observation::healthy;
    o.message = "no change detected";
    return o;
  }
  // Detected, but the diagnosis named another fault: nothing said of this one.
  if (run.best_fault != name) return o;
  const SeriesValue* s = series(run, rule.id + "." + rule.parameter);
  if (!s) return o;
  o.kind = Observation::value;
  o.v = rule.nominal ? std::abs(s->value - *rule.nominal) : s->value;
  o.fault = name;
  o.message = name + ": " + rule.parameter + " " + num(s->value) + (s->sd ? " (sd " + num(*s->sd, "%.2g") + ")" : "");
  return o;
}

Observation mode_observation(const AlarmRule& rule, const SeriesValue& s, const RunFacts& run) {
  Observation o;
  const auto ref = run.reference.find(s.name);
  if (ref == run.reference.end() || ref->second.n < 2 || !(std::abs(ref->second.mean) > 0)) return o;
  const double shift = s.value / ref->second.mean - 1.0;
  const double limit = std::max(rule.min_relative_shift, rule.k_sd * ref->second.sd / std::abs(ref->second.mean));
  o.kind = Observation::value;
  o.v = std::abs(shift) / limit;
  o.message = s.name + " " + num(s.value) + " " + s.unit + ", " + num(100.0 * shift, "%+.2f") + " % from the reference " +
              num(ref->second.mean) + " (limit " + num(100.0 * limit, "%.2f") + " %)";
  return o;
}

}  // namespace

std::string ConditionMemory::to_text() const { return json{{"window", window}, {"clear_runs", clear_runs}}.dump(); }

ConditionMemory ConditionMemory::from_text(const std::string& text) {
  ConditionMemory m;
  try {
    const json j = json::parse(text);
    m.window = j.value("window", "");
    m.clear_runs = j.value("clear_runs", 0);
  } catch (const json::exception&) {
  }
  return m;
}

std::string suppression_reason(const AlarmRuleSet& rules, double speed_rpm, std::optional<double> model_speed_rpm) {
  if (speed_rpm < rules.stopped_below_rpm)
    return "pump stopped: run at " + num(speed_rpm, "%.0f") + " rpm (below " + num(rules.stopped_below_rpm, "%.0f") + " rpm)";
  if (model_speed_rpm && *model_speed_rpm > 0 && std::abs(speed_rpm / *model_speed_rpm - 1.0) > rules.speed_band)
    return "run at " + num(speed_rpm, "%.0f") + " rpm, outside the trusted band " +
           num(*model_speed_rpm * (1 - rules.speed_band), "%.0f") + ".." + num(*model_speed_rpm * (1 + rules.speed_band), "%.0f") +
           " rpm (model " + num(*model_speed_rpm, "%.0f") + " rpm +-" + num(100 * rules.speed_band, "%.3g") + " %)";
  return "";
}

char orbit_zone(double ratio) { return ratio < 0.3 ? 'A' : ratio < 0.4 ? 'B' : ratio < 0.5 ? 'C' : 'D'; }

AlarmChanges evaluate_run(const AlarmRuleSet& rules, PumpAlarms& pump, const RunFacts& run) {
  Evaluation ev(pump, run.pump_id, run.time, run.run_id);
  const std::string suppress = suppression_reason(rules, run.speed_rpm, run.model_speed_rpm);
  const bool usable = !run.analysis_failed;
  // An analysis alarm carries the fault its run was diagnosed with, if any.
  const std::optional<std::string> diagnosed =
      run.detected && run.best_fault && *run.best_fault != "unknown" ? run.best_fault : std::nullopt;
  for (const auto& rule : rules.rules) {
    Observation o;
    switch (rule.kind) {
      case RuleKind::detection:
        if (usable && run.has_detection)
          if (const auto* s = series(run, "detection.ratio")) {
            o.kind = Observation::value;
            o.v = s->value;
            o.message = std::string(run.detected ? "change detected" : "no change detected") + ": statistic / threshold " + num(s->value) +
                        (run.best_fault ? ", diagnosis: " + *run.best_fault : "");

          }
        break;
      case RuleKind::fault: o = fault_observation(rule, run); break;
      case RuleKind::mode_f:
      case RuleKind::mode_zeta:
        if (rule.is_template()) continue;  // instances below, one per labelled mode
        if (const auto* s = series(run, rule.id); s && usable) o = mode_observation(rule, *s, run);
        break;
      case RuleKind::orbit_zone: {
        const auto clearance = rule.clearance_m ? rule.clearance_m : run.clearance_m;
        if (clearance && run.displacement_m) {
          o.kind = Observation::value;
          o.v = *run.displacement_m / *clearance;
          o.message = "orbit " + num(*run.displacement_m * 1e6, "%.1f") + " um = " + num(o.v, "%.2f") + " of the " +
                      num(*clearance * 1e6, "%.0f") + " um touchdown clearance: ISO 14839-2 zone " + orbit_zone(o.v);
        }
        break;
      }
      case RuleKind::stale_data:
        if (usable) {
          o.kind = Observation::healthy;
          o.message = "run " + run.run_id + " analysed";
        }
        break;
      case RuleKind::poor_data:
        if (run.analysis_failed) {
          o.kind = Observation::failed;
          o.message = "analysis failed: " + run.error;
        } else if (!run.detected) {  // a detected change explains a misfit
          if (const auto* s = series(run, "fit.nrmse")) {
            o.kind = Observation::value;
            o.v = s->value / rule.nrmse_limit;
            o.message = "fit.nrmse " + num(s->value) + " (limit " + num(rule.nrmse_limit) + ")";
          }
        }
        break;
    }
    if (rule.kind != RuleKind::fault && rule.kind != RuleKind::stale_data) o.fault = diagnosed;
    ev.step(rule, rule.id, o, rule.kind == RuleKind::stale_data ? "" : suppress);
  }
  // Template mode rules: one alarm per labelled mode the run identified
  // that has no rule of its own.
  if (usable)
    for (const auto& s : run.values) {
      if (!s.name.starts_with("mode.")) continue;
      const AlarmRule* rule = rules.find(s.name);
      if (!rule || !rule->is_template()) continue;
      Observation o = mode_observation(*rule, s, run);
      o.fault = diagnosed;
      ev.step(*rule, s.name, o, suppress);
    }
  return ev.finish();
}

AlarmChanges evaluate_stale(const AlarmRuleSet& rules, PumpAlarms& pump, const std::string& pump_id, double age_s,
                            const std::string& time) {
  Evaluation ev(pump, pump_id, time, "");
  const AlarmRule* rule = rules.find("stale_data");
  if (!rule) return ev.finish();
  Observation o;
  o.kind = Observation::value;
  o.v = age_s / rule->limit_s;
  o.message = "no valid run for " + num(age_s / 3600.0, "%.1f") + " h (limit " + num(rule->limit_s / 3600.0, "%.3g") + " h)";
  // The tick only raises: a stale alarm returns with the next valid run.
  const bool active = pump.open.contains("stale_data") && pump.open.at("stale_data").active;
  if (active || o.v < rule->levels.front().raise) return ev.finish();
  ev.step(*rule, "stale_data", o, "");
  return ev.finish();
}

}  // namespace ambdiag::server::detail
