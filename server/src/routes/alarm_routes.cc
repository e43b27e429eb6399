// Alarms (rest.md "Alarms"; docs/service.md "Alarms"): the list, one alarm
// and its history, the fleet's journal by cursor, the KPIs, what operators
// and engineers do to alarms, and each pump's rules.
#include <algorithm>

#include "alarms/alarm_evaluator.h"
#include "alarms/alarm_kpis.h"
#include "alarms/alarm_rules.h"
#include "alarms/alarm_service.h"
#include "alarms/alarm_state.h"
#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/storage/monitoring.h"
#include "routes/api_schemas.h"
#include "routes/route_context.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

std::int64_t alarm_id_of(const PathParams& p) { return positive_integer(p.at("alarm_id"), "alarm_id"); }

int limit_param(const RouteContext& c, int def, int max) {
  if (!c.req.has_param("limit")) return def;
  return static_cast<int>(std::min<std::int64_t>(positive_integer(c.req.get_param_value("limit"), "limit"), max));
}

// An optional JSON object body ({} when empty); InputError otherwise.
json object_body(const RouteContext& c, const std::string& what) {
  if (c.req.body.find_first_not_of(" \t\r\n") == std::string::npos) return json::object();
  const json body = parse_body(c.req, what);
  if (!body.is_object()) throw InputError(what + ": the body must be a JSON object");
  return body;
}

std::string comment_of(const json& body, const std::string& what) {
  if (!body.contains("comment") || body["comment"].is_null()) return "";
  if (!body["comment"].is_string()) throw InputError(what + ": comment: must be a string");
  const std::string comment = body["comment"].get<std::string>();
  if (comment.size() > 4096) throw InputError(what + ": comment: longer than 4096 bytes");
  return comment;
}

// The defaults the rules' GET shows: the running service's, else the built-in ones.
void get_alarms(RouteContext& c) {
  storage::AlarmFilter f;
  if (c.req.has_param("pump_id")) f.pump_id = c.req.get_param_value("pump_id");
  if (c.req.has_param("state")) {
    const std::string s = c.req.get_param_value("state");
    if (std::find(alarm_states().begin(), alarm_states().end(), s) == alarm_states().end())
      throw InputError("state: '" + s + "' is not normal, unack_active, ack_active, unack_rtn, shelved, suppressed or out_of_service");
    f.state = s;
  }
  if (c.req.has_param("active")) {
    const std::string a = c.req.get_param_value("active");
    if (a != "true" && a != "false") throw InputError("active: '" + a + "' is not true or false");
    f.active = a == "true";
  }
  f.limit = limit_param(c, 1000, 10000);
  auto h = c.pool.acquire();
  json list = json::array();
  for (const auto& a : h->list_alarms(f)) list.push_back(alarm_json(a));
  send_json(c.res, 200, {{"alarms", list}});
}

void get_alarm(RouteContext& c, const PathParams& p) {
  const auto id = alarm_id_of(p);
  auto h = c.pool.acquire();
  const auto a = h->find_alarm(id);
  if (!a) return send_error(c.res, 404, "no alarm " + std::to_string(id));
  send_json(c.res, 200, alarm_json(*a));
}

void get_history(RouteContext& c, const PathParams& p) {
  const auto id = alarm_id_of(p);
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!h->find_alarm(id)) return send_error(c.res, 404, "no alarm " + std::to_string(id));
  json events = json::array();
  for (const auto& e : h->alarm_history(id)) events.push_back(alarm_event_json(e, false));
  send_json(c.res, 200, {{"alarm_id", id}, {"events", events}});
}

void get_events(RouteContext& c) {
  std::int64_t after = 0;
  if (c.req.has_param("after_seq")) {
    const std::string t = c.req.get_param_value("after_seq");
    after = t == "0" ? 0 : positive_integer(t, "after_seq");
  }
  const int limit = limit_param(c, 1000, 10000);
  auto h = c.pool.acquire();
  json events = json::array();
  std::int64_t next = after;
  for (const auto& e : h->alarm_events(after, limit)) {
    events.push_back(alarm_event_json(e, true));
    next = e.seq;
  }
  // next_seq: pass it as after_seq to go on; equal to after_seq when nothing is new.
  send_json(c.res, 200, {{"events", events}, {"next_seq", next}});
}

void get_kpis(RouteContext& c) {
  const std::int64_t now = now_ns();
  const std::int64_t to = c.req.has_param("to") ? storage::ns_from_utc(c.req.get_param_value("to"), "to") : now;
  const std::int64_t from =
      c.req.has_param("from") ? storage::ns_from_utc(c.req.get_param_value("from"), "from") : to - 24 * 3600'000'000'000LL;
  if (to <= from) throw InputError("to: must be after from");
  if (to - from > 400LL * 86400'000'000'000LL) throw InputError("from: the range is longer than 400 days");
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  storage::AlarmFilter f;
  f.active = true;
  f.limit = 100000;
  send_json(c.res, 200, alarm_kpis(h->alarm_events_between(iso_ms(from), iso_ms(to)), h->list_alarms(f), from, to));
}

void post_ack(RouteContext& c, const PathParams& p) {
  const json body = object_body(c, "ack");
  send_json(c.res, 200, c.opt.analysis->acknowledge_alarm(alarm_id_of(p), c.caller.name, comment_of(body, "ack")));
}

void post_shelve(RouteContext& c, const PathParams& p) {
  const json body = object_body(c, "shelve");
  if (!body.contains("minutes") || !body["minutes"].is_number_integer())
    throw InputError("shelve: minutes: required, an integer in 1..43200");
  send_json(c.res, 200, c.opt.analysis->shelve_alarm(alarm_id_of(p), body["minutes"].get<std::int64_t>(), c.caller.name,
                                                     comment_of(body, "shelve")));
}

void post_unshelve(RouteContext& c, const PathParams& p) {
  const json body = object_body(c, "unshelve");
  send_json(c.res, 200, c.opt.analysis->unshelve_alarm(alarm_id_of(p), c.caller.name, comment_of(body, "unshelve")));
}

void post_reset(RouteContext& c, const PathParams& p) {
  const json body = object_body(c, "reset");
  send_json(c.res, 200, c.opt.analysis->reset_alarm(alarm_id_of(p), c.caller.name, comment_of(body, "reset")));
}

void get_rules(RouteContext& c, const PathParams& p) {
  const std::string& pump_id = p.at("pump_id");
  auto h = c.pool.acquire();
  if (!h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  send_json(c.res, 200, alarm_rules_view(*h, pump_id, alarm_defaults_of(c)));
}

void put_rules(RouteContext& c, const PathParams& p) {
  const std::string& pump_id = p.at("pump_id");
  const json body = parse_body(c.req, "alarm rules");
  {
    auto h = c.pool.acquire();
    if (!h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  }
  send_json(c.res, 200, c.opt.analysis->put_alarm_rules(pump_id, body, c.caller.name));
}

}  // namespace

json alarm_defaults_of(const RouteContext& c) {
  return c.opt.analysis ? c.opt.analysis->alarm_defaults()
                        : merged_rule_set_json(default_rule_set_json(), json::object(), "alarm defaults");
}

void add_alarm_routes(RouteTable& t) {
  using storage::Role;
  using namespace schema;
  add_alarm_schemas(t);
  const auto plain = [](void (*f)(RouteContext&)) { return [f](RouteContext& c, const PathParams&) { f(c); }; };
  const json comment = object({}, {{"comment", string()}});
  t.add({"GET", "/api/v1/alarms", Role::viewer, "alarms, newest first", plain(get_alarms),
         {{"pump_id", "only this pump's"},
          {"state", "normal, unack_active, ack_active, unack_rtn, shelved, suppressed or out_of_service"},
          {"active", "true or false"},
          {"limit", "at most this many (1..10000, default 1000)"}}})
      .response_schema = object({{"alarms", array(ref("Alarm"))}});
  t.add({"GET", "/api/v1/alarms/{alarm_id}", Role::viewer, "one alarm", get_alarm}).response_schema = ref("Alarm");
  t.add({"GET", "/api/v1/alarms/{alarm_id}/history", Role::viewer, "every transition of an alarm, oldest first, with who made it",
         get_history})
      .response_schema = object({{"events", array(ref("AlarmTransition"))}}, {{"alarm_id", integer()}});
  // Each answers the alarm after the transition.
  const auto transition = [&](Route r, json body) {
    Route& added = t.add(std::move(r));
    added.body_schema = std::move(body);
    added.response_schema = ref("Alarm");
  };
  transition({"POST", "/api/v1/alarms/{alarm_id}/ack", Role::operator_, "acknowledge an alarm (body {\"comment\"?}); 409 where its state allows none",
              post_ack},
             comment);
  transition({"POST", "/api/v1/alarms/{alarm_id}/shelve", Role::operator_, "shelve an alarm (body {\"minutes\", \"comment\"})", post_shelve},
             object({{"minutes", integer()}, {"comment", string()}}));
  transition({"POST", "/api/v1/alarms/{alarm_id}/unshelve", Role::operator_, "unshelve an alarm (body {\"comment\"?})", post_unshelve},
             comment);
  transition({"POST", "/api/v1/alarms/{alarm_id}/reset", Role::engineer, "reset a latched alarm (body {\"comment\"}, required)", post_reset},
             object({{"comment", string()}}));
  t.add({"GET", "/api/v1/alarm-events", Role::viewer, "the fleet's alarm journal after a sequence number: the cursor plant systems poll",
         plain(get_events), {{"after_seq", "entries after this seq (default 0)"}, {"limit", "at most this many (1..10000, default 1000)"}}})
      .response_schema = object({{"events", array(ref("AlarmJournalEvent"))}, {"next_seq", integer()}});
  t.add({"GET", "/api/v1/alarm-kpis", Role::viewer, "alarm-system KPIs after EEMUA 191 / ISA-18.2 over a time range", plain(get_kpis),
         {{"from", "ISO 8601 UTC (default: to - 24 h)"}, {"to", "ISO 8601 UTC (default: now)"}}})
      .response_schema = ref("AlarmKpis");
  t.add({"GET", "/api/v1/pumps/{pump_id}/alarm-rules", Role::viewer, "the pump's effective alarm rules", get_rules})
      .response_schema = ref("AlarmRules");
  auto& rules = t.add({"PUT", "/api/v1/pumps/{pump_id}/alarm-rules", Role::engineer,
                       "a new version of the pump's alarm rules (body {\"rules\": [...], \"plant_state\"?}, each rule over the default of its id)",
                       put_rules});
  rules.body_schema = object({}, {{"rules", array(object({{"id", string()}}))}, {"plant_state", object({})}});
  rules.response_schema = ref("AlarmRules");
}

}  // namespace ambdiag::server::detail
