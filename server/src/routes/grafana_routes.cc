// A Grafana data source (docs/service.md "Grafana"): the JSON API that
// Grafana's "JSON" data source (simpod-json-datasource) and the older
// "SimpleJSON" read, under /api/v1/grafana. Metrics are "PUMP:SERIES";
// queries are answered from the same trend storage as GET .../trends, with
// maxDataPoints kept by the same min/max buckets. The POSTs only read.
#include <map>
#include <set>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/storage/historian.h"
#include "alarms/alarm_state.h"
#include "routes/json_schema.h"
#include "routes/route_context.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

constexpr std::int64_t kMaxDataPoints = 100000;
constexpr std::size_t kMaxTargets = 50;
constexpr std::int64_t kMaxAnnotations = 10000;

std::int64_t ms_of(std::int64_t ns) { return ns / 1'000'000; }

// Every "PUMP:SERIES" the historian holds, by pump then series.
json metric_list(storage::Historian& h, bool labelled) {
  json out = json::array();
  for (const auto& p : h.list_pumps())
    for (const auto& s : h.list_series(p.pump_id)) {
      const std::string value = p.pump_id + ":" + s.name;
      if (labelled)
        out.push_back({{"label", p.pump_id + " " + s.name + " [" + s.unit + "]"}, {"value", value}});
      else
        out.push_back(value);
    }
  return out;
}

// range.from / range.to of a Grafana body (ISO 8601 UTC); absent: all.
storage::TrendQuery range_of(const json& body) {
  storage::TrendQuery q;
  if (!body.contains("range")) return q;
  const json& r = body["range"];
  if (!r.is_object()) throw InputError("range: not an object");
  for (const char* key : {"from", "to"}) {
    if (!r.contains(key)) continue;
    if (!r[key].is_string()) throw InputError(std::string("range.") + key + ": not a time string");
    (std::string(key) == "from" ? q.from_ns : q.to_ns) = storage::ns_from_utc(r[key].get<std::string>(), std::string("range.") + key);
  }
  if (q.from_ns > q.to_ns) throw InputError("range.from: after range.to");
  return q;
}

// "PUMP:SERIES" split at the first ':' (series names hold none before
// their label), or payload {"pump_id", "series"} for a pump id with a ':'.
std::pair<std::string, std::string> target_of(const json& t, size_t i) {
  const std::string where = "targets[" + std::to_string(i) + "]";
  if (t.contains("payload") && t["payload"].is_object() && t["payload"].contains("pump_id")) {
    const json& p = t["payload"];
    if (!p["pump_id"].is_string() || !p.contains("series") || !p["series"].is_string())
      throw InputError(where + ".payload: needs the strings pump_id and series");
    return {p["pump_id"].get<std::string>(), p["series"].get<std::string>()};
  }
  if (!t.contains("target") || !t["target"].is_string()) throw InputError(where + ".target: missing or not a string");
  const std::string s = t["target"].get<std::string>();
  const size_t colon = s.find(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == s.size())
    throw InputError(where + ".target: '" + s + "' is not PUMP:SERIES");
  return {s.substr(0, colon), s.substr(colon + 1)};
}

void query(RouteContext& c) {
  const json body = parse_body(c.req, "grafana query");
  if (!body.is_object()) throw InputError("grafana query: the body is not an object");
  storage::TrendQuery q = range_of(body);
  std::int64_t max_points = 1000;
  if (body.contains("maxDataPoints")) {
    const json& m = body["maxDataPoints"];
    if (!m.is_number_integer() || m.get<std::int64_t>() < 1 || m.get<std::int64_t>() > kMaxDataPoints)
      throw InputError("maxDataPoints: not an integer in 1.." + std::to_string(kMaxDataPoints));
    max_points = m.get<std::int64_t>();
  }
  if (!body.contains("targets") || !body["targets"].is_array()) throw InputError("targets: missing or not an array");
  if (body["targets"].size() > kMaxTargets) throw InputError("targets: at most " + std::to_string(kMaxTargets));
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  json out = json::array();
  for (size_t i = 0; i < body["targets"].size(); ++i) {
    const json& t = body["targets"][i];
    if (!t.is_object()) throw InputError("targets[" + std::to_string(i) + "]: not an object");
    if (t.value("hide", false)) continue;
    const auto [pump_id, series] = target_of(t, i);
    q.max_points = max_points;
    auto trend = h->query_trend(pump_id, series, q);
    // Past maxDataPoints each bucket gives two datapoints (its min and its
    // max, at its start): half as many buckets keep within the budget.
    if (trend && !trend->buckets.empty() && max_points > 1) {
      q.max_points = max_points / 2;
      trend = h->query_trend(pump_id, series, q);
    }
    if (!trend) throw NotFoundError("targets[" + std::to_string(i) + "]: no series '" + series + "' of pump '" + pump_id + "'");
    json points = json::array();
    for (const auto& p : trend->points) points.push_back({p.value, ms_of(p.time_ns)});
    for (const auto& b : trend->buckets) {
      points.push_back({b.min, ms_of(b.time_ns)});
      if (max_points > 1) points.push_back({b.max, ms_of(b.time_ns)});
    }
    json r = {{"target", pump_id + ":" + series}, {"datapoints", points}};
    if (t.contains("refId")) r["refId"] = t["refId"];
    out.push_back(std::move(r));
  }
  send_json(c.res, 200, out);
}

// The alarm journal as annotations (rest.md: "alarms as annotations"): every
// transition in the range (raised, acknowledged with its comment, returned,
// shelved, ...) of the pump named in annotation.query, or of every pump;
// tagged with the pump, the rule, the kind of transition and the alarm's
// severity, so a dashboard can filter them. At most kMaxAnnotations, oldest
// first.
void annotations(RouteContext& c) {
  const json body = parse_body(c.req, "grafana annotations");
  if (!body.is_object()) throw InputError("grafana annotations: the body is not an object");
  const storage::TrendQuery q = range_of(body);
  std::string only;
  const json annotation = body.value("annotation", json::object());
  if (!annotation.is_object()) throw InputError("annotation: not an object");
  if (annotation.contains("query")) {
    if (!annotation["query"].is_string()) throw InputError("annotation.query: not a string (a pump id or empty)");
    only = annotation["query"].get<std::string>();
  }
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!only.empty() && !h->find_pump(only)) throw NotFoundError("annotation.query: no pump '" + only + "'");
  // The journal's times are ISO 8601 with milliseconds: the range as well,
  // so they compare as text; `to` is inclusive, the query's end exclusive.
  const std::string from = iso_ms(std::max<std::int64_t>(q.from_ns, 0));
  const std::string to = iso_ms(q.to_ns == std::numeric_limits<std::int64_t>::max() ? q.to_ns : q.to_ns + 1'000'000);
  std::map<std::int64_t, std::string> severity;  // by alarm id
  json out = json::array();
  for (const auto& e : h->alarm_events_between(from, to)) {
    if (!only.empty() && e.pump_id != only) continue;
    if (out.size() >= static_cast<size_t>(kMaxAnnotations)) break;
    if (!severity.count(e.alarm_id)) {
      const auto a = h->find_alarm(e.alarm_id);
      severity[e.alarm_id] = a ? a->severity : "";
    }
    const std::int64_t ms = storage::ns_from_utc(e.time, "alarm event time") / 1'000'000;
    std::string text = e.kind + ": " + e.from + " -> " + e.to + " by " + e.by;
    if (!e.comment.empty()) text += " (" + e.comment + ")";
    if (!e.run_id.empty()) text += ", run " + e.run_id;
    out.push_back({{"annotation", annotation},
                   {"time", ms},
                   {"timeEnd", ms},
                   {"title", e.pump_id + ": " + e.rule},
                   {"text", text},
                   {"tags", {e.pump_id, e.rule, e.kind, severity[e.alarm_id]}}});
  }
  send_json(c.res, 200, out);
}

// A dashboard variable's values: the pumps (payload.target "pumps" or
// absent), or the series of one pump (payload.target "series:PUMP").
void variable(RouteContext& c) {
  const json body = parse_body(c.req, "grafana variable");
  if (!body.is_object()) throw InputError("grafana variable: the body is not an object");
  std::string target = "pumps";
  if (body.contains("payload") && body["payload"].is_object() && body["payload"].contains("target")) {
    if (!body["payload"]["target"].is_string()) throw InputError("payload.target: not a string");
    target = body["payload"]["target"].get<std::string>();
  }
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  json out = json::array();
  if (target == "pumps") {
    for (const auto& p : h->list_pumps()) out.push_back({{"__text", p.pump_id}, {"__value", p.pump_id}});
  } else if (target.starts_with("series:")) {
    const std::string pump_id = target.substr(7);
    if (!h->find_pump(pump_id)) throw NotFoundError("payload.target: no pump '" + pump_id + "'");
    for (const auto& s : h->list_series(pump_id)) out.push_back({{"__text", s.name}, {"__value", s.name}});
  } else {
    throw InputError("payload.target: '" + target + "' is neither 'pumps' nor 'series:PUMP'");
  }
  send_json(c.res, 200, out);
}

}  // namespace

void add_grafana_routes(RouteTable& t) {
  using storage::Role;
  using namespace schema;
  // The schemas are the Grafana plugins' protocol (simpod-json-datasource, SimpleJSON).
  const auto read_post = [&t](std::string pattern, std::string summary, RouteHandler h, json body, json answer) {
    Route r{"POST", std::move(pattern), Role::viewer, std::move(summary), std::move(h)};
    r.read_only = true;
    r.body_schema = std::move(body);
    r.response_schema = std::move(answer);
    t.add(std::move(r));
  };
  Route root{"GET", "/api/v1/grafana", Role::viewer, "Grafana data source: connection test (200; also with a trailing '/')",
             [](RouteContext& c, const PathParams&) { send_json(c.res, 200, {{"status", "ok"}, {"service", "ambdiag"}}); }};
  root.trailing_slash = true;
  root.response_schema = object({{"status", one_of({"ok"})}, {"service", string()}});
  t.add(std::move(root));
  const json range = object({}, {{"from", time()}, {"to", time()}});
  read_post("/api/v1/grafana/metrics", "Grafana JSON data source: every PUMP:SERIES as {label, value}",
            [](RouteContext& c, const PathParams&) {
              auto h = c.pool.acquire();
              auto snap = h->snapshot();
              send_json(c.res, 200, metric_list(*h, true));
            },
            object({}), array(object({{"label", string()}, {"value", string()}})));
  read_post("/api/v1/grafana/search", "Grafana SimpleJSON: every PUMP:SERIES as a string",
            [](RouteContext& c, const PathParams&) {
              auto h = c.pool.acquire();
              auto snap = h->snapshot();
              send_json(c.res, 200, metric_list(*h, false));
            },
            object({}), array(string()));
  read_post("/api/v1/grafana/metric-payload-options", "Grafana JSON data source: payload options (none)",
            [](RouteContext& c, const PathParams&) { send_json(c.res, 200, json::array()); }, object({}), array(any()));
  read_post("/api/v1/grafana/query", "Grafana: targets PUMP:SERIES over range as [value, epoch ms] datapoints, maxDataPoints by min/max buckets",
            [](RouteContext& c, const PathParams&) { query(c); },
            object({{"targets", array(object({}, {{"target", string()}, {"refId", any()}, {"hide", boolean()}, {"payload", object({})}}))}},
                   {{"range", range}, {"maxDataPoints", integer()}}),
            array(object({{"target", string()}, {"datapoints", array(array(number()))}}, {{"refId", any()}})));
  read_post("/api/v1/grafana/variable", "Grafana JSON data source: a variable's values (the pumps, or a pump's series)",
            [](RouteContext& c, const PathParams&) { variable(c); },
            object({}, {{"payload", object({}, {{"target", string()}})}}),
            array(object({{"__text", string()}, {"__value", string()}})));
  read_post("/api/v1/grafana/annotations", "Grafana: the alarm journal (every transition) as annotations",
            [](RouteContext& c, const PathParams&) { annotations(c); },
            object({}, {{"range", range}, {"annotation", object({}, {{"query", string()}})}}),
            array(object({{"annotation", object({})},
                          {"time", integer()},
                          {"timeEnd", integer()},
                          {"title", string()},
                          {"text", string()},
                          {"tags", array(string())}})));
}

}  // namespace ambdiag::server::detail
