// What a route's handler gets (RouteContext), the token check every route
// but the open ones goes through, and the files that add each feature's
// routes to the table (route_table.h). Reads use the REST reader pool;
// writes go to the AnalysisService, which owns the write connection and the
// job queue.
#pragma once

#include <httplib.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/service.h"
#include "reader_pool.h"
#include "routes/route_table.h"

namespace ambdiag::server::detail {

void send_json(httplib::Response& res, int status, const nlohmann::json& body);
void send_error(httplib::Response& res, int status, const std::string& message);

// Who makes the request: the token's name and role ("anonymous" viewer
// under --anonymous-read).
struct Caller {
  std::string name = "anonymous";
  storage::Role role = storage::Role::viewer;
  bool from_token = false;  // false: anonymous (rate-limited by address)
};

// The caller when the request's token (Authorization: Bearer) has at least
// `needed`; otherwise sends 401 (no or unknown token) or 403 (role too low)
// and returns nullopt. The token is looked up on every request, so `ambdiag
// token revoke` takes effect on the next one. `token_in_query`: without the
// header, ?access_token= is taken as the token.
std::optional<Caller> authorize(ReaderPool& pool, const httplib::Request& req, storage::Role needed, bool anonymous_read,
                                httplib::Response& res, bool token_in_query = false);

struct RouteContext {
  ReaderPool& pool;
  const RestOptions& opt;
  Caller caller;
  const httplib::Request& req;
  httplib::Response& res;
};

// The request's body as JSON; InputError naming `what` otherwise.
nlohmann::json parse_body(const httplib::Request& req, const std::string& what);
// A positive integer parameter or path segment; InputError naming it.
std::int64_t positive_integer(const std::string& text, const std::string& what);

// health, pumps, runs, samples, monitoring (read_routes.cc); `started` is the
// server's start, for health's uptime.
void add_read_routes(RouteTable& t, std::chrono::steady_clock::time_point started);
// models, references, analyses and their files, explain, jobs (analysis_routes.cc).
void add_analysis_routes(RouteTable& t);
// series, trends, prognosis (trend_routes.cc).
void add_trend_routes(RouteTable& t);
// the Grafana data source under /api/v1/grafana (grafana_routes.cc).
void add_grafana_routes(RouteTable& t);
// the web UI's files, the fleet in one reply, a run's model FRF (web_routes.cc).
void add_web_routes(RouteTable& t);
// openapi.json, metrics, events: service_routes.h (they need the server's state).
// alarms, their journal, KPIs and each pump's alarm rules (alarm_routes.cc).
void add_alarm_routes(RouteTable& t);
// each pump's retention policy (retention_routes.cc).
void add_retention_routes(RouteTable& t);
// The server's default alarm rules (the analysis service's, else the
// built-in ones), which a pump's own rules override (alarm_routes.cc).
nlohmann::json alarm_defaults_of(const RouteContext& c);

}  // namespace ambdiag::server::detail
