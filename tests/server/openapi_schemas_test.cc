// The OpenAPI document holds the server to what it answers: on a real
// server over a real historian file, with the real job runner, a pump with
// a model, runs analysed, a reference, a diagnosed run, jobs, series and
// trend points, a monitoring snapshot, alarms with a history, the pump's
// own alarm rules and retention policy; then every route whose answer the
// document describes is called and its real answer (and the body sent)
// validated against the schema taken from the served openapi.json (the
// tests' own validator, json_schema_check.h). A route given a schema but
// not exercised here fails the test, so the two cannot drift apart.
#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <map>
#include <set>
#include <thread>

#include "alarm_seed.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/server/retention_service.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/recording_io.h"
#include "json_schema_check.h"
#include "rest_request.h"
#include "test_support.h"

namespace ambdiag::server {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;
using storage::Historian;

const std::string kRun = "P-101/2026-11-21T10:00:00Z";
const std::string kCopy = "P-101/copy-1";  // a second healthy run, for a reference

class OpenApiSchemas : public ::testing::Test {
 protected:
  void SetUp() override {
    db_ = (ambdiag::testing::scratch_dir() / "h.db").string();
    writer_.emplace(Historian::open(db_));
    storage::import_recording(*writer_, ambdiag::testing::data_file("reference_pump/run_ref_1").string());
    admin_ = writer_->add_token("ada", storage::Role::admin);
    AnalysisOptions a;
    a.db_path = db_;
    a.verbose = false;
    a.workers = 1;
    a.idle_priority = false;  // others' builds on the machine must not stall the analysis
    analysis_ = std::make_unique<AnalysisService>(a);
    analysis_->start();
    RetentionOptions ro;
    ro.db_path = db_;
    ro.interval = std::chrono::milliseconds(0);  // policies kept, never swept here
    ro.verbose = false;
    retention_ = std::make_unique<RetentionService>(ro);
    RestOptions r;
    r.db_path = db_;
    r.host = "127.0.0.1";
    r.analysis = analysis_.get();
    r.retention = retention_.get();
    r.proposed_reference_runs = 1;  // the one run is proposed: GET .../reference answers
    server_ = std::make_unique<RestServer>(r);
    port_ = server_->start();
    const auto doc = request("GET", "/api/v1/openapi.json");
    ASSERT_EQ(doc->status, 200);
    document_ = json::parse(doc->body);
  }

  httplib::Result request(const std::string& method, const std::string& path, const std::string& body = "") {
    return rest_request(port_, method, path, admin_, body);
  }

  // A key as a JSON pointer's token ('/' as ~1).
  static std::string escaped(const std::string& key) {
    std::string out;
    for (const char ch : key) out += ch == '~' ? "~0" : ch == '/' ? "~1" : std::string(1, ch);
    return out;
  }

  // The success answer's schema of (method, path) in the served document;
  // null where it only says "an object" (a route not described yet).
  json response_schema(const std::string& method, const std::string& path) const {
    const json& op = document_["paths"][path][method];
    for (const auto& [status, response] : op["responses"].items()) {
      if (status[0] != '2') continue;
      const json::json_pointer at("/content/application~1json/schema");
      if (!response.contains(at)) return nullptr;  // not JSON
      const json& s = response.at(at);
      return s == json{{"type", "object"}} ? json(nullptr) : s;
    }
    return nullptr;
  }

  // Calls the route, expects its success status, validates the body sent
  // and the answer against the route's schemas (documented path `path`,
  // real URL `url`) and returns the answer.
  json checked(const std::string& method, const std::string& path, const std::string& url, const std::string& body = "") {
    const json::json_pointer body_at("/paths/" + escaped(path) + "/" + method + "/requestBody/content/application~1json/schema");
    if (!body.empty() && document_.contains(body_at))
      for (const auto& v : ambdiag::testing::schema_violations(json::parse(body), document_.at(body_at), document_))
        ADD_FAILURE() << method << " " << path << " body " << body << ": " << v;
    const auto r = request(method == "get" ? "GET" : method == "put" ? "PUT" : "POST", url, body);
    EXPECT_TRUE(r) << url;
    if (!r) return nullptr;
    EXPECT_EQ(r->status / 100, 2) << method << " " << url << ": " << r->body;
    const json answer = json::parse(r->body);
    const json schema = response_schema(method, path);
    EXPECT_FALSE(schema.is_null()) << method << " " << path << " has no schema";
    for (const auto& v : ambdiag::testing::schema_violations(answer, schema, document_))
      ADD_FAILURE() << method << " " << url << ": " << v << "\n  answer: " << answer.dump().substr(0, 2000);
    validated_.insert(method + " " + path);
    return answer;
  }

  // The run's analysis once done or failed against this reference version
  // (0: none), or as it stands at the deadline.
  json wait_analysis(const std::string& run_id, int reference_version, std::chrono::seconds timeout = 120s) {
    json a;
    for (const auto until = std::chrono::steady_clock::now() + timeout; std::chrono::steady_clock::now() < until;) {
      a = json::parse(request("GET", "/api/v1/runs/" + url_encode_segment(run_id) + "/analysis")->body);
      const bool finished = a["status"] == "done" || a["status"] == "failed";
      if (finished && a.value("reference_version", 0) == reference_version) break;
      std::this_thread::sleep_for(100ms);
    }
    return a;
  }

  std::string db_, admin_;
  std::optional<Historian> writer_;
  std::unique_ptr<AnalysisService> analysis_;
  std::unique_ptr<RetentionService> retention_;
  std::unique_ptr<RestServer> server_;
  int port_ = 0;
  json document_;
  std::set<std::string> validated_;  // "method path" of each route checked
};

TEST_F(OpenApiSchemas, EveryDescribedRouteAnswersAsItsSchemaSays) {
  // The state: a model (its PUT checked too), two runs analysed, the
  // reference learnt from them and the run analysed again against it (so
  // with a detection), an explain job cancelled, an alarm acknowledged,
  // shelved and unshelved, a latched one reset, the pump's alarm rules and
  // retention policy (each answer checked), a monitoring snapshot.
  const std::string plant = read_file_bytes(ambdiag::testing::data_file("reference_pump/plant.json").string());
  checked("put", "/api/v1/pumps/{pump_id}/model", "/api/v1/pumps/P-101/model", plant);
  RunRecording copy = read_run(ambdiag::testing::data_file("reference_pump/run_ref_1").string());
  copy.run_id = kCopy;
  copy.started_at = "2026-11-21T10:30:00Z";
  const auto copy_dir = std::filesystem::path(db_).parent_path() / "copy";  // scratch_dir() again would empty the folder
  write_run(copy_dir.string(), copy);
  storage::import_recording(*writer_, copy_dir.string());
  analysis_->notify_run_complete(kCopy);
  for (const auto& run : {kRun, kCopy}) {
    const json a = wait_analysis(run, 0);
    ASSERT_EQ(a["status"], "done") << a.dump().substr(0, 2000);
  }
  checked("put", "/api/v1/pumps/{pump_id}/reference", "/api/v1/pumps/P-101/reference",
          json{{"runs", {kRun, kCopy}}}.dump());
  const json analysis = wait_analysis(kRun, 1);
  ASSERT_EQ(analysis["status"], "done") << analysis.dump().substr(0, 2000);
  ASSERT_TRUE(analysis["detection"].is_object()) << "the detection's schema is applied";
  // A run with a fault: detected, so with a diagnosis (and the server's own alarm).
  const std::string dry = storage::import_recording(*writer_, ambdiag::testing::data_file("fault_dry_run/run").string()).run_id;
  analysis_->notify_run_complete(dry);
  ASSERT_EQ(wait_analysis(dry, 1)["status"], "done");
  const json diagnosed = checked("get", "/api/v1/runs/{run_id}/analysis", "/api/v1/runs/" + url_encode_segment(dry) + "/analysis");
  ASSERT_TRUE(diagnosed["diagnosis"].is_object()) << "the diagnosis' schema is applied";
  analysis_->stop();  // the explain job stays queued, to be cancelled
  const json explain = checked("post", "/api/v1/runs/{run_id}/explain", "/api/v1/runs/" + url_encode_segment(kRun) + "/explain");
  checked("post", "/api/v1/jobs/{job_id}/cancel", "/api/v1/jobs/" + std::to_string(explain["job_id"].get<int>()) + "/cancel");
  const auto latched = std::to_string(seed_alarm(*writer_, "P-101", "detection", kRun, true));
  checked("post", "/api/v1/alarms/{alarm_id}/reset", "/api/v1/alarms/" + latched + "/reset", R"({"comment": "overhauled"})");
  const auto alarm_id = std::to_string(seed_alarm(*writer_, "P-101", "fault.balance_piston_wear", kRun));
  const std::string alarm = "/api/v1/alarms/{alarm_id}";
  checked("post", alarm + "/ack", "/api/v1/alarms/" + alarm_id + "/ack", R"({"comment": "known"})");
  checked("post", alarm + "/shelve", "/api/v1/alarms/" + alarm_id + "/shelve", R"({"minutes": 30, "comment": "sensor work"})");
  checked("post", alarm + "/unshelve", "/api/v1/alarms/" + alarm_id + "/unshelve", "{}");
  checked("put", "/api/v1/pumps/{pump_id}/alarm-rules", "/api/v1/pumps/P-101/alarm-rules",
          R"({"rules": [{"id": "detection", "on_delay": {"k": 3, "n": 5}}]})");
  checked("put", "/api/v1/pumps/{pump_id}/retention", "/api/v1/pumps/P-101/retention", R"({"samples_days": 90})");
  storage::MonitoringSnapshot snap;
  snap.pump_id = "P-101";
  snap.time_ns = storage::ns_from_utc("2026-11-21T10:05:00Z", "time");
  snap.speed_rpm = 2950;
  snap.orbit_major_m = {2e-5, 3e-5};
  snap.orbit_minor_m = {1e-5, 1e-5};
  writer_->put_monitoring(std::span(&snap, 1));

  // The values of the path parameters and the queries some routes need.
  const json series = json::parse(request("GET", "/api/v1/pumps/P-101/series")->body)["series"];
  ASSERT_FALSE(series.empty()) << "the analysis fed no trend series";
  const std::string name = url_encode_segment(series[0]["name"].get<std::string>());
  const std::map<std::string, std::string> params = {{"{pump_id}", "P-101"},
                                                     {"{run_id}", url_encode_segment(kRun)},
                                                     {"{job_id}", std::to_string(analysis["job_id"].get<int>())},
                                                     {"{alarm_id}", alarm_id}};
  const std::map<std::string, std::string> queries = {{"/api/v1/pumps/{pump_id}/trends", "?series=" + name},
                                                      {"/api/v1/pumps/{pump_id}/prognosis", "?series=fit.nrmse&limit=1"}};
  // The Grafana data source's POSTs only read: each with a body that finds something.
  const auto grafana = [&](const std::string& what, const json& body) {
    const json answer = checked("post", "/api/v1/grafana/" + what, "/api/v1/grafana/" + what, body.dump());
    EXPECT_TRUE(what == "metric-payload-options" || !answer.empty()) << what << " found nothing";
  };
  for (const char* what : {"metrics", "search", "metric-payload-options", "variable"}) grafana(what, json::object());
  grafana("query", {{"targets", {{{"target", "P-101:fit.nrmse"}, {"refId", "A"}}}}});
  grafana("annotations", {{"annotation", {{"query", "P-101"}}}});

  // Lists whose items must be there, so that their schema was applied.
  const std::map<std::string, std::string> non_empty = {
      {"/api/v1/pumps", "/pumps"},
      {"/api/v1/fleet", "/pumps"},
      {"/api/v1/pumps/{pump_id}/runs", "/runs"},
      {"/api/v1/pumps/{pump_id}/monitoring", "/snapshots"},
      {"/api/v1/pumps/{pump_id}/models", "/models"},
      {"/api/v1/runs/{run_id}/analysis", "/modes"},
      {"/api/v1/jobs", "/jobs"},
      {"/api/v1/alarms", "/alarms"},
      {"/api/v1/alarms/{alarm_id}/history", "/events"},
      {"/api/v1/alarm-events", "/events"},
      {"/api/v1/pumps/{pump_id}/trends", "/series/0/points"},
      {"/api/v1/pumps/{pump_id}/alarm-rules", "/rules"},
      {"/api/v1/pumps/{pump_id}/retention/history", "/versions"}};

  std::set<std::string> described;
  for (const auto& [path, ops] : document_["paths"].items()) {
    for (const auto& [method, op] : ops.items()) {
      if (response_schema(method, path).is_null()) continue;
      described.insert(method + " " + path);
      if (method != "get") continue;
      std::string url = path;
      for (const auto& [param, value] : params)
        if (const auto at = url.find(param); at != std::string::npos) url.replace(at, param.size(), value);
      if (const auto q = queries.find(path); q != queries.end()) url += q->second;
      const json answer = checked(method, path, url);
      if (const auto n = non_empty.find(path); n != non_empty.end()) {
        EXPECT_FALSE(answer.value(json::json_pointer(n->second), json::array()).empty()) << url << ": " << n->second << " is empty";
      }
    }
  }
  // Described but not exercised here: adopting needs a done explain job,
  // minutes of CPU.
  EXPECT_EQ(described.erase("post /api/v1/jobs/{job_id}/adopt"), 1u) << "adopt is no longer described";
  for (const auto& d : described) EXPECT_TRUE(validated_.contains(d)) << d << " has a schema but was not checked";
  EXPECT_GE(validated_.size(), 20u);
}

}  // namespace
}  // namespace ambdiag::server
