// Retention with real processes: `ambdiag serve --retention FILE` with its
// periodic sweep, runs streamed by an agent and analysed, a pump's policy
// set over REST. The sweep drops the samples of the run that is no
// reference run, REST says so (the run listed, 410 for its samples); a new
// model analyses that run again from the FRF its analysis kept; once the FRF
// is dropped too, the next analysis fails naming retention; the reference
// runs keep everything; /metrics counts what was dropped. On PostgreSQL
// with --parts: only the analysis part sweeps.
#include <csignal>
#include <fstream>

#include "ambdiag/core/io_util.h"
#include "pg_cluster.h"
#include "service_fixture.h"

namespace ambdiag::testing {
namespace {

constexpr const char* kRefRun = "P-101/2026-11-21T10:00:00Z";
constexpr const char* kCopy1 = "P-101/copy-1";
constexpr const char* kCopy2 = "P-101/copy-2";
constexpr const char* kPolicy = "/api/v1/pumps/P-101/retention";

class RetentionServiceTest : public ServiceTest {
 protected:
  // Polls GET path until `done` holds for its JSON (or the deadline).
  nlohmann::json wait_for(const std::string& path, const std::function<bool(const nlohmann::json&)>& done,
                          std::chrono::seconds timeout = 180s) {
    nlohmann::json last;
    for (const auto until = std::chrono::steady_clock::now() + timeout; std::chrono::steady_clock::now() < until;) {
      const auto r = get(path);
      if (r && r->status == 200) {
        last = json_of(r);
        if (done(last)) return last;
      }
      std::this_thread::sleep_for(200ms);
    }
    ADD_FAILURE() << path << " did not get there in time; last: " << last.dump() << "\n" << server->log();
    return last;
  }
  // The run's analysis against this model version, once it ended.
  nlohmann::json analysis_of(const std::string& run_id, int model_version) {
    return wait_for(run_url(run_id) + "/analysis", [&](const nlohmann::json& a) {
      const std::string st = a.value("status", "");
      return a.value("model_version", 0) == model_version && a.value("reference_version", 0) == 1 &&
             (st == "done" || st == "failed");
    });
  }
  int put_model() {
    const auto m = put("/api/v1/pumps/P-101/model", read_file_bytes(data_file("reference_pump/plant.json").string()));
    EXPECT_EQ(m->status, 200) << m->body;
    return json_of(m)["model_version"].get<int>();
  }
};

TEST_F(RetentionServiceTest, OldSamplesAreDroppedTheReferenceKeptAndTheKeptFrfAnalysedAgain) {
  // The server keeps everything by default; the sweep runs every half second.
  const auto defaults = dir / "retention.json";
  std::ofstream(defaults) << R"({"samples_days": null, "frf_days": null})";
  start_service({"--retention", defaults.string(), "--retention-interval", "0.5"});
  put_model();
  ASSERT_TRUE(replay(data_file("reference_pump/run_ref_1")));
  ASSERT_TRUE(replay(copy_run("reference_pump/run_ref_1", kCopy1, "2026-11-21T10:30:00Z")));
  ASSERT_TRUE(replay(copy_run("reference_pump/run_ref_1", kCopy2, "2026-11-21T11:00:00Z")));
  const auto ref = put("/api/v1/pumps/P-101/reference", nlohmann::json{{"runs", {kRefRun, kCopy1}}}.dump());
  ASSERT_EQ(ref->status, 202) << ref->body;
  for (const char* run : {kRefRun, kCopy1, kCopy2}) ASSERT_EQ(analysis_of(run, 1)["status"], "done") << run;
  auto policy = json_of(get(kPolicy));
  EXPECT_TRUE(policy["policy"]["samples_days"].is_null()) << "--retention's defaults: " << policy.dump();
  EXPECT_EQ(policy["usage"]["runs_with_samples"], 3);

  // The pump keeps raw samples for no time: copy-2's go, the reference runs' stay.
  ASSERT_EQ(put(kPolicy, R"({"samples_days": 0})")->status, 200);
  const auto run = wait_for(run_url(kCopy2), [](const nlohmann::json& j) { return j["samples"] == "dropped"; }, 30s);
  EXPECT_EQ(run["status"], "complete");
  EXPECT_EQ(run["samples_dropped_bytes"], 6553600);
  for (const char* kept : {kRefRun, kCopy1}) EXPECT_EQ(json_of(get(run_url(kept)))["samples"], "held") << kept;
  auto r = get(run_url(kCopy2) + "/samples.f32");
  EXPECT_EQ(r->status, 410);
  EXPECT_NE(json_of(r)["error"].get<std::string>().find("run 'P-101/copy-2': its samples were dropped by retention at " +
                                                        run["samples_dropped_at"].get<std::string>()),
            std::string::npos)
      << r->body;
  EXPECT_EQ(get(run_url(kCopy2) + "/frf.csv")->status, 200) << "FRFs are kept longer";

  // A new model: copy-2 is analysed again from the FRF its analysis kept.
  const int v2 = put_model();
  const auto again = analysis_of(kCopy2, v2);
  ASSERT_EQ(again["status"], "done") << again.dump();
  EXPECT_FALSE(again["detection"]["detected"].get<bool>());
  const auto jobs = json_of(get("/api/v1/jobs?kind=analysis&status=done&limit=1&run_id=" + server::url_encode_segment(kCopy2)));
  const auto job = json_of(get("/api/v1/jobs/" + std::to_string(jobs["jobs"][0]["job_id"].get<int>())));
  EXPECT_NE(job["result"]["frf"].value("source", "").find("frf.csv of analysis job"), std::string::npos) << job["result"]["frf"].dump();

  // The FRFs go too: the files are gone (410), the next analysis fails naming retention.
  ASSERT_EQ(put(kPolicy, R"({"samples_days": 0, "frf_days": 0})")->status, 200);
  wait_for(run_url(kCopy2), [](const nlohmann::json& j) { return j.contains("frf_dropped_at"); }, 30s);
  EXPECT_EQ(get(run_url(kCopy2) + "/frf.csv")->status, 410);
  EXPECT_EQ(get(run_url(kCopy2) + "/model_frf.csv")->status, 410);
  const int v3 = put_model();
  const auto failed = analysis_of(kCopy2, v3);
  ASSERT_EQ(failed["status"], "failed") << failed.dump();
  const std::string error = failed["error"];
  EXPECT_NE(error.find("dropped by retention"), std::string::npos) << error;
  EXPECT_NE(error.find("cannot be analysed again"), std::string::npos) << error;
  // The reference runs kept everything and are analysed as before.
  EXPECT_EQ(analysis_of(kRefRun, v3)["status"], "done");
  const auto kept = json_of(get(run_url(kRefRun)));
  EXPECT_EQ(kept["samples"], "held");
  EXPECT_FALSE(kept.contains("frf_dropped_at"));
  EXPECT_EQ(get(run_url(kRefRun) + "/frf.csv")->status, 200);

  const std::string m = client().Get("/metrics")->body;
  EXPECT_NE(m.find("ambdiag_retention_dropped_bytes_total{what=\"samples\"} 6553600"), std::string::npos) << m;
  EXPECT_NE(m.find("ambdiag_retention_dropped_runs_total{what=\"frf\"} 1"), std::string::npos) << m;
  EXPECT_EQ(m.find("ambdiag_retention_last_sweep_timestamp_seconds 0\n"), std::string::npos);
  EXPECT_TRUE(json_of(client().Get("/api/v1/health"))["retention"].contains("samples")) << "the last sweep in health";
}

TEST_F(RetentionServiceTest, ABadRetentionFileStopsTheStartNamingTheKey) {
  const auto bad = dir / "retention.json";
  std::ofstream(bad) << R"({"samples_days": -3})";
  for (const char* role : {"viewer", "operator", "engineer", "admin"}) tokens[role] = add_token(role, role);
  Process p({AMBDIAG_CLI, "serve", "--db", db.string(), "--http-port", "0", "--retention", bad.string()}, env,
            (dir / "bad.log").string());
  EXPECT_EQ(p.wait(30s), 3) << p.log();
  EXPECT_NE(p.log().find("samples_days: must be a number of days"), std::string::npos) << p.log();
}

// Two servers on one PostgreSQL database: ingest and REST in one, the
// analysis in the other. Only the analysis part sweeps (a sweep option to
// a process without it is refused); its sweep drops what the REST
// process then shows as dropped.
TEST_F(RetentionServiceTest, OnPostgreSQLWithPartsTheAnalysisPartSweeps) {
  const auto location = postgres_test_location();
  if (!location) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
  db = *location;
  const auto defaults = dir / "retention.json";
  std::ofstream(defaults) << R"({"samples_days": 0})";
  Process refused({AMBDIAG_CLI, "serve", "--db", *location, "--parts", "rest", "--http-port", "0", "--retention-interval", "1"},
                  env, (dir / "refused.log").string());
  EXPECT_EQ(refused.wait(30s), 2) << refused.log();
  EXPECT_NE(refused.log().find("--retention-interval: this process runs no analysis"), std::string::npos) << refused.log();

  start_service({"--parts", "ingest,rest", "--retention", defaults.string()});
  Process analysis({AMBDIAG_CLI, "serve", "--db", *location, "--parts", "analysis", "--instance", "worker-1", "--retention",
                    defaults.string(), "--retention-interval", "0.5"},
                   env, (dir / "analysis.log").string());
  put_model();
  ASSERT_TRUE(replay(data_file("reference_pump/run_ref_1")));
  // Its analysis ends first (a queued or running job keeps the run).
  const auto run = wait_for(run_url(kRefRun), [](const nlohmann::json& j) { return j["samples"] == "dropped"; }, 90s);
  EXPECT_EQ(run["samples_dropped_bytes"], 6553600);
  EXPECT_EQ(get(run_url(kRefRun) + "/samples.f32")->status, 410);
  EXPECT_TRUE(json_of(client().Get("/api/v1/health"))["retention"].is_null()) << "the ingest,rest process never swept";
  analysis.signal(SIGTERM);
  EXPECT_EQ(analysis.wait(30s), 0) << analysis.log();
}

}  // namespace
}  // namespace ambdiag::testing
