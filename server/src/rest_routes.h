// The REST routes of the analysis side (rest.md: pumps, models, references,
// analyses, jobs, explain) and the token check every route but health goes
// through. Reads use the REST reader pool; writes go to the
// AnalysisService, which owns the write connection and the job queue.
#pragma once

#include <httplib.h>

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/service.h"
#include "reader_pool.h"

namespace ambdiag::server::detail {

void send_json(httplib::Response& res, int status, const nlohmann::json& body);
void send_error(httplib::Response& res, int status, const std::string& message);

// Who makes the request: the token's name and role ("anonymous" viewer
// under --anonymous-read).
struct Caller {
  std::string name = "anonymous";
  storage::Role role = storage::Role::viewer;
};

// The caller when the request's token (Authorization: Bearer) has at least
// `needed`; otherwise sends 401 (no or unknown token) or 403 (role too low)
// and returns nullopt. The token is looked up on every request, so `ambdiag
// token revoke` takes effect on the next one.
std::optional<Caller> authorize(ReaderPool& pool, const httplib::Request& req, storage::Role needed, bool anonymous_read,
                                httplib::Response& res);

struct RouteContext {
  ReaderPool& pool;
  const RestOptions& opt;
  Caller caller;
  const httplib::Request& req;
  httplib::Response& res;
};

void get_pump(RouteContext& c, const std::string& pump_id);
void get_model(RouteContext& c, const std::string& pump_id);
void put_model(RouteContext& c, const std::string& pump_id);
void get_models(RouteContext& c, const std::string& pump_id);
void get_reference(RouteContext& c, const std::string& pump_id);
void put_reference(RouteContext& c, const std::string& pump_id);
void get_analysis(RouteContext& c, const std::string& run_id);
void get_run_file(RouteContext& c, const std::string& run_id, const std::string& name);
void post_explain(RouteContext& c, const std::string& run_id);
void get_jobs(RouteContext& c);
void get_job(RouteContext& c, const std::string& job_id);
void get_job_file(RouteContext& c, const std::string& job_id, const std::string& name);
void post_adopt(RouteContext& c, const std::string& job_id);
void post_cancel(RouteContext& c, const std::string& job_id);

}  // namespace ambdiag::server::detail
