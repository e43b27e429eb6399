#include "alarms/alarm_evaluator.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "ambdiag/core/error.h"
#include "ambdiag/server/events.h"
#include "ambdiag/storage/monitoring.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;
using storage::Historian;

json parse_or_null(const std::string& text) {
  try {
    return json::parse(text);
  } catch (const json::exception&) {
    return nullptr;
  }
}

std::optional<double> finite_number(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return std::nullopt;
  const double v = j[key].get<double>();
  return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

// The runs' agent times in ns; nullopt for a text that is not a time.
std::optional<std::int64_t> time_ns(const std::string& iso) {
  try {
    return storage::ns_from_utc(iso, "started_at");
  } catch (const InputError&) {
    return std::nullopt;
  }
}

}  // namespace

AlarmRuleSet pump_rule_set(Historian& h, const std::string& pump_id, const json& defaults) {
  const auto v = h.find_alarm_rules(pump_id);
  if (!v) return rule_set_from_json(defaults, "alarm defaults");
  // Stored rules were validated when PUT against the defaults of that
  // server; should today's defaults reject the merge, today's defaults hold.
  try {
    return merge_rule_sets(defaults, json::parse(v->rules_json), "alarm rules of pump " + pump_id);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ambdiag serve: alarm rules version %d of pump %s no longer apply (%s): the defaults are used\n",
                 v->version, pump_id.c_str(), e.what());
    return rule_set_from_json(defaults, "alarm defaults");
  }
}

PumpAlarms load_pump_alarms(Historian& h, const std::string& pump_id) {
  PumpAlarms p;
  for (auto& a : h.open_alarms(pump_id)) p.open[a.rule] = std::move(a);
  for (const auto& [rule, text] : h.alarm_memories(pump_id)) p.memory[rule] = ConditionMemory::from_text(text);
  return p;
}

const AlarmRuleSet& AlarmEvaluator::rules_of(Historian& h, const std::string& pump_id) {
  const auto v = h.find_alarm_rules(pump_id);
  const int version = v ? v->version : 0;
  auto it = rules_.find(pump_id);
  if (it == rules_.end() || it->second.first != version)
    it = rules_.insert_or_assign(pump_id, std::pair{version, pump_rule_set(h, pump_id, defaults_)}).first;
  return it->second.second;
}

std::map<std::string, SeriesReference> AlarmEvaluator::reference_of(Historian& h, const std::string& pump_id, int m, int r) {
  const auto key = std::tuple{pump_id, m, r};
  if (const auto it = references_.find(key); it != references_.end()) return it->second;
  std::map<std::string, std::vector<double>> values;
  bool all_done = true;
  if (const auto ref = r > 0 ? h.find_reference(pump_id, r) : std::nullopt)
    for (const auto& run_id : ref->run_ids) {
      const auto job = h.find_job(storage::JobKey{"analysis", pump_id, run_id, m, r});
      if (!job || job->status != storage::JobStatus::done || !job->result_json) {
        all_done = all_done && job && job->status != storage::JobStatus::queued && job->status != storage::JobStatus::running;
        continue;
      }
      for (const auto& s : run_series(parse_or_null(*job->result_json)))
        if (s.name.starts_with("mode.")) values[s.name].push_back(s.value);
    }
  std::map<std::string, SeriesReference> out;
  for (const auto& [name, v] : values) {
    SeriesReference sr;
    sr.n = static_cast<int>(v.size());
    for (double x : v) sr.mean += x / sr.n;
    for (double x : v) sr.sd += sr.n > 1 ? (x - sr.mean) * (x - sr.mean) / (sr.n - 1) : 0.0;
    sr.sd = std::sqrt(sr.sd);
    out[name] = sr;
  }
  // Kept only once every reference run's analysis has ended; until then
  // computed again for each run.
  if (all_done) references_[key] = out;
  return out;
}

RunFacts AlarmEvaluator::run_facts(Historian& h, const storage::RunInfo& run, const storage::Job& job, int m, int r,
                                   const std::optional<storage::AlarmCursor>& cursor) {
  RunFacts f;
  f.pump_id = run.pump_id;
  f.run_id = run.run_id;
  f.time = iso_ms(now_ns());
  f.speed_rpm = run.speed_rpm;
  auto plant = plants_.find({run.pump_id, m});
  if (plant == plants_.end()) {
    Plant p;
    if (const auto model = h.find_model(run.pump_id, m)) {
      const json doc = parse_or_null(model->plant_json);
      p.speed_rpm = finite_number(doc, "speed_rpm");
      // Not in plant-model.md: a model may carry its touchdown bearings'
      // radial clearance; the orbit_zone rule's clearance_m takes precedence.
      p.clearance_m = finite_number(doc, "touchdown_clearance_m");
    }
    plant = plants_.emplace(std::pair{run.pump_id, m}, p).first;
  }
  f.model_speed_rpm = plant->second.speed_rpm;
  f.clearance_m = plant->second.clearance_m;
  if (job.status == storage::JobStatus::done) {
    const json result = parse_or_null(job.result_json.value_or(""));
    f.values = run_series(result);
    if (const auto s = finite_number(result, "speed_rpm")) f.speed_rpm = *s;
    if (result.is_object() && result.contains("detection") && result["detection"].is_object()) {
      f.has_detection = true;
      f.detected = result["detection"].value("detected", false);
    }
    if (result.is_object() && result.contains("diagnosis") && result["diagnosis"].is_object()) {
      const json& faults = result["diagnosis"].value("faults", json::array());
      if (faults.is_array() && !faults.empty() && faults[0].contains("fault") && faults[0]["fault"].is_string())
        f.best_fault = faults[0]["fault"].get<std::string>();
    }
  } else {
    f.analysis_failed = true;
    f.error = job.error.value_or(storage::to_string(job.status));
  }
  if (r > 0) f.reference = reference_of(h, run.pump_id, m, r);
  // The orbit: the largest displacement from the bearing centre (centre
  // offset + major semi-axis) of the snapshots since the previous run.
  if (const auto until = time_ns(run.started_at)) {
    std::int64_t since = *until - 86'400'000'000'000LL;  // the first run: its last day
    if (cursor)
      if (const auto prev = time_ns(cursor->started_at); prev && *prev < *until) since = *prev + 1;
    for (const auto& s : h.list_monitoring(run.pump_id, since, 100000)) {
      if (s.time_ns > *until) break;
      for (size_t b = 0; b < 2; ++b) {
        const double d = std::hypot(s.orbit_center_x_m[b], s.orbit_center_y_m[b]) + s.orbit_major_m[b];
        f.displacement_m = std::max(f.displacement_m.value_or(0.0), d);
      }
    }
  }
  return f;
}

void AlarmEvaluator::commit(Historian::WriteBatch& batch, Historian& h, storage::AlarmChanges& changes) {
  if (!changes.empty()) h.apply_alarm_changes(changes);
  // Each journal entry is announced (GET /api/v1/events) in its transaction.
  for (const auto& [index, e] : changes.events)
    h.append_event("alarm.transition", e.pump_id, event_data(alarm_event_json(e, true)));
  batch.commit();
  if (sink_)
    for (const auto& [index, e] : changes.events) sink_(alarm_event_json(e, true));
}

int AlarmEvaluator::catch_up(Historian& h, const std::string& pump_id) {
  for (int evaluated = 0;; ++evaluated) {
    auto batch = h.write_batch();
    // Another server evaluating this pump now: after it, from its cursor.
    h.lock_pump_alarms(pump_id);
    const auto model = h.find_model(pump_id);
    if (!model) return evaluated;
    const auto ref = h.find_reference(pump_id);
    const int m = model->version, r = ref ? ref->version : 0;
    auto cursor = h.find_alarm_cursor(pump_id);
    std::optional<std::pair<std::string, std::string>> after;
    if (cursor) after = std::pair{cursor->started_at, cursor->run_id};
    // The first reference: the runs after its newest one again, with detection.
    if (cursor && cursor->reference_version == 0 && r > 0) {
      std::optional<std::pair<std::string, std::string>> newest;
      for (const auto& id : ref->run_ids)
        if (const auto run = h.find_run(id); run && (!newest || std::pair{run->started_at, run->run_id} > *newest))
          newest = std::pair{run->started_at, run->run_id};
      if (newest && *newest < *after) after = newest;
    }
    const auto run = h.next_run_for_alarms(pump_id, after);
    if (!run) {
      if (cursor && (cursor->model_version != m || cursor->reference_version != r)) {
        storage::AlarmChanges c;
        c.pump_id = pump_id;
        c.cursor = *cursor;
        c.cursor->model_version = m;
        c.cursor->reference_version = r;
        commit(batch, h, c);
      }
      return evaluated;
    }
    const auto job = h.find_job(storage::JobKey{"analysis", pump_id, run->run_id, m, r});
    if (!job || job->status == storage::JobStatus::queued || job->status == storage::JobStatus::running) return evaluated;
    const AlarmRuleSet& rules = rules_of(h, pump_id);
    storage::AlarmChanges changes;
    changes.pump_id = pump_id;
    const std::string now = iso_ms(now_ns());
    std::optional<std::string> last_valid = cursor ? cursor->last_valid_at : std::nullopt;
    if (job->status != storage::JobStatus::cancelled) {  // cancelled by an engineer: not evaluated
      PumpAlarms pump = load_pump_alarms(h, pump_id);
      changes = evaluate_run(rules, pump, run_facts(h, *run, *job, m, r, cursor));
      if (job->status == storage::JobStatus::done) last_valid = now;
    }
    changes.pump_id = pump_id;
    changes.cursor = storage::AlarmCursor{pump_id, run->started_at, run->run_id, m, r, last_valid};
    commit(batch, h, changes);
  }
}

void AlarmEvaluator::tick(Historian& h, std::int64_t now, bool check_stale) {
  const std::string time = iso_ms(now);
  // Each pump's expired shelves under its lock, read again there: another
  // server's tick may have ended them meanwhile. One pump per transaction:
  // never two pumps' locks at once.
  std::set<std::string> shelved_pumps;
  for (const auto& a : h.expired_shelves(time)) shelved_pumps.insert(a.pump_id);
  for (const auto& pump_id : shelved_pumps) {
    auto batch = h.write_batch();
    h.lock_pump_alarms(pump_id);
    storage::AlarmChanges c;
    for (auto& a : h.expired_shelves(time)) {
      if (a.pump_id != pump_id) continue;
      AlarmActor actor{"server", time, "", ""};
      auto e = expire_shelve(a, actor);
      c.events.emplace_back(c.alarms.size(), std::move(e));
      c.alarms.push_back(std::move(a));
    }
    commit(batch, h, c);
  }
  if (!check_stale) return;
  for (const auto& cur : h.list_alarm_cursors()) {
    const auto last = cur.last_valid_at ? time_ns(*cur.last_valid_at) : std::nullopt;
    if (!last) continue;
    const double age_s = 1e-9 * static_cast<double>(now - *last);
    const AlarmRuleSet& rules = rules_of(h, cur.pump_id);
    const AlarmRule* rule = rules.find("stale_data");
    if (!rule || !rule->enabled || age_s < rule->limit_s * rule->levels.front().raise) continue;  // the common case: no write
    auto batch = h.write_batch();
    h.lock_pump_alarms(cur.pump_id);  // another server's tick raised it meanwhile: no second raise
    PumpAlarms pump = load_pump_alarms(h, cur.pump_id);
    auto c = evaluate_stale(rules, pump, cur.pump_id, age_s, time);
    commit(batch, h, c);
  }
}

json alarm_json(const storage::AlarmRecord& a) {
  json j = {{"alarm_id", a.alarm_id},   {"pump_id", a.pump_id},     {"rule", a.rule},
            {"severity", a.severity},   {"state", a.state},         {"active", a.active},
            {"acknowledged", a.acknowledged}, {"latched", a.latched}, {"raised_at", a.raised_at},
            {"updated_at", a.updated_at}, {"run_id", a.run_id},     {"message", a.message}};
  if (a.cleared_at) j["cleared_at"] = *a.cleared_at;
  if (a.fault) j["fault"] = *a.fault;
  if (a.value) j["value"] = *a.value;
  if (a.shelved_until) j["shelved_until"] = *a.shelved_until;
  if (!a.suppressed_reason.empty()) j["suppressed_reason"] = a.suppressed_reason;
  if (a.out_of_service) j["out_of_service"] = true;
  return j;
}

json alarm_event_json(const storage::AlarmEvent& e, bool fleet) {
  json j = {{"seq", e.seq}, {"time", e.time}, {"from", e.from}, {"to", e.to}, {"by", e.by}, {"kind", e.kind}};
  if (fleet) {
    j["alarm_id"] = e.alarm_id;
    j["pump_id"] = e.pump_id;
    j["rule"] = e.rule;
  }
  if (!e.comment.empty()) j["comment"] = e.comment;
  if (!e.run_id.empty()) j["run_id"] = e.run_id;
  return j;
}

}  // namespace ambdiag::server::detail
