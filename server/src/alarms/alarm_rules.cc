#include "alarms/alarm_rules.h"

#include <cmath>
#include <map>
#include <set>

#include "ambdiag/core/error.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

constexpr Severity kSeverities[] = {Severity::low, Severity::medium, Severity::high, Severity::critical};

std::optional<RuleKind> kind_of(const std::string& id) {
  if (id == "detection") return RuleKind::detection;
  if (id == "orbit_zone") return RuleKind::orbit_zone;
  if (id == "stale_data") return RuleKind::stale_data;
  if (id == "poor_data") return RuleKind::poor_data;
  if (id.size() > 6 && id.starts_with("fault.") && id.find('*') == std::string::npos) return RuleKind::fault;
  if (id.size() > 10 && id.starts_with("mode.")) {
    const std::string label = id.ends_with(".f_hz") ? id.substr(5, id.size() - 10)
                              : id.ends_with(".zeta") ? id.substr(5, id.size() - 10) : "";
    if (label.empty() || (label.find('*') != std::string::npos && label != "*")) return std::nullopt;
    return id.ends_with(".f_hz") ? RuleKind::mode_f : RuleKind::mode_zeta;
  }
  return std::nullopt;
}

// Reads one rule's JSON; `at` is its place ("rules[2]") for the messages.
class RuleReader {
 public:
  RuleReader(const json& j, std::string at) : j_(j), at_(std::move(at)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw InputError(at_ + (key.empty() ? "" : "." + key) + ": " + what);
  }
  bool has(const char* key) const { return j_.contains(key) && !j_[key].is_null(); }
  double number(const char* key, double def, double lo, double hi) const {
    if (!has(key)) return def;
    if (!j_[key].is_number()) fail(key, "must be a number");
    const double v = j_[key].get<double>();
    if (!std::isfinite(v) || v < lo || v > hi) fail(key, "must be in [" + fmt(lo) + ", " + fmt(hi) + "]");
    return v;
  }
  int integer(const json& j, const std::string& key, int lo, int hi) const {
    if (!j.is_number_integer()) fail(key, "must be an integer");
    const auto v = j.get<std::int64_t>();
    if (v < lo || v > hi) fail(key, "must be in " + std::to_string(lo) + ".." + std::to_string(hi));
    return static_cast<int>(v);
  }
  Severity severity(const json& j, const std::string& key) const {
    if (!j.is_string() || !severity_from(j.get<std::string>())) fail(key, "must be low, medium, high or critical");
    return *severity_from(j.get<std::string>());
  }
  static std::string fmt(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }

  AlarmRule read() const {
    if (!j_.is_object()) fail("", "must be an object");
    AlarmRule r;
    if (!j_.contains("id") || !j_["id"].is_string()) fail("id", "must be a string");
    r.id = j_["id"].get<std::string>();
    const auto kind = kind_of(r.id);
    if (!kind)
      fail("id", "unknown rule '" + r.id +
                     "' (detection, fault.NAME, mode.LABEL.f_hz, mode.LABEL.zeta, mode.*.f_hz, mode.*.zeta, orbit_zone, "
                     "stale_data, poor_data)");
    r.kind = *kind;
    std::set<std::string> allowed = {"id", "enabled", "levels", "clear", "on_delay", "off_delay", "latch", "comment"};
    switch (r.kind) {
      case RuleKind::fault: allowed.insert({"parameter", "nominal", "direction"}); break;
      case RuleKind::mode_f:
      case RuleKind::mode_zeta: allowed.insert({"min_relative_shift", "k_sd"}); break;
      case RuleKind::orbit_zone: allowed.insert("clearance_m"); break;
      case RuleKind::stale_data: allowed.insert("limit_s"); break;
      case RuleKind::poor_data: allowed.insert("nrmse_limit"); break;
      case RuleKind::detection: break;
    }
    for (const auto& [key, v] : j_.items())
      if (!allowed.contains(key)) fail(key, "unknown key for rule '" + r.id + "'");
    if (has("enabled")) {
      if (!j_["enabled"].is_boolean()) fail("enabled", "must be true or false");
      r.enabled = j_["enabled"].get<bool>();
    }
    if (has("direction")) {
      const json& d = j_["direction"];
      if (!d.is_string() || (d != "above" && d != "below")) fail("direction", "must be \"above\" or \"below\"");
      r.below = d == "below";
    }
    if (!has("levels") || !j_["levels"].is_array() || j_["levels"].empty())
      fail("levels", "must be a non-empty array of {\"severity\", \"raise\"}");
    for (size_t i = 0; i < j_["levels"].size(); ++i) {
      const json& l = j_["levels"][i];
      const std::string at = "levels[" + std::to_string(i) + "]";
      if (!l.is_object()) fail(at, "must be an object {\"severity\", \"raise\"}");
      for (const auto& [key, v] : l.items())
        if (key != "severity" && key != "raise") fail(at + "." + key, "unknown key");
      AlarmLevel level;
      level.severity = severity(l.value("severity", json()), at + ".severity");
      if (!l.contains("raise") || !l["raise"].is_number() || !std::isfinite(l["raise"].get<double>()))
        fail(at + ".raise", "must be a finite number");
      level.raise = l["raise"].get<double>();
      if (!r.levels.empty()) {
        const AlarmLevel& prev = r.levels.back();
        if (level.severity <= prev.severity) fail(at + ".severity", "must be more severe than levels[" + std::to_string(i - 1) + "]'s");
        if (r.below ? level.raise >= prev.raise : level.raise <= prev.raise)
          fail(at + ".raise", std::string("must be ") + (r.below ? "below" : "above") + " levels[" + std::to_string(i - 1) + "].raise");
      }
      r.levels.push_back(level);
    }
    if (!has("clear") || !j_["clear"].is_number() || !std::isfinite(j_["clear"].get<double>()))
      fail("clear", "must be a finite number");
    r.clear = j_["clear"].get<double>();
    if (r.below ? r.clear < r.levels.front().raise : r.clear > r.levels.front().raise)
      fail("clear", std::string("must be ") + (r.below ? ">= " : "<= ") + "levels[0].raise (" + fmt(r.levels.front().raise) +
                        "): the clear limit is on the healthy side of the raise limit");
    if (has("on_delay")) {
      const json& d = j_["on_delay"];
      if (!d.is_object() || !d.contains("k") || !d.contains("n")) fail("on_delay", "must be {\"k\", \"n\"}");
      r.on_n = integer(d["n"], "on_delay.n", 1, 100);
      r.on_k = integer(d["k"], "on_delay.k", 1, 100);
      if (r.on_k > r.on_n) fail("on_delay.k", "must be <= n (" + std::to_string(r.on_n) + ")");
    }
    if (has("off_delay")) r.off_delay = integer(j_["off_delay"], "off_delay", 1, 100);
    if (has("latch")) r.latch = severity(j_["latch"], "latch");
    if (r.kind == RuleKind::fault) {
      if (!has("parameter") || !j_["parameter"].is_string() || j_["parameter"].get<std::string>().empty())
        fail("parameter", "must name the fault parameter compared (e.g. \"clearance_factor\")");
      r.parameter = j_["parameter"].get<std::string>();
      if (has("nominal")) r.nominal = number("nominal", 0.0, -1e12, 1e12);
    }
    r.min_relative_shift = number("min_relative_shift", r.min_relative_shift, 1e-6, 10.0);
    r.k_sd = number("k_sd", r.k_sd, 0.0, 1000.0);
    if (has("clearance_m")) r.clearance_m = number("clearance_m", 0.0, 1e-7, 1.0);
    if (r.kind == RuleKind::orbit_zone && r.clearance_m && *r.clearance_m <= 0) fail("clearance_m", "must be > 0");
    r.limit_s = number("limit_s", r.limit_s, 1.0, 3.2e7);
    r.nrmse_limit = number("nrmse_limit", r.nrmse_limit, 1e-6, 100.0);
    return r;
  }

 private:
  const json& j_;
  std::string at_;
};

void read_plant_state(const json& j, AlarmRuleSet& s) {
  if (!j.contains("plant_state") || j["plant_state"].is_null()) return;
  const json& p = j["plant_state"];
  if (!p.is_object()) throw InputError("plant_state: must be an object {\"speed_band\", \"stopped_below_rpm\"}");
  for (const auto& [key, v] : p.items()) {
    if (key != "speed_band" && key != "stopped_below_rpm") throw InputError("plant_state." + key + ": unknown key");
    if (!v.is_number() || !std::isfinite(v.get<double>())) throw InputError("plant_state." + key + ": must be a number");
  }
  s.speed_band = p.value("speed_band", s.speed_band);
  if (!(s.speed_band > 0 && s.speed_band <= 1)) throw InputError("plant_state.speed_band: must be in (0, 1] (a share of the model's speed)");
  s.stopped_below_rpm = p.value("stopped_below_rpm", s.stopped_below_rpm);
  if (!(s.stopped_below_rpm >= 0 && s.stopped_below_rpm < 1e6)) throw InputError("plant_state.stopped_below_rpm: must be >= 0");
}

void check_top_level(const json& j) {
  if (!j.is_object()) throw InputError("alarm rules: the body must be an object {\"rules\": [...], \"plant_state\"?: {...}}");
  // A GET's reply may be PUT back as it is: its informative keys are ignored.
  static const std::set<std::string> allowed = {"rules", "plant_state", "pump_id", "version", "created_at", "created_by", "source"};
  for (const auto& [key, v] : j.items())
    if (!allowed.contains(key)) throw InputError(key + ": unknown key (rules, plant_state)");
  if (j.contains("rules") && !j["rules"].is_array()) throw InputError("rules: must be an array of rules");
}

json level(Severity s, double raise) { return {{"severity", to_string(s)}, {"raise", raise}}; }

json rule_json(const std::string& id, json levels, double clear, int k, int n, int off, std::optional<Severity> latch) {
  return {{"id", id}, {"enabled", true}, {"levels", std::move(levels)}, {"clear", clear}, {"on_delay", {{"k", k}, {"n", n}}},
          {"off_delay", off}, {"latch", latch ? json(to_string(*latch)) : json(nullptr)}};
}

json fault_rule(const std::string& name, const std::string& parameter, const char* direction, json levels, double clear,
                std::optional<Severity> latch, std::optional<double> nominal = std::nullopt) {
  json r = rule_json("fault." + name, std::move(levels), clear, 1, 1, 2, latch);
  r["parameter"] = parameter;
  r["direction"] = direction;
  if (nominal) r["nominal"] = *nominal;
  return r;
}

}  // namespace

std::string to_string(Severity s) {
  switch (s) {
    case Severity::low: return "low";
    case Severity::medium: return "medium";
    case Severity::high: return "high";
    case Severity::critical: return "critical";
  }
  return "low";
}

std::optional<Severity> severity_from(const std::string& s) {
  for (auto v : kSeverities)
    if (to_string(v) == s) return v;
  return std::nullopt;
}

json AlarmRule::to_json() const {
  json lv = json::array();
  for (const auto& l : levels) lv.push_back(level(l.severity, l.raise));
  json j = rule_json(id, lv, clear, on_k, on_n, off_delay, latch);
  j["enabled"] = enabled;
  switch (kind) {
    case RuleKind::fault:
      j["parameter"] = parameter;
      j["direction"] = below ? "below" : "above";
      if (nominal) j["nominal"] = *nominal;
      break;
    case RuleKind::mode_f:
    case RuleKind::mode_zeta:
      j["min_relative_shift"] = min_relative_shift;
      j["k_sd"] = k_sd;
      break;
    case RuleKind::orbit_zone: j["clearance_m"] = clearance_m ? json(*clearance_m) : json(nullptr); break;
    case RuleKind::stale_data: j["limit_s"] = limit_s; break;
    case RuleKind::poor_data: j["nrmse_limit"] = nrmse_limit; break;
    case RuleKind::detection: break;
  }
  return j;
}

const AlarmRule* AlarmRuleSet::find(const std::string& id) const {
  for (const auto& r : rules)
    if (r.id == id) return &r;
  if (id.starts_with("mode.")) {
    const std::string tmpl = id.ends_with(".f_hz") ? "mode.*.f_hz" : id.ends_with(".zeta") ? "mode.*.zeta" : "";
    for (const auto& r : rules)
      if (r.id == tmpl) return &r;
  }
  return nullptr;
}

json AlarmRuleSet::to_json() const {
  json rs = json::array();
  for (const auto& r : rules) rs.push_back(r.to_json());
  return {{"plant_state", {{"speed_band", speed_band}, {"stopped_below_rpm", stopped_below_rpm}}}, {"rules", rs}};
}

json default_rule_set_json() {
  using S = Severity;
  json rules = json::array();
  // Detection fired: its ratio statistic / threshold reaches 1, on three
  // runs in a row: the fleet false-alarm budget with the measured tail of
  // the detection test (docs/diagnosis.md section 8). The fault rules below
  // name a fault on the run itself.
  rules.push_back(rule_json("detection", json::array({level(S::medium, 1.0)}), 0.8, 3, 3, 3, std::nullopt));
  // Fault parameters, by the diagnosis' best-ranked fault. A fault alarm
  // comes on the first run detection fires on and the diagnosis names the
  // fault (its lowest level sits just past nominal: the fault is already
  // told apart from the normal drift there), and escalates as it grows:
  // clearance factors after the usual renewal practice for annular seals
  // (watch from 1.3 x the design clearance, plan at 1.6 x, renew at 2 x,
  // critical and latched).
  for (const char* seal : {"balance_piston_wear", "impeller_seal_wear"})
    rules.push_back(fault_rule(seal, "clearance_factor", "above",
                               json::array({level(S::low, 1.1), level(S::medium, 1.3), level(S::high, 1.6), level(S::critical, 2.0)}),
                               1.05, S::critical));
  // A seal running dry keeps a share of its fluid stiffness: under half is critical.
  rules.push_back(fault_rule("dry_run", "fluid_factor", "below",
                             json::array({level(S::medium, 0.9), level(S::high, 0.7), level(S::critical, 0.4)}), 0.95, S::critical));
  // A crack or a loose shaft nut: a bending stiffness loss of 10 % is high,
  // 25 % critical and latched (a crack grows).
  rules.push_back(fault_rule("rotor_crack", "EI_factor", "below",
                             json::array({level(S::medium, 0.97), level(S::high, 0.9), level(S::critical, 0.75)}), 0.98, S::high));
  rules.push_back(fault_rule("shaft_nut_loosening", "joint_factor", "below",
                             json::array({level(S::low, 0.97), level(S::medium, 0.9), level(S::high, 0.75)}), 0.98, S::high));
  // Sensor and actuator gains: |gain - 1|.
  for (const char* dev : {"sensor_fault", "actuator_fault"})
    rules.push_back(fault_rule(dev, "gain", "above", json::array({level(S::low, 0.03), level(S::medium, 0.1), level(S::high, 0.3)}),
                               0.02, std::nullopt, 1.0));
  // Labelled modes against the reference runs' scatter. Not calibrated on
  // healthy fleets the way detection is (an sd from three reference runs
  // is rough, and seal coefficients move modes with speed): wide limits and
  // three runs in a row, so that they speak only of a lasting shift.
  json mode_f = rule_json("mode.*.f_hz", json::array({level(S::low, 1.0)}), 0.7, 3, 3, 3, std::nullopt);
  mode_f["min_relative_shift"] = 0.05;
  mode_f["k_sd"] = 6.0;
  rules.push_back(mode_f);
  json mode_zeta = rule_json("mode.*.zeta", json::array({level(S::low, 1.0)}), 0.7, 3, 3, 3, std::nullopt);
  mode_zeta["min_relative_shift"] = 1.0;
  mode_zeta["k_sd"] = 6.0;
  rules.push_back(mode_zeta);
  // ISO 14839-2 zones of the displacement over the minimum (touchdown)
  // clearance: A/B 0.3, B/C 0.4, C/D 0.5. Zone C is an alarm, D a trip.
  json orbit = rule_json("orbit_zone", json::array({level(S::high, 0.4), level(S::critical, 0.5)}), 0.35, 1, 1, 2, S::critical);
  orbit["clearance_m"] = nullptr;
  rules.push_back(orbit);
  json stale = rule_json("stale_data", json::array({level(S::low, 1.0)}), 0.5, 1, 1, 1, std::nullopt);
  stale["limit_s"] = 86400.0;
  rules.push_back(stale);
  json poor = rule_json("poor_data", json::array({level(S::low, 1.0)}), 0.8, 2, 3, 2, std::nullopt);
  poor["nrmse_limit"] = 0.3;
  rules.push_back(poor);
  return {{"plant_state", {{"speed_band", 0.05}, {"stopped_below_rpm", 60.0}}}, {"rules", rules}};
}

AlarmRuleSet rule_set_from_json(const json& j, const std::string& what) {
  check_top_level(j);
  AlarmRuleSet s;
  read_plant_state(j, s);
  std::set<std::string> ids;
  const json rules = j.value("rules", json::array());
  for (size_t i = 0; i < rules.size(); ++i) {
    const std::string at = (what.empty() ? "" : what + ": ") + "rules[" + std::to_string(i) + "]";
    AlarmRule r = RuleReader(rules[i], at).read();
    if (!ids.insert(r.id).second) throw InputError(at + ".id: '" + r.id + "' given twice");
    s.rules.push_back(std::move(r));
  }
  return s;
}

json merged_rule_set_json(const json& base, const json& overrides, const std::string& what) {
  check_top_level(overrides);
  AlarmRuleSet checked;
  read_plant_state(overrides, checked);  // names a bad plant_state key of the given set
  json out = base;
  if (overrides.contains("plant_state") && overrides["plant_state"].is_object())
    for (const auto& [key, v] : overrides["plant_state"].items()) out["plant_state"][key] = v;
  json& rules = out["rules"];
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < rules.size(); ++i) index[rules[i].value("id", "")] = i;
  std::set<std::string> given;
  const json list = overrides.value("rules", json::array());
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string at = (what.empty() ? "" : what + ": ") + "rules[" + std::to_string(i) + "]";
    const json& r = list[i];
    if (!r.is_object()) throw InputError(at + ": must be an object");
    if (!r.contains("id") || !r["id"].is_string()) throw InputError(at + ".id: must be a string");
    const std::string id = r["id"].get<std::string>();
    if (!given.insert(id).second) throw InputError(at + ".id: '" + id + "' given twice");
    json merged = r;
    if (const auto it = index.find(id); it != index.end()) {
      merged = rules[it->second];
      for (const auto& [key, v] : r.items()) merged[key] = v;
    }
    RuleReader(merged, at).read();  // names the field of the given rule
    if (const auto it = index.find(id); it != index.end())
      rules[it->second] = merged;
    else
      rules.push_back(merged);
  }
  rule_set_from_json(out, what);  // the whole, with the plant state
  return out;
}

AlarmRuleSet merge_rule_sets(const json& base, const json& overrides, const std::string& what) {
  return rule_set_from_json(merged_rule_set_json(base, overrides, what), what);
}

}  // namespace ambdiag::server::detail
