#include "routes/route_context.h"

#include <limits>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "analysis/views.h"
#include "rest_json.h"
#include "routes/api_schemas.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

std::string run_url(const std::string& run_id) { return "/api/v1/runs/" + url_encode_segment(run_id); }

void send_artifact(httplib::Response& res, const storage::JobArtifact& a) {
  res.status = 200;
  res.set_content(a.data, a.content_type);
}

void get_pump(RouteContext& c, const std::string& pump_id) {
  auto h = c.pool.acquire();
  const auto j = pump_view(*h, pump_id, c.opt.proposed_reference_runs);
  if (!j) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  send_json(c.res, 200, *j);
}

void get_model(RouteContext& c, const std::string& pump_id) {
  std::optional<int> version;
  if (c.req.has_param("version"))
    version = static_cast<int>(std::min<std::int64_t>(positive_integer(c.req.get_param_value("version"), "version"),
                                                      std::numeric_limits<int>::max()));
  auto h = c.pool.acquire();
  const auto m = h->find_model(pump_id, version);
  if (!m) {
    if (!h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
    return send_error(c.res, 404, version ? "pump '" + pump_id + "' has no model version " + std::to_string(*version)
                                          : "pump '" + pump_id + "' has no model");
  }
  c.res.status = 200;
  c.res.set_header("X-Model-Version", std::to_string(m->version));
  c.res.set_content(m->plant_json, "application/json");
}

void put_model(RouteContext& c, const std::string& pump_id) {
  if (pump_id.size() > 128) throw InputError("pump_id: longer than 128 bytes");
  const int version = c.opt.analysis->put_model(pump_id, c.req.body, c.caller.name);
  send_json(c.res, 200, {{"pump_id", pump_id}, {"model_version", version}});
}

void get_models(RouteContext& c, const std::string& pump_id) {
  auto h = c.pool.acquire();
  const auto list = h->list_models(pump_id);
  if (list.empty() && !h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  json out = json::array();
  for (const auto& m : list)
    out.push_back({{"model_version", m.version}, {"created_at", m.created_at}, {"created_by", m.created_by}, {"comment", m.comment}});
  send_json(c.res, 200, {{"pump_id", pump_id}, {"models", out}});
}

void get_reference(RouteContext& c, const std::string& pump_id) {
  auto h = c.pool.acquire();
  const auto pump = pump_view(*h, pump_id, c.opt.proposed_reference_runs);
  if (!pump) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  if (!pump->contains("reference")) return send_error(c.res, 404, "pump '" + pump_id + "' has no reference and too few runs to propose one");
  json j = (*pump)["reference"];
  j["pump_id"] = pump_id;
  send_json(c.res, 200, j);
}

void put_reference(RouteContext& c, const std::string& pump_id) {
  const json body = parse_body(c.req, "reference");
  if (!body.is_object() || !body.contains("runs") || !body["runs"].is_array())
    throw InputError("reference: the body must be {\"runs\": [run_id, ...]}");
  std::vector<std::string> runs;
  for (const auto& r : body["runs"]) {
    if (!r.is_string()) throw InputError("reference: runs: every entry must be a run_id string");
    runs.push_back(r.get<std::string>());
  }
  const auto reply = c.opt.analysis->put_reference(pump_id, runs, c.caller.name);
  send_json(c.res, 202, {{"pump_id", pump_id}, {"job_id", reply.job_id}, {"reference_version", reply.reference_version}});
}

void get_analysis(RouteContext& c, const std::string& run_id) {
  auto h = c.pool.acquire();
  const auto j = analysis_view(*h, run_id, run_url(run_id));
  if (!j) return send_error(c.res, 404, "no run '" + run_id + "'");
  send_json(c.res, 200, *j);
}

void get_run_file(RouteContext& c, const std::string& run_id, const std::string& name) {
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  const auto run = h->find_run(run_id);
  if (!run) return send_error(c.res, 404, "no run '" + run_id + "'");
  const auto job = current_analysis_job(*h, *run);
  if (!job || job->status != storage::JobStatus::done)
    return send_error(c.res, 404, "run '" + run_id + "' has no finished analysis yet (GET " + run_url(run_id) + "/analysis)");
  const auto a = h->find_artifact(job->job_id, name);
  if (!a && run->frf_dropped_at) return send_error(c.res, 410, dropped_by_retention(*run, false));
  if (!a) return send_error(c.res, 404, "the analysis of run '" + run_id + "' has no " + name);
  send_artifact(c.res, *a);
}

void post_explain(RouteContext& c, const std::string& run_id) {
  const auto id = c.opt.analysis->request_explain(run_id, c.caller.name);
  send_json(c.res, 202, {{"job_id", id}, {"run_id", run_id}});
}

void get_jobs(RouteContext& c) {
  storage::JobFilter f;
  if (c.req.has_param("pump_id")) f.pump_id = c.req.get_param_value("pump_id");
  if (c.req.has_param("run_id")) f.run_id = c.req.get_param_value("run_id");
  if (c.req.has_param("kind")) f.kind = c.req.get_param_value("kind");
  if (c.req.has_param("status")) {
    f.status = storage::job_status_from(c.req.get_param_value("status"));
    if (!f.status)
      throw InputError("status: '" + c.req.get_param_value("status") + "' is not queued, running, done, failed or cancelled");
  }
  if (c.req.has_param("limit"))
    f.limit = static_cast<int>(std::min<std::int64_t>(positive_integer(c.req.get_param_value("limit"), "limit"), 10000));
  auto h = c.pool.acquire();
  json list = json::array();
  for (const auto& j : h->list_jobs(f)) list.push_back(job_json(j, false));
  send_json(c.res, 200, {{"jobs", list}});
}

void get_job(RouteContext& c, const std::string& job_id) {
  const auto id = positive_integer(job_id, "job_id");
  auto h = c.pool.acquire();
  const auto j = h->find_job(id);
  if (!j) return send_error(c.res, 404, "no job " + job_id);
  json out = job_json(*j, true);
  json files = json::object();
  for (const auto& name : h->list_artifacts(id)) files[name] = "/api/v1/jobs/" + job_id + "/files/" + name;
  if (!files.empty()) out["files"] = files;
  send_json(c.res, 200, out);
}

void get_job_file(RouteContext& c, const std::string& job_id, const std::string& name) {
  const auto id = positive_integer(job_id, "job_id");
  auto h = c.pool.acquire();
  if (!h->find_job(id)) return send_error(c.res, 404, "no job " + job_id);
  const auto a = h->find_artifact(id, name);
  if (!a) return send_error(c.res, 404, "job " + job_id + " has no file '" + name + "'");
  send_artifact(c.res, *a);
}

void post_adopt(RouteContext& c, const std::string& job_id) {
  const auto id = positive_integer(job_id, "job_id");
  const int version = c.opt.analysis->adopt_explained_model(id, c.caller.name);
  auto h = c.pool.acquire();
  const auto j = h->find_job(id);
  send_json(c.res, 200, {{"pump_id", j ? j->key.pump_id : ""}, {"model_version", version}, {"adopted_from_job", id}});
}

void post_cancel(RouteContext& c, const std::string& job_id) {
  const auto id = positive_integer(job_id, "job_id");
  c.opt.analysis->cancel_job(id, c.caller.name);
  auto h = c.pool.acquire();
  send_json(c.res, 200, job_json(*h->find_job(id), false));
}

}  // namespace

void add_analysis_routes(RouteTable& t) {
  using storage::Role;
  using namespace schema;
  add_analysis_schemas(t);
  const auto pump = [](void (*f)(RouteContext&, const std::string&)) {
    return [f](RouteContext& c, const PathParams& p) { f(c, p.at("pump_id")); };
  };
  const auto run = [](void (*f)(RouteContext&, const std::string&)) {
    return [f](RouteContext& c, const PathParams& p) { f(c, p.at("run_id")); };
  };
  const auto job = [](void (*f)(RouteContext&, const std::string&)) {
    return [f](RouteContext& c, const PathParams& p) { f(c, p.at("job_id")); };
  };
  t.add({"GET", "/api/v1/pumps/{pump_id}", Role::viewer, "a pump: model and reference versions, health, active alarms, last run and analysis", pump(get_pump)})
      .response_schema = ref("Pump");
  t.add({"GET", "/api/v1/pumps/{pump_id}/model", Role::viewer, "the plant JSON of a model version (default: the current one)", pump(get_model),
         {{"version", "model version (default: the current one)"}}});
  auto& model = t.add({"PUT", "/api/v1/pumps/{pump_id}/model", Role::engineer, "a new model version (body: plant JSON); registers the pump", pump(put_model)});
  model.body = "the plant JSON (plant-model.md); a bad plant is 400 naming the field";
  model.response_schema = object({{"pump_id", string()}, {"model_version", integer()}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/models", Role::viewer, "every model version of a pump", pump(get_models)})
      .response_schema = object({{"pump_id", string()},
                                 {"models", array(object({{"model_version", integer()}, {"created_at", time()}},
                                                         {{"created_by", string()}, {"comment", string()}}))}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/reference", Role::viewer, "the pump's reference (or the proposed one)", pump(get_reference)})
      .response_schema = ref("Reference");
  auto& reference = t.add({"PUT", "/api/v1/pumps/{pump_id}/reference", Role::engineer,
                           "a new reference version from runs (body {\"runs\": [run_id, ...]})", pump(put_reference)});
  reference.body = "{\"runs\": [run_id, ...]}: at least 2 complete identification runs of the pump";
  reference.status = 202;
  reference.body_schema = object({{"runs", array(string())}});
  reference.response_schema = object({{"job_id", integer()}, {"reference_version", integer()}}, {{"pump_id", string()}});
  t.add({"GET", "/api/v1/runs/{run_id*}/analysis", Role::viewer, "the run's analysis: status, modes, detection, diagnosis", run(get_analysis)})
      .response_schema = ref("Analysis");
  for (const std::string file : {"frf.csv", "bode.svg", "stabilization.svg", "diagnosis.svg", "fit_model.json"})
    t.add({"GET", "/api/v1/runs/{run_id*}/" + file, Role::viewer, "the analysis' " + file,
           [file](RouteContext& c, const PathParams& p) { get_run_file(c, p.at("run_id"), file); }, {},
           file == "frf.csv" ? "text/csv" : file == "fit_model.json" ? "application/json" : "image/svg+xml"})
        .errors = {410};
  auto& explain = t.add({"POST", "/api/v1/runs/{run_id*}/explain", Role::engineer, "an explain job for the run (202 with its job_id)", run(post_explain)});
  explain.status = 202;
  explain.response_schema = object({{"job_id", integer()}}, {{"run_id", string()}});
  t.add({"GET", "/api/v1/jobs", Role::viewer, "jobs, newest first", [](RouteContext& c, const PathParams&) { get_jobs(c); },
         {{"pump_id", "only this pump's"}, {"run_id", "only this run's"}, {"kind", "analysis, reference or explain"},
          {"status", "queued, running, done, failed or cancelled"}, {"limit", "at most this many (1..10000)"}}})
      .response_schema = object({{"jobs", array(ref("Job"))}});
  t.add({"GET", "/api/v1/jobs/{job_id}", Role::viewer, "a job with its result and files", job(get_job)})
      .response_schema = ref("Job");
  t.add({"GET", "/api/v1/jobs/{job_id}/files/{name}", Role::viewer, "a file a job made",
         [](RouteContext& c, const PathParams& p) { get_job_file(c, p.at("job_id"), p.at("name")); }, {}, "application/octet-stream"});
  t.add({"POST", "/api/v1/jobs/{job_id}/adopt", Role::engineer, "adopt an explain job's improved model as the pump's new model version", job(post_adopt)})
      .response_schema = object({{"pump_id", string()}, {"model_version", integer()}, {"adopted_from_job", integer()}});
  t.add({"POST", "/api/v1/jobs/{job_id}/cancel", Role::engineer, "cancel a queued or running job", job(post_cancel)})
      .response_schema = ref("Job");
}

}  // namespace ambdiag::server::detail
