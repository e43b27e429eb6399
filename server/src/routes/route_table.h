// Every REST route in one table: method, path pattern, the role it needs and
// what it does. The server dispatches from it, and GET /api/v1/openapi.json
// is generated from it, so a route cannot be served and undocumented (or the
// reverse). Each feature adds its routes in its own file (add_*_routes).
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/service.h"

namespace ambdiag::server::detail {

struct RouteContext;

// Path parameters by name ("pump_id" -> "P-101"), percent-decoded.
using PathParams = std::map<std::string, std::string>;
using RouteHandler = std::function<void(RouteContext&, const PathParams&)>;

struct QueryParam {
  std::string name;
  std::string description;
  bool required = false;
  bool repeated = false;  // ?series=a&series=b
};

struct Route {
  std::string method;   // GET (answers HEAD too), POST or PUT
  // "/api/v1/pumps/{pump_id}/runs": "{name}" matches one non-empty segment,
  // "{name*}" one or more (a run_id whose '/' came unencoded); one per pattern.
  std::string pattern;
  std::optional<storage::Role> role;  // nullopt: open to all (health, metrics)
  std::string summary;                // one line, for the OpenAPI document
  RouteHandler handler;
  std::vector<QueryParam> query = {};
  std::string response_type = "application/json";
  // For the OpenAPI document; set after add() (t.add({...}).body = "..."),
  // so that the positional initializers above keep compiling.
  std::string body = {};    // what a PUT/POST body holds ("": no body expected)
  std::string body_type = "application/json";
  // JSON Schemas (2020-12, routes/json_schema.h) of the success answer and
  // of the body, for the OpenAPI document; null: only "an object".
  nlohmann::json response_schema = nullptr;
  nlohmann::json body_schema = nullptr;
  int status = 200;         // the status of success (202: a job was queued)
  std::string description = {};  // more than the summary: behaviour, limits
  // The token may also come as ?access_token= (EventSource cannot set
  // headers); only where a browser needs it, since URLs end up in logs.
  bool token_in_query = false;
  // A POST that only reads (Grafana's queries carry their request in a
  // body): served without the analysis service, like a GET.
  bool read_only = false;
  // A write that goes to a service of its own (retention policies), not to
  // the analysis service: served without it; the handler answers 503 when
  // its own service is missing.
  bool writes_elsewhere = false;
  // Error statuses the route answers besides the usual ones (e.g. 410: the
  // data was dropped by retention), for the OpenAPI document.
  std::vector<int> errors = {};
  // Also answers the path with a trailing '/' (Grafana's connection test
  // asks for the data source's URL + "/"); other routes refuse it (404).
  bool trailing_slash = false;
};

// One segment of a parsed pattern: a literal, or a parameter's name.
struct PatternSegment {
  std::string text;
  bool param = false;
  bool rest = false;  // "{name*}"
};

class RouteTable {
 public:
  // Throws std::logic_error on a malformed pattern or a duplicate (method,
  // pattern): both are programming errors caught by every test. The
  // reference returned is valid until the next add.
  Route& add(Route r);

  struct Found {
    const Route* route = nullptr;  // null: no route for this method
    PathParams params;
    bool path_known = false;       // some route has this path (then 405, not 404)
    std::string allow;             // "GET, HEAD, PUT" for a 405
  };
  // The most specific route (most literal segments) whose pattern the
  // decoded path segments match; a path ending in '/' (an empty last
  // segment) matches a route with trailing_slash without it.
  Found find(const std::string& method, const std::vector<std::string>& segments) const;

  // A named schema (an OpenAPI component) that routes reference as
  // schema::ref(name): a Pump, a Run, an Alarm shared by several routes.
  // Throws std::logic_error on a duplicate name.
  void add_schema(const std::string& name, nlohmann::json schema);
  const std::map<std::string, nlohmann::json>& schemas() const { return schemas_; }

  const std::vector<Route>& routes() const { return routes_; }
  // The parsed pattern of routes()[i].
  const std::vector<PatternSegment>& pattern(size_t i) const { return patterns_[i]; }

 private:
  std::vector<Route> routes_;
  std::vector<std::vector<PatternSegment>> patterns_;  // parsed once, by index
  std::map<std::string, nlohmann::json> schemas_;
};

}  // namespace ambdiag::server::detail
