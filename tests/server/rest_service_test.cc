// The service routes over real HTTP on an ephemeral port against a real
// historian file: the OpenAPI document (against the routes the server
// really answers, and an independent validator), GET /metrics (checked by
// Prometheus' promtool), the event stream and the per-token rate limit.
#include <gtest/gtest.h>
#include <httplib.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <regex>
#include <thread>

#include "ambdiag/core/io_util.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/events.h"
#include "ambdiag/server/metrics.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/recording_io.h"
#include "test_support.h"

namespace ambdiag::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;
using storage::Historian;
using storage::Role;

const std::string kRefRunId = "P-101/2026-11-21T10:00:00Z";

// What a command printed (stdout and stderr) and its exit status.
std::pair<int, std::string> run_command(const std::string& cmd, const fs::path& out) {
  const int rc = std::system((cmd + " > " + out.string() + " 2>&1").c_str());
  return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, read_file_bytes(out.string())};
}

class RestService : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ambdiag::testing::scratch_dir();
    db_path_ = (dir_ / "h.db").string();
    Historian h = Historian::open(db_path_);
    storage::import_recording(h, ambdiag::testing::data_file("reference_pump/run_ref_1").string());
    for (const auto& [name, role] : std::vector<std::pair<std::string, Role>>{
             {"viewer", Role::viewer}, {"viewer2", Role::viewer}, {"admin", Role::admin}})
      tokens_[name] = h.add_token(name, role);
  }

  void start(RestOptions opt = {}) {
    AnalysisOptions aopt;
    aopt.db_path = db_path_;
    aopt.metrics = &metrics_;
    aopt.verbose = false;
    analysis_.emplace(aopt);  // not started: writes are stored and queued, nothing runs
    opt.db_path = db_path_;
    opt.host = "127.0.0.1";
    opt.analysis = &*analysis_;
    opt.metrics = &metrics_;
    opt.events = &events_;
    opt.event_heartbeat_ms = 200;
    server_ = std::make_unique<RestServer>(opt);
    port_ = server_->start();
  }

  httplib::Client client() const {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(10, 0);
    return c;
  }
  httplib::Headers auth(const std::string& who) const {
    return {{"Authorization", "Bearer " + tokens_.at(who)}};
  }

  struct Answer {
    int status = 0;
    std::string content_type, body;
  };
  // Any method; a text/event-stream answer is cut after its first chunk.
  Answer request(const std::string& method, const std::string& path, const std::string& who = "admin") const {
    auto c = client();
    Answer a;
    if (method == "GET") {
      c.Get(
          path, auth(who),
          [&](const httplib::Response& r) {
            a.status = r.status;
            a.content_type = r.get_header_value("Content-Type");
            return true;
          },
          [&](const char* d, size_t n) {
            a.body.append(d, n);
            return a.content_type.rfind("text/event-stream", 0) != 0;
          });
      return a;
    }
    httplib::Result r = method == "POST"    ? c.Post(path, auth(who), "{}", "application/json")
                        : method == "PUT"   ? c.Put(path, auth(who), "{}", "application/json")
                        : method == "PATCH" ? c.Patch(path, auth(who), "{}", "application/json")
                                            : c.Delete(path, auth(who));
    if (r) a = {r->status, r->get_header_value("Content-Type"), r->body};
    return a;
  }

  std::string metrics_text() const {
    const auto r = client().Get("/metrics");
    EXPECT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_EQ(r->get_header_value("Content-Type"), "text/plain; version=0.0.4; charset=utf-8");
    return r->body;
  }
  // The value of one series line ("name{labels}"), -1 when it is absent.
  static double series(const std::string& text, const std::string& name_and_labels) {
    const auto at = text.find("\n" + name_and_labels + " ");
    if (at == std::string::npos) return -1;
    return std::stod(text.substr(at + name_and_labels.size() + 2));
  }

  fs::path dir_;
  std::string db_path_;
  std::map<std::string, std::string> tokens_;
  MetricsRegistry metrics_;
  EventBus events_;
  std::optional<AnalysisService> analysis_;
  std::unique_ptr<RestServer> server_;
  int port_ = 0;
};

TEST_F(RestService, TheOpenApiDocumentListsEveryRouteTheServerAnswersAndEachAnswers) {
  start();
  EXPECT_EQ(client().Get("/api/v1/openapi.json")->status, 401);  // a viewer route, like every other read
  const auto r = client().Get("/api/v1/openapi.json", auth("viewer"));
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const json doc = json::parse(r->body);
  EXPECT_EQ(doc["openapi"], "3.1.0");
  EXPECT_EQ(doc["components"]["securitySchemes"]["bearer"]["scheme"], "bearer");

  // rest.md's routes and the service's own are documented.
  for (const auto& [path, method] :
       std::vector<std::pair<std::string, std::string>>{{"/api/v1/health", "get"},
                                                        {"/metrics", "get"},
                                                        {"/api/v1/events", "get"},
                                                        {"/api/v1/openapi.json", "get"},
                                                        {"/api/v1/pumps/{pump_id}/model", "put"},
                                                        {"/api/v1/runs/{run_id}/analysis", "get"},
                                                        {"/api/v1/jobs/{job_id}", "get"},
                                                        {"/api/v1/runs/{run_id}/samples.f32", "get"}})
    EXPECT_TRUE(doc["paths"].contains(path) && doc["paths"][path].contains(method)) << method << " " << path;

  const std::map<std::string, std::string> values = {{"pump_id", "P-101"},
                                                     {"run_id", url_encode_segment(kRefRunId)},
                                                     {"job_id", "1"},
                                                     {"name", "explain.svg"}};
  int operations = 0;
  for (const auto& [path, item] : doc["paths"].items()) {
    EXPECT_EQ(path.find('*'), std::string::npos) << path;
    std::string concrete = path;
    for (const auto& [name, value] : values)
      concrete = std::regex_replace(concrete, std::regex("\\{" + name + "\\}"), value);
    // Parameters of routes added later (an alarm_id, ...): any value reaches the route.
    concrete = std::regex_replace(concrete, std::regex("\\{[A-Za-z0-9_]+\\}"), "1");
    for (const std::string method : {"GET", "POST", "PUT", "PATCH", "DELETE"}) {
      std::string lower = method;
      for (auto& ch : lower) ch = static_cast<char>(std::tolower(ch));
      const Answer a = request(method, concrete);
      if (item.contains(lower)) {
        ++operations;
        const json& op = item[lower];
        // Documented: it answers, as a route (not the 404 of an unknown path, not 405).
        EXPECT_NE(a.status, 405) << method << " " << concrete << ": " << a.body.substr(0, 300);
        EXPECT_FALSE(a.status == 404 && a.body.find("no such resource") != std::string::npos)
            << method << " " << concrete;
        EXPECT_TRUE(op.contains("x-ambdiag-role")) << method << " " << path;
        EXPECT_TRUE(op["responses"].contains("400")) << method << " " << path;
        if (op["x-ambdiag-role"] != "none") {
          EXPECT_TRUE(op["responses"].contains("401") && op["responses"].contains("403"))
              << method << " " << path;
        } else {
          EXPECT_EQ(op["security"], json::array()) << path;
        }
        for (const auto& p : op.value("parameters", json::array()))
          if (p["in"] == "path") {
            EXPECT_NE(path.find("{" + p["name"].get<std::string>() + "}"), std::string::npos) << path;
          }
      } else {
        // Not documented: the server does not answer it either.
        EXPECT_EQ(a.status, 405) << method << " " << concrete
                                 << " answers but is not in the document: " << a.body;
      }
    }
  }
  EXPECT_GE(operations, 25);
  // Anything else is no route at all.
  EXPECT_EQ(request("GET", "/api/v1/nothing-here").status, 404);
  EXPECT_EQ(request("GET", "/api/v2/pumps").status, 404);
}

TEST_F(RestService, AnIndependentOpenApiValidatorAcceptsTheDocument) {
  const fs::path tool = fs::path(AMBDIAG_SOURCE_DIR) / "tests/tools/openapi";
  if (!fs::exists(tool / "node_modules/@seriousme/openapi-schema-validator") ||
      std::system("node --version > /dev/null 2>&1") != 0)
    GTEST_SKIP() << "the validator is not installed (deploy/install-deps.sh runs npm ci in " << tool << ")";
  start();
  const auto r = client().Get("/api/v1/openapi.json", auth("viewer"));
  ASSERT_TRUE(r && r->status == 200);
  const fs::path file = dir_ / "openapi.json";
  std::ofstream(file) << r->body;
  const auto [rc, out] =
      run_command("node " + (tool / "validate.mjs").string() + " " + file.string(), dir_ / "validate.log");
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("valid (3.1)"), std::string::npos) << out;
  // And it refuses a broken one: the check can fail.
  json broken = json::parse(r->body);
  broken["paths"]["/api/v1/pumps"]["get"]["responses"]["200"] = 42;
  std::ofstream(dir_ / "broken.json") << broken.dump();
  EXPECT_NE(run_command("node " + (tool / "validate.mjs").string() + " " + (dir_ / "broken.json").string(),
                        dir_ / "broken.log")
                .first,
            0);
}

TEST_F(RestService, PromtoolAcceptsTheMetricsAndTheCountersMove) {
  start();
  EXPECT_EQ(client().Get("/api/v1/pumps", auth("viewer"))->status, 200);
  EXPECT_EQ(client().Get("/api/v1/no/such/thing", auth("viewer"))->status, 404);
  EXPECT_EQ(client().Get("/api/v1/pumps")->status, 401);
  EXPECT_EQ(client().Get("/api/v1/pumps/P-404", auth("viewer"))->status, 404);
  // A new model queues the pump's run: the jobs table has one queued analysis.
  const std::string plant =
      read_file_bytes(ambdiag::testing::data_file("reference_pump/plant.json").string());
  EXPECT_EQ(client().Put("/api/v1/pumps/P-101/model", auth("admin"), plant, "application/json")->status, 200);

  std::string text = metrics_text();
  EXPECT_EQ(series(text, R"(ambdiag_http_requests_total{route="/api/v1/pumps",method="GET",status="200"})"),
            1)
      << text;
  EXPECT_EQ(series(text, R"(ambdiag_http_requests_total{route="/api/v1/pumps",method="GET",status="401"})"),
            1)
      << text;
  EXPECT_EQ(series(text, R"(ambdiag_http_requests_total{route="unmatched",method="GET",status="404"})"), 1)
      << text;
  // A 404 of a known route is labelled by its pattern, never by the raw path.
  EXPECT_EQ(
      series(text,
             R"(ambdiag_http_requests_total{route="/api/v1/pumps/{pump_id}",method="GET",status="404"})"),
      1)
      << text;
  EXPECT_EQ(text.find("P-404"), std::string::npos);
  EXPECT_EQ(
      series(
          text,
          R"(ambdiag_http_requests_total{route="/api/v1/pumps/{pump_id}/model",method="PUT",status="200"})"),
      1)
      << text;
  EXPECT_EQ(
      series(text, R"(ambdiag_http_request_duration_seconds_count{route="/api/v1/pumps",method="GET"})"), 2)
      << text;
  EXPECT_EQ(series(text, R"(ambdiag_jobs{kind="analysis",status="queued"})"), 1) << text;
  EXPECT_EQ(series(text, "ambdiag_historian_runs"), 1) << text;
  client().Get("/api/v1/pumps", auth("viewer"));
  text = metrics_text();
  EXPECT_EQ(series(text, R"(ambdiag_http_requests_total{route="/api/v1/pumps",method="GET",status="200"})"),
            2)
      << text;
  // The first scrape is counted too, under its own route.
  EXPECT_EQ(series(text, R"(ambdiag_http_requests_total{route="/metrics",method="GET",status="200"})"), 1)
      << text;

  const fs::path file = dir_ / "metrics.txt";
  std::ofstream(file) << text;
  const auto [rc, out] = run_command("promtool check metrics < " + file.string(), dir_ / "promtool.log");
  ASSERT_NE(rc, 127) << "promtool is missing: deploy/install-deps.sh installs Debian's prometheus package";
  EXPECT_EQ(rc, 0) << out;
  EXPECT_EQ(out, "") << "promtool reported problems:\n" << out;
}

// Reads an event stream on its own thread until `until` holds for what
// arrived (or the deadline).
class StreamReader {
 public:
  StreamReader(int port, httplib::Headers headers, std::string path) {
    thread_ = std::thread([this, port, headers = std::move(headers), path = std::move(path)] {
      httplib::Client c("127.0.0.1", port);
      c.set_read_timeout(5, 0);
      c.Get(
          path, headers,
          [&](const httplib::Response& r) {
            status_ = r.status;
            return true;
          },
          [&](const char* d, size_t n) {
            std::lock_guard l(mu_);
            text_.append(d, n);
            return !stop_;
          });
      done_ = true;
    });
  }
  ~StreamReader() {
    stop_ = true;
    thread_.join();
  }
  bool wait_for(const std::string& part, std::chrono::milliseconds timeout = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      if (text().find(part) != std::string::npos) return true;
      if (done_) return false;
      std::this_thread::sleep_for(10ms);
    }
    return false;
  }
  std::string text() {
    std::lock_guard l(mu_);
    return text_;
  }
  int status() const { return status_; }
  bool done() const { return done_; }

 private:
  std::thread thread_;
  std::mutex mu_;
  std::string text_;
  std::atomic<bool> stop_{false}, done_{false};
  std::atomic<int> status_{0};
};

TEST_F(RestService, AnEventStreamCarriesANewModelAndAReconnectGetsWhatItMissed) {
  start();
  const std::string plant =
      read_file_bytes(ambdiag::testing::data_file("reference_pump/plant.json").string());
  std::string first_id;
  {
    // A browser's EventSource: the token in the query, on this route only.
    StreamReader s(port_, {}, "/api/v1/events?access_token=" + tokens_.at("viewer"));
    ASSERT_TRUE(s.wait_for(": ambdiag events")) << s.status() << s.text();
    EXPECT_EQ(s.status(), 200);
    ASSERT_EQ(client().Put("/api/v1/pumps/P-101/model", auth("admin"), plant, "application/json")->status,
              200);
    ASSERT_TRUE(s.wait_for("event: model.new\ndata: {")) << s.text();
    const std::string text = s.text();
    const std::smatch m = [&] {
      std::smatch x;
      std::regex_search(text, x, std::regex("id: (\\d+)\nevent: model.new\ndata: (.*)\n\n"));
      return x;
    }();
    ASSERT_EQ(m.size(), 3u) << text;
    first_id = m[1];
    const json data = json::parse(m[2].str());
    EXPECT_EQ(data["pump_id"], "P-101");
    EXPECT_EQ(data["model_version"], 1);
    EXPECT_EQ(data["by"], "admin");
    EXPECT_TRUE(s.wait_for(": heartbeat")) << "an idle stream sends heartbeats";
  }
  // While no one listens, a second version; the reconnect names the id it saw.
  ASSERT_EQ(client().Put("/api/v1/pumps/P-101/model", auth("admin"), plant, "application/json")->status, 200);
  {
    auto h = auth("viewer");
    h.emplace("Last-Event-ID", first_id);
    StreamReader s(port_, h, "/api/v1/events");
    ASSERT_TRUE(s.wait_for("\"model_version\":2")) << s.text();
    EXPECT_EQ(s.text().find("\"model_version\":1"), std::string::npos) << "only what it missed";
  }
  {
    auto h = auth("viewer");
    h.emplace("Last-Event-ID", "1");  // long gone
    StreamReader s(port_, h, "/api/v1/events");
    ASSERT_TRUE(s.wait_for("event: reload\n")) << s.text();
  }
  // The query token is refused where it is not allowed, and on the stream when it is wrong.
  EXPECT_EQ(client().Get("/api/v1/pumps?access_token=" + tokens_.at("viewer"))->status, 401);
  EXPECT_EQ(request("GET", "/api/v1/events?access_token=nope", "viewer").status,
            200);  // the header's token counts first
  EXPECT_EQ(client().Get("/api/v1/events?access_token=nope")->status, 401);
  auto bad = auth("viewer");
  bad.emplace("Last-Event-ID", "12x");
  EXPECT_EQ(client().Get("/api/v1/events", bad)->status, 400);
}

TEST_F(RestService, StreamsBeyondTheLimitAre503AndTheApiStillAnswers) {
  RestOptions opt;
  opt.worker_threads = 4;
  opt.max_event_streams = 2;
  start(opt);
  StreamReader a(port_, auth("viewer"), "/api/v1/events");
  StreamReader b(port_, auth("viewer"), "/api/v1/events");
  ASSERT_TRUE(a.wait_for(": ambdiag events"));
  ASSERT_TRUE(b.wait_for(": ambdiag events"));
  const auto third = client().Get("/api/v1/events", auth("viewer"));
  ASSERT_TRUE(third);
  EXPECT_EQ(third->status, 503);
  EXPECT_NE(third->body.find("too many event streams"), std::string::npos) << third->body;
  for (int i = 0; i < 10; ++i) EXPECT_EQ(client().Get("/api/v1/pumps", auth("viewer"))->status, 200);
  EXPECT_EQ(series(metrics_text(), "ambdiag_event_streams"), 2);
  // The server stops with streams open: they end, it does not hang.
  const auto t0 = std::chrono::steady_clock::now();
  server_->stop();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 5s);
  for (int i = 0; i < 500 && !(a.done() && b.done()); ++i) std::this_thread::sleep_for(10ms);
  EXPECT_TRUE(a.done() && b.done());
}

TEST_F(RestService, ABurstBeyondTheRateLimitIs429AndAnotherTokenIsNotAffected) {
  RestOptions opt;
  opt.rate_limit_per_s = 1;
  opt.rate_limit_burst = 5;
  start(opt);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(client().Get("/api/v1/pumps", auth("viewer"))->status, 200) << i;
  const auto r = client().Get("/api/v1/pumps", auth("viewer"));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 429);
  EXPECT_NE(json::parse(r->body)["error"].get<std::string>().find("rate limit of token 'viewer'"),
            std::string::npos)
      << r->body;
  EXPECT_GE(std::stoi(r->get_header_value("Retry-After")), 1);
  // Another token (same role, same address) has its own bucket.
  EXPECT_EQ(client().Get("/api/v1/pumps", auth("viewer2"))->status, 200);
  // Health and metrics are never limited.
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(client().Get("/api/v1/health")->status, 200);
    EXPECT_EQ(client().Get("/metrics")->status, 200);
  }
  EXPECT_EQ(series(metrics_text(), "ambdiag_http_rate_limited_total"), 1);
}

TEST_F(RestService, AnonymousReadsAreLimitedByClientAddress) {
  RestOptions opt;
  opt.anonymous_read = true;
  opt.rate_limit_per_s = 1;
  opt.rate_limit_burst = 3;
  start(opt);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(client().Get("/api/v1/pumps")->status, 200) << i;
  const auto r = client().Get("/api/v1/pumps");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 429);
  EXPECT_NE(r->body.find("address 127.0.0.1"), std::string::npos) << r->body;
  EXPECT_EQ(client().Get("/api/v1/pumps", auth("viewer"))->status, 200);  // a token has its own
}

}  // namespace
}  // namespace ambdiag::server
