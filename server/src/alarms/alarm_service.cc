#include "alarms/alarm_service.h"

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;
using storage::Historian;

}  // namespace

json alarm_rules_view(Historian& h, const std::string& pump_id, const json& defaults) {
  const auto v = h.find_alarm_rules(pump_id);
  json j = pump_rule_set(h, pump_id, defaults).to_json();
  j["pump_id"] = pump_id;
  j["version"] = v ? v->version : 0;
  j["source"] = v ? "pump" : "defaults";
  if (v) {
    j["created_at"] = v->created_at;
    j["created_by"] = v->created_by;
  }
  return j;
}

AlarmService::AlarmService(const std::string& db_path, const json& defaults, AlarmEventSink sink, int tick_ms, int stale_check_s)
    : defaults_(defaults),
      tick_ms_(std::max(10, tick_ms)),
      stale_check_s_(std::max(1, stale_check_s)),
      h_(Historian::open(db_path, Historian::Mode::write)),
      ev_(defaults, std::move(sink)) {}

AlarmService::~AlarmService() { stop(); }

void AlarmService::start() {
  if (timer_.joinable()) return;
  {
    std::lock_guard l(mu_);
    int n = 0;
    for (const auto& p : h_.list_pumps()) n += ev_.catch_up(h_, p.pump_id);
    if (n > 0) std::fprintf(stderr, "ambdiag serve: %d runs evaluated for alarms that a previous server had not\n", n);
  }
  timer_ = std::thread([this] { timer_loop(); });
}

void AlarmService::stop() {
  {
    std::lock_guard l(stop_mu_);
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (timer_.joinable()) timer_.join();
}

void AlarmService::timer_loop() {
  auto next_stale = std::chrono::steady_clock::now();
  for (;;) {
    {
      std::unique_lock l(stop_mu_);
      if (stop_cv_.wait_for(l, std::chrono::milliseconds(tick_ms_), [&] { return stopping_; })) return;
    }
    const auto now = std::chrono::steady_clock::now();
    const bool stale = now >= next_stale;
    if (stale) next_stale = now + std::chrono::seconds(stale_check_s_);
    try {
      std::lock_guard l(mu_);
      ev_.tick(h_, now_ns(), stale);
    } catch (const std::exception& e) {  // busy past the timeout: the next tick tries again
      std::fprintf(stderr, "ambdiag serve: alarm timer: %s\n", e.what());
    }
  }
}

json AlarmService::put_rules(const std::string& pump_id, const json& body, const std::string& by) {
  if (pump_id.empty() || pump_id.size() > 128) throw InputError("pump_id: must be 1..128 bytes");
  merge_rule_sets(defaults_, body, "");  // InputError naming the field; nothing stored
  json stored = body;
  for (const char* informative : {"pump_id", "version", "created_at", "created_by", "source"}) stored.erase(informative);
  std::lock_guard l(mu_);
  h_.put_alarm_rules(pump_id, stored.dump(), by);
  return alarm_rules_view(h_, pump_id, defaults_);
}

template <class F>
json AlarmService::act(std::int64_t alarm_id, F&& action) {
  std::lock_guard l(mu_);
  auto batch = h_.write_batch();
  auto a = h_.find_alarm(alarm_id);
  if (!a) throw NotFoundError("no alarm " + std::to_string(alarm_id));
  // Read again under the pump's lock: an evaluation or another server's
  // action may be changing it now (the pump of an alarm never changes).
  h_.lock_pump_alarms(a->pump_id);
  a = h_.find_alarm(alarm_id);
  AlarmActor actor;
  actor.time = iso_ms(now_ns());
  storage::AlarmChanges c;
  c.pump_id = a->pump_id;
  c.events.emplace_back(0, action(*a, actor));
  c.alarms.push_back(*a);
  ev_.commit(batch, h_, c);
  return alarm_json(c.alarms.front());
}

json AlarmService::acknowledge(std::int64_t alarm_id, const std::string& by, const std::string& comment) {
  return act(alarm_id, [&](storage::AlarmRecord& a, AlarmActor& actor) {
    actor.by = by;
    actor.comment = comment;
    return acknowledge_alarm(a, actor);
  });
}

json AlarmService::shelve(std::int64_t alarm_id, std::int64_t minutes, const std::string& by, const std::string& comment) {
  return act(alarm_id, [&](storage::AlarmRecord& a, AlarmActor& actor) {
    actor.by = by;
    actor.comment = comment;
    return shelve_alarm(a, minutes, actor);
  });
}

json AlarmService::unshelve(std::int64_t alarm_id, const std::string& by, const std::string& comment) {
  return act(alarm_id, [&](storage::AlarmRecord& a, AlarmActor& actor) {
    actor.by = by;
    actor.comment = comment;
    return unshelve_alarm(a, actor);
  });
}

json AlarmService::reset(std::int64_t alarm_id, const std::string& by, const std::string& comment) {
  return act(alarm_id, [&](storage::AlarmRecord& a, AlarmActor& actor) {
    actor.by = by;
    actor.comment = comment;
    // Returns at once when the condition has been clear for its off-delay.
    const AlarmRuleSet rules = pump_rule_set(h_, a.pump_id, defaults_);
    const AlarmRule* rule = rules.find(a.rule);
    bool clear = false;
    for (const auto& [id, text] : h_.alarm_memories(a.pump_id))
      if (id == a.rule) clear = rule && ConditionMemory::from_text(text).clear_runs >= rule->off_delay;
    return reset_alarm(a, clear, actor);
  });
}

}  // namespace ambdiag::server::detail
