// The analysis service end to end with real processes (issue 16): tokens
// and roles, a pump's model and reference over REST, every run streamed by
// an agent analysed by the server, detection and diagnosis read back, a
// kill -9 during an analysis, bad input refused with its reason.
#include <csignal>
#include <sstream>

#include "ambdiag/core/io_util.h"
#include "service_fixture.h"

namespace ambdiag::testing {
namespace {

constexpr const char* kRefRun = "P-101/2026-11-21T10:00:00Z";
constexpr const char* kDryRun = "P-101/2026-11-21T11:00:00Z";

std::string plant_text() { return read_file_bytes(data_file("reference_pump/plant.json").string()); }

TEST_F(ServiceTest, TokensAndRolesGuardEveryRouteButHealth) {
  start_service();
  auto c = client();
  EXPECT_EQ(c.Get("/api/v1/health")->status, 200);
  EXPECT_EQ(c.Get("/api/v1/pumps")->status, 401);
  EXPECT_EQ(c.Get("/api/v1/pumps", {{"Authorization", "Bearer not-a-token"}})->status, 401);
  EXPECT_EQ(get("/api/v1/pumps", "viewer")->status, 200);
  // Writes need engineer: viewer and operator get 403 naming the role.
  for (const char* role : {"viewer", "operator"}) {
    const auto r = put("/api/v1/pumps/P-9/model", plant_text(), role);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 403) << role;
    EXPECT_NE(json_of(r)["error"].get<std::string>().find("engineer"), std::string::npos);
  }
  EXPECT_EQ(put("/api/v1/pumps/P-9/model", plant_text(), "admin")->status, 200);  // admin holds engineer's rights
  // A revoked token stops working at the next request.
  Process revoke({AMBDIAG_CLI, "token", "revoke", "--db", db.string(), "viewer"}, env, (dir / "revoke.log").string());
  ASSERT_EQ(revoke.wait(30s), 0) << revoke.log();
  EXPECT_EQ(get("/api/v1/pumps", "viewer")->status, 401);
  // Bodies past the limit are 413, never parsed.
  EXPECT_EQ(put("/api/v1/pumps/P-9/model", std::string(9u << 20, ' '))->status, 413);
}

TEST_F(ServiceTest, EveryRunIsAnalysedAndAReferenceAddsDetectionAndDiagnosis) {
  start_service();
  // A model that does not parse: 400 naming what is wrong, nothing stored.
  const auto bad = put("/api/v1/pumps/P-101/model", R"({"format": "ambdiag.plant/1", "shaft": 3})");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);
  EXPECT_FALSE(json_of(bad)["error"].get<std::string>().empty());
  EXPECT_EQ(get("/api/v1/pumps/P-101/model")->status, 404);

  // A run before the model: waiting; the model's PUT queues it.
  ASSERT_TRUE(replay(data_file("reference_pump/run_ref_1")));
  EXPECT_EQ(json_of(get(run_url(kRefRun) + "/analysis"))["status"], "waiting");
  const auto m = put("/api/v1/pumps/P-101/model", plant_text());
  ASSERT_EQ(m->status, 200) << m->body;
  EXPECT_EQ(json_of(m)["model_version"], 1);
  EXPECT_EQ(nlohmann::json::parse(get("/api/v1/pumps/P-101/model")->body), nlohmann::json::parse(plant_text()));

  const auto a = wait_analysis(kRefRun);
  ASSERT_EQ(a["status"], "done") << a.dump();
  EXPECT_TRUE(a["detection"].is_null());  // no reference yet
  EXPECT_EQ(a["model_version"], 1);
  int labelled = 0;
  for (const auto& mode : a["modes"]) labelled += mode.contains("label") ? 1 : 0;
  EXPECT_GE(labelled, 4) << a["modes"].dump();
  EXPECT_LT(a["nrmse"].get<double>(), 0.5);
  for (const char* f : {"bode.svg", "stabilization.svg", "frf.csv"}) {
    const auto r = get(run_url(kRefRun) + "/" + f);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << f;
    EXPECT_GT(r->body.size(), 1000u) << f;
  }

  // Two more healthy runs: the first three are proposed as the reference.
  const auto copy1 = copy_run("reference_pump/run_ref_1", "P-101/copy-1", "2026-11-21T10:30:00Z");
  ASSERT_TRUE(replay(copy1));
  ASSERT_TRUE(replay(data_file("fault_dry_run/run")));
  const auto pump = json_of(get("/api/v1/pumps/P-101"));
  ASSERT_TRUE(pump.contains("reference")) << pump.dump();
  EXPECT_EQ(pump["reference"]["status"], "proposed");
  EXPECT_EQ(pump["reference"]["runs"].size(), 3u);

  // References naming what is not a healthy run of this pump: 400 naming it.
  EXPECT_EQ(put("/api/v1/pumps/P-101/reference", R"({"runs": ["P-101/none"]})")->status, 400);
  EXPECT_EQ(put("/api/v1/pumps/P-101/reference", R"({"runs": "P-101/copy-1"})")->status, 400);
  EXPECT_EQ(put("/api/v1/pumps/P-101/reference", R"({"runs": ["P-101/copy-1"]})")->status, 400);  // one run
  EXPECT_EQ(put("/api/v1/pumps/P-404/reference", R"({"runs": ["P-101/copy-1"]})")->status, 404);

  // The engineer's reference: a job learns it, every run is analysed again.
  const auto ref = put("/api/v1/pumps/P-101/reference",
                       nlohmann::json{{"runs", {kRefRun, "P-101/copy-1"}}}.dump());
  ASSERT_EQ(ref->status, 202) << ref->body;
  EXPECT_EQ(json_of(ref)["reference_version"], 1);
  const auto healthy = wait_analysis(kRefRun, 180s, 1);
  ASSERT_EQ(healthy["status"], "done") << healthy.dump();
  ASSERT_TRUE(healthy["detection"].is_object()) << healthy.dump();
  EXPECT_FALSE(healthy["detection"]["detected"].get<bool>()) << healthy["detection"].dump();
  EXPECT_GT(healthy["detection"]["false_alarm_rate"].get<double>(), 0.0);
  // The seal drift fitted for the run, per fluid-seal link (for trends).
  EXPECT_EQ(healthy["detection"]["operating"]["nuisance"].size(), 2u) << healthy["detection"].dump();

  const auto dry = wait_analysis(kDryRun, 180s, 1);
  ASSERT_EQ(dry["status"], "done") << dry.dump();
  EXPECT_TRUE(dry["detection"]["detected"].get<bool>()) << dry["detection"].dump();
  ASSERT_TRUE(dry["diagnosis"].is_object());
  EXPECT_EQ(dry["diagnosis"]["faults"][0]["fault"], "dry_run") << dry["diagnosis"].dump();
  EXPECT_EQ(get(run_url(kDryRun) + "/diagnosis.svg")->status, 200);

  // The dry run's alarm (fault.dry_run, critical): evaluated just after its analysis.
  auto after = json_of(get("/api/v1/pumps/P-101"));
  for (auto until = std::chrono::steady_clock::now() + 10s; after["health"] != "alarm" && std::chrono::steady_clock::now() < until;) {
    std::this_thread::sleep_for(100ms);
    after = json_of(get("/api/v1/pumps/P-101"));
  }
  EXPECT_EQ(after["reference"]["status"], "active");
  EXPECT_EQ(after["health"], "alarm") << after.dump() << json_of(get("/api/v1/alarms")).dump();
  const auto job = json_of(get("/api/v1/jobs/" + std::to_string(json_of(ref)["job_id"].get<int>())));
  EXPECT_EQ(job["kind"], "reference");
  EXPECT_EQ(job["status"], "done");
  // What was learnt: per run its seal factors and fit, the model's bias.
  ASSERT_EQ(job["result"]["learnt"].size(), 2u) << job.dump();
  EXPECT_EQ(job["result"]["learnt"][0]["seal_factors"].size(), 2u);
  EXPECT_GT(job["result"]["model_bias_nrmse"].get<double>(), 0.0);
  EXPECT_LT(job["result"]["model_bias_nrmse"].get<double>(), 0.5);
  // One analysis job per (run, model version, reference version).
  const auto jobs = json_of(get("/api/v1/jobs?run_id=" + server::url_encode_segment(kRefRun) + "&status=done"))["jobs"];
  EXPECT_EQ(jobs.size(), 2u) << jobs.dump();  // against (1, none) and (1, 1)
}

TEST_F(ServiceTest, KillDuringAnAnalysisAnalysesTheRunOnceAfterRestart) {
  start_service({"--workers", "1"});
  ASSERT_EQ(put("/api/v1/pumps/P-101/model", plant_text())->status, 200);
  // Not replay(): the agent ends once its run's verdict is durable, up to a
  // second after the commit that starts the analysis, which may be done by then.
  auto agent = start_agent(data_file("reference_pump/run_ref_1"), {"--fast"});
  // Kill -9 while the analysis runs.
  bool seen_running = false;
  for (int i = 0; i < 600 && !seen_running; ++i) {
    const auto r = get(run_url(kRefRun) + "/analysis");
    seen_running = r && r->status == 200 && json_of(r)["status"] == "running";
    if (!seen_running) std::this_thread::sleep_for(20ms);
  }
  ASSERT_TRUE(seen_running);
  server->signal(SIGKILL);
  server->wait(10s);
  start_service({"--workers", "1"});
  EXPECT_EQ(agent->wait(120s), 0) << agent->log();  // its verdict from the restarted server
  const auto a = wait_analysis(kRefRun);
  EXPECT_EQ(a["status"], "done") << a.dump();
  const auto jobs = json_of(get("/api/v1/jobs?run_id=" + server::url_encode_segment(kRefRun)))["jobs"];
  ASSERT_EQ(jobs.size(), 1u) << jobs.dump();
  EXPECT_EQ(jobs[0]["attempts"], 2);
  EXPECT_EQ(jobs[0]["status"], "done");
}

// Bad input never stops the service: a run whose reference channel is dead
// fails its analysis naming the channel, the next run is analysed; a
// reference naming another pump's run is refused naming it.
TEST_F(ServiceTest, ABadRunFailsItsJobWithTheReasonAndTheNextGoesOn) {
  start_service({"--workers", "1"});
  ASSERT_EQ(put("/api/v1/pumps/P-101/model", plant_text())->status, 200);
  const auto dead = copy_run("reference_pump/run_ref_1", "P-101/dead-rZ", "2026-11-21T09:00:00Z", [](RunRecording& run) {
    const int c = run.channel_index("rZ");
    for (int64_t t = 0; t < run.frame_count(); ++t) run.samples[static_cast<size_t>(t) * run.channels.size() + c] = 0;
  });
  ASSERT_TRUE(replay(dead));
  ASSERT_TRUE(replay(data_file("reference_pump/run_ref_1")));
  const auto failed = wait_analysis("P-101/dead-rZ");
  EXPECT_EQ(failed["status"], "failed") << failed.dump();
  EXPECT_NE(failed.value("error", "").find("rZ"), std::string::npos) << failed.dump();
  EXPECT_EQ(wait_analysis(kRefRun)["status"], "done");
  const auto job = json_of(get("/api/v1/jobs?run_id=" + server::url_encode_segment("P-101/dead-rZ")))["jobs"];
  ASSERT_EQ(job.size(), 1u);
  EXPECT_EQ(job[0]["status"], "failed");
  EXPECT_EQ(job[0]["attempts"], 1);  // a failure is not retried

  const auto other = copy_run("reference_pump/run_ref_1", "P-102/run-1", "2026-11-21T09:30:00Z",
                              [](RunRecording& run) { run.pump_id = "P-102"; });
  ASSERT_TRUE(replay(other));
  const auto r = put("/api/v1/pumps/P-101/reference", nlohmann::json{{"runs", {kRefRun, "P-102/run-1"}}}.dump());
  ASSERT_EQ(r->status, 400) << r->body;
  EXPECT_NE(json_of(r)["error"].get<std::string>().find("P-102/run-1"), std::string::npos) << r->body;
}

// Ingest first: the analysis workers (--workers 3 here) are the server's
// only threads at SCHED_IDLE (policy 5, field 41 of /proc/PID/task/TID/stat),
// so they get only the CPU that ingest and REST leave.
TEST_F(ServiceTest, AnalysisWorkersRunAtIdlePriority) {
  start_service({"--workers", "3"});
  std::this_thread::sleep_for(500ms);  // the workers set their policy when they start
  int idle = 0, threads = 0;
  for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(server->pid()) + "/task")) {
    const std::string stat = read_file_bytes((task.path() / "stat").string());
    std::istringstream fields(stat.substr(stat.rfind(')') + 2));
    std::string field;
    for (int k = 3; k <= 41 && fields >> field; ++k) {
    }
    ++threads;
    idle += field == "5" ? 1 : 0;
  }
  EXPECT_EQ(idle, 3) << threads << " threads";
  EXPECT_GT(threads, 3);
}

// Until issue 22 a second server on the file exited 3 (FILE.lock). Now it
// stands by for the ingest group the first holds and serves the same
// database (docs/service.md "Several servers").
TEST_F(ServiceTest, ASecondServerOnTheSameFileStandsByForTheIngestAndServesTheSame) {
  start_service();
  Process second({AMBDIAG_CLI, "serve", "--db", db.string(), "--http-port", "0", "--domain", std::to_string(domain),
                  "--partition", partition},
                 env, (dir / "second.log").string());
  const int second_port = rest_port(second);
  ASSERT_GT(second_port, 0) << second.log();
  httplib::Client c2("127.0.0.1", second_port);
  const auto role = [](const httplib::Result& r) { return json_of(r)["ingest_groups"].at(0).value("role", ""); };
  EXPECT_EQ(role(client().Get("/api/v1/health")), "holder");
  EXPECT_EQ(role(c2.Get("/api/v1/health")), "standby");
  EXPECT_EQ(put("/api/v1/pumps/P-9/model", plant_text())->status, 200);
  const auto pumps = get("/api/v1/pumps");
  ASSERT_EQ(pumps->status, 200);
  EXPECT_EQ(c2.Get("/api/v1/pumps", auth("viewer"))->body, pumps->body);
  second.signal(SIGTERM);
  EXPECT_EQ(second.wait(30s), 0) << second.log();
}

TEST_F(ServiceTest, ExplainRunsOnRequestAndItsModelCanBeAdopted) {
  start_service();
  ASSERT_EQ(put("/api/v1/pumps/P-101/model", plant_text())->status, 200);
  ASSERT_TRUE(replay(data_file("reference_pump/run_ref_1")));
  ASSERT_EQ(wait_analysis(kRefRun)["status"], "done");
  EXPECT_EQ(post(run_url(kRefRun) + "/explain", "{}", "viewer")->status, 403);
  EXPECT_EQ(post(run_url("P-101/none") + "/explain")->status, 404);
  const auto e = post(run_url(kRefRun) + "/explain");
  ASSERT_EQ(e->status, 202) << e->body;
  const auto id = std::to_string(json_of(e)["job_id"].get<int>());
  // Progress while it runs never goes back and stays in 0..1; done is 1.
  nlohmann::json job;
  double last_progress = 0;
  for (int i = 0; i < 3000; ++i) {
    job = json_of(get("/api/v1/jobs/" + id));
    const double p = job["progress"].get<double>();
    EXPECT_GE(p, last_progress);
    EXPECT_LE(p, 1.0);
    last_progress = p;
    if (job["status"] == "done" || job["status"] == "failed") break;
    std::this_thread::sleep_for(20ms);
  }
  ASSERT_EQ(job["status"], "done") << job.dump();
  EXPECT_EQ(job["progress"], 1.0);
  EXPECT_TRUE(job["result"].contains("explanations"));
  EXPECT_TRUE(job["result"].contains("improved_model"));
  EXPECT_EQ(get("/api/v1/jobs/" + id + "/files/explain.svg")->status, 200);
  const auto adopt = post("/api/v1/jobs/" + id + "/adopt");
  ASSERT_EQ(adopt->status, 200) << adopt->body;
  EXPECT_EQ(json_of(adopt)["model_version"], 2);
  // The new version re-queues the pump's runs: the run's analysis moves to it.
  const auto again = wait_analysis(kRefRun);
  EXPECT_EQ(again["model_version"], 2) << again.dump();
  const auto models = json_of(get("/api/v1/pumps/P-101/models"))["models"];
  ASSERT_EQ(models.size(), 2u);
  EXPECT_NE(models[1]["comment"].get<std::string>().find("explain job " + id), std::string::npos);
  // The run is analysed again against version 2; version 1 is kept.
  EXPECT_EQ(get("/api/v1/pumps/P-101/model?version=1")->status, 200);
}

}  // namespace
}  // namespace ambdiag::testing
