// Trends (rest.md "Trends"; docs/service.md): a pump's series, their points
// or min/max buckets over a range with the reference band, and the
// prognosis of a series towards a limit.
#include <cmath>
#include <cstdlib>
#include <set>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/storage/historian.h"
#include "routes/api_schemas.h"
#include "routes/route_context.h"
#include "trends/prognosis.h"
#include "trends/trend_json.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

constexpr int kMaxSeriesPerRequest = 20;
constexpr std::int64_t kMaxPoints = 100000;

// A parameter this route does not know is refused rather than ignored:
// a misspelt "max_point" would otherwise silently give the default.
void only_params(const httplib::Request& req, const std::set<std::string>& known) {
  for (const auto& [name, value] : req.params)
    if (!known.contains(name)) throw InputError("unknown parameter '" + name + "'");
}

// from, to (ISO 8601 UTC or ns since the epoch, inclusive).
void read_range(const httplib::Request& req, storage::TrendQuery& q) {
  if (req.has_param("from")) q.from_ns = storage::ns_from_utc(req.get_param_value("from"), "from");
  if (req.has_param("to")) q.to_ns = storage::ns_from_utc(req.get_param_value("to"), "to");
  if (q.from_ns > q.to_ns) throw InputError("from: after to");
}

std::vector<std::string> series_params(const httplib::Request& req) {
  const size_t n = req.get_param_value_count("series");
  if (n == 0) throw InputError("series: at least one is needed (GET .../series lists them)");
  if (n > kMaxSeriesPerRequest) throw InputError("series: at most " + std::to_string(kMaxSeriesPerRequest) + " per request");
  std::vector<std::string> out;
  for (size_t i = 0; i < n; ++i) {
    out.push_back(req.get_param_value("series", i));
    if (out.back().empty()) throw InputError("series: an empty name");
  }
  return out;
}

void not_found_series(const std::string& pump_id, const std::string& name) {
  throw NotFoundError("pump '" + pump_id + "' has no series '" + name + "' (GET /api/v1/pumps/" + pump_id + "/series lists them)");
}

void series_list(RouteContext& c, const std::string& pump_id) {
  only_params(c.req, {});
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!h->find_pump(pump_id)) throw NotFoundError("no pump '" + pump_id + "'");
  json list = json::array();
  for (const auto& s : h->list_series(pump_id)) list.push_back({{"name", s.name}, {"unit", s.unit}});
  send_json(c.res, 200, {{"pump_id", pump_id}, {"series", list}});
}

void trends(RouteContext& c, const std::string& pump_id) {
  only_params(c.req, {"series", "from", "to", "max_points", "raw"});
  const auto names = series_params(c.req);
  storage::TrendQuery q;
  read_range(c.req, q);
  if (c.req.has_param("max_points")) {
    q.max_points = positive_integer(c.req.get_param_value("max_points"), "max_points");
    if (q.max_points > kMaxPoints) throw InputError("max_points: at most " + std::to_string(kMaxPoints));
  }
  if (c.req.has_param("raw")) {
    const std::string r = c.req.get_param_value("raw");
    if (r != "true" && r != "false") throw InputError("raw: '" + r + "' is neither true nor false");
    q.raw = r == "true";
  }
  auto h = c.pool.acquire();
  auto snap = h->snapshot();  // every series from one committed state
  if (!h->find_pump(pump_id)) throw NotFoundError("no pump '" + pump_id + "'");
  const json defaults = alarm_defaults_of(c);
  json out = json::array();
  bool truncated = false;
  for (const auto& name : names) {
    const auto t = h->query_trend(pump_id, name, q);
    if (!t) not_found_series(pump_id, name);
    json j = trend_json(*t);
    const auto band = reference_band(*h, pump_id, name);
    if (band) j["reference"] = *band;
    if (auto limits = series_limits(*h, pump_id, name, defaults, band)) j["limits"] = std::move(*limits);
    truncated = truncated || t->truncated;
    out.push_back(std::move(j));
  }
  json body = {{"pump_id", pump_id}, {"max_points", q.max_points}, {"series", out}, {"truncated", truncated}};
  if (truncated) body["continue"] = "ask again with from = each truncated series' next_from";
  send_json(c.res, 200, body);
}

double number_param(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
    throw InputError(what + ": '" + text + "' is not a finite number");
  return v;
}

void prognosis(RouteContext& c, const std::string& pump_id) {
  only_params(c.req, {"series", "limit", "from", "to"});
  const auto names = series_params(c.req);
  if (names.size() != 1) throw InputError("series: exactly one for a prognosis");
  const std::string& name = names.front();
  std::optional<double> limit = default_prognosis_limit(name);
  const bool given = c.req.has_param("limit");
  if (given) limit = number_param(c.req.get_param_value("limit"), "limit");
  if (!limit) throw InputError("limit: needed for series '" + name + "' (it has no default limit)");
  storage::TrendQuery q;
  read_range(c.req, q);
  q.raw = true;
  q.max_points = kMaxPoints;
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!h->find_pump(pump_id)) throw NotFoundError("no pump '" + pump_id + "'");
  const auto t = h->query_trend(pump_id, name, q);
  if (!t) not_found_series(pump_id, name);
  std::vector<PrognosisPoint> pts;
  for (const auto& p : t->points) pts.push_back({1e-9 * static_cast<double>(p.time_ns), p.value, p.sd});
  const PrognosisOptions opt;
  const Prognosis p = prognose(std::move(pts), *limit, opt);
  constexpr double kDay = 86400.0;
  json j = {{"pump_id", pump_id},
            {"series", name},
            {"unit", t->series.unit},
            {"limit", *limit},
            {"limit_source", given ? "query" : "default"},
            {"status", to_string(p.status)},
            {"points", p.n},
            {"span_s", p.span_s},
            {"truncated", t->truncated}};
  if (!p.reason.empty()) j["reason"] = p.reason;
  if (p.status == PrognosisStatus::ok || p.status == PrognosisStatus::limit_reached || p.status == PrognosisStatus::not_trending) {
    j["weighted"] = p.weighted;
    j["slope_per_day"] = p.slope_per_s * kDay;
    j["slope_sd_per_day"] = p.slope_sd_per_s * kDay;
    j["value_at_last"] = p.value_at_last;
  }
  if (p.crossing_s) {
    j["estimated_at"] = utc_from_s(*p.crossing_s).value_or("beyond 2262");
    j["interval"] = {{"level", opt.level},
                     {"from", utc_from_s(*p.lower_s).value_or("before 1677")},
                     {"to", utc_from_s(*p.upper_s).value_or("beyond 2262")}};
  }
  send_json(c.res, 200, j);
}

}  // namespace

void add_trend_routes(RouteTable& t) {
  using storage::Role;
  using namespace schema;
  add_trend_schemas(t);
  t.add({"GET", "/api/v1/pumps/{pump_id}/series", Role::viewer, "the pump's trend series: name and unit",
         [](RouteContext& c, const PathParams& p) { series_list(c, p.at("pump_id")); }})
      .response_schema = object({{"series", array(object({{"name", string()}, {"unit", string()}}))}}, {{"pump_id", string()}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/trends", Role::viewer,
         "points of the pump's series over a range, or min/max buckets past max_points, with the reference band",
         [](RouteContext& c, const PathParams& p) { trends(c, p.at("pump_id")); },
         {{"series", "a series name (URL-encoded); up to 20", true, true},
          {"from", "from this time on (ISO 8601 UTC or ns since the epoch, inclusive; default: the first point)"},
          {"to", "up to this time (inclusive; default: the last point)"},
          {"max_points", "at most this many points; more become as many min/max buckets (1..100000, default 1000)"},
          {"raw", "true: the first max_points points and where to go on, instead of buckets"}}})
      .response_schema = object({{"series", array(ref("Trend"))}},
                                {{"pump_id", string()}, {"max_points", integer()}, {"truncated", boolean()}, {"continue", string()}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/prognosis", Role::viewer,
         "when the series' linear trend reaches a limit, with a 90 % interval, or why not",
         [](RouteContext& c, const PathParams& p) { prognosis(c, p.at("pump_id")); },
         {{"series", "the series name (URL-encoded)", true},
          {"limit", "the limit (default for the wear clearance factors: 2)"},
          {"from", "points from this time on (default: all)"},
          {"to", "points up to this time"}}})
      .response_schema = ref("Prognosis");
}

}  // namespace ambdiag::server::detail
