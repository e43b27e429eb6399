// Each pump's retention policy (docs/service.md "Retention"): the effective
// policy with where each value comes from, a new version by an engineer,
// and the versions with who made them.
#include "ambdiag/server/retention_service.h"
#include "routes/json_schema.h"
#include "routes/route_context.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

// The server's defaults: the retention service's, else (ambdiag-rest alone) the built-in ones.
storage::RetentionPolicy defaults_of(const RouteContext& c) {
  return c.opt.retention ? c.opt.retention->defaults() : storage::RetentionPolicy{};
}

void get_policy(RouteContext& c, const PathParams& p) {
  const std::string& pump_id = p.at("pump_id");
  auto h = c.pool.acquire();
  const auto view = retention_view(*h, pump_id, defaults_of(c));
  if (!view) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  send_json(c.res, 200, *view);
}

void put_policy(RouteContext& c, const PathParams& p) {
  if (!c.opt.retention)
    return send_error(c.res, 503, "this server runs without the retention service: PUT " + c.req.path + " is not served");
  const json body = parse_body(c.req, "retention");
  send_json(c.res, 200, c.opt.retention->put_policy(p.at("pump_id"), body, c.caller.name));
}

void get_history(RouteContext& c, const PathParams& p) {
  const std::string& pump_id = p.at("pump_id");
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  json versions = json::array();
  for (const auto& v : h->list_retention_policies(pump_id))
    versions.push_back({{"version", v.version}, {"created_at", v.created_at}, {"created_by", v.created_by},
                        {"override", json::parse(v.policy_json)}});
  send_json(c.res, 200, {{"pump_id", pump_id}, {"versions", versions}});
}

}  // namespace

void add_retention_routes(RouteTable& t) {
  using storage::Role;
  using namespace schema;
  // Each value a number, null: kept for ever (storage/retention_policy.h).
  const json days = nullable(number());
  const json values = object({}, {{"samples_days", days}, {"samples_bytes", nullable(integer())}, {"frf_days", days}, {"monitoring_days", days}});
  t.add_schema("RetentionPolicy", values);
  const json policy = object({{"pump_id", string()},
                              {"policy", ref("RetentionPolicy")},
                              {"source", one_of({"pump", "defaults"})},
                              {"override", ref("RetentionPolicy")},
                              {"defaults", ref("RetentionPolicy")},
                              {"usage", object({{"runs_with_samples", integer()},
                                                {"samples_bytes_held", integer()},
                                                {"runs_samples_dropped", integer()},
                                                {"samples_bytes_dropped", integer()},
                                                {"runs_frf_dropped", integer()},
                                                {"frf_bytes_dropped", integer()}})}},
                             {{"version", integer()}, {"created_at", time()}, {"created_by", string()}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/retention", Role::viewer,
         "the pump's retention policy: effective values, its own keys over the server's defaults, what it holds", get_policy})
      .response_schema = policy;
  auto& put = t.add({"PUT", "/api/v1/pumps/{pump_id}/retention", Role::engineer,
                     "a new version of the pump's retention policy (its keys over the server's defaults)", put_policy});
  put.body =
      "{\"samples_days\"?, \"samples_bytes\"?, \"frf_days\"?, \"monitoring_days\"?}: each a number (null: kept for ever); "
      "keys left out take the server's defaults; {} goes back to them";
  put.writes_elsewhere = true;
  put.body_schema = ref("RetentionPolicy");
  put.response_schema = policy;
  t.add({"GET", "/api/v1/pumps/{pump_id}/retention/history", Role::viewer,
         "every version of the pump's retention policy, oldest first, with who made it", get_history})
      .response_schema = object({{"pump_id", string()},
                                 {"versions", array(object({{"version", integer()},
                                                            {"created_at", time()},
                                                            {"created_by", string()},
                                                            {"override", ref("RetentionPolicy")}}))}});
}

}  // namespace ambdiag::server::detail
