// The service's own routes with real processes (issue 19): a real `ambdiag
// serve` whose ingest and analysis publish to GET /api/v1/events while an
// agent streams a run, and whose GET /metrics then counts the run and the
// analysis, checked by Prometheus' promtool.
#include <atomic>
#include <fstream>
#include <mutex>
#include <regex>
#include <thread>

#include "ambdiag/core/io_util.h"
#include "event_stream.h"
#include "service_fixture.h"

namespace ambdiag::testing {
namespace {

constexpr const char* kRefRun = "P-101/2026-11-21T10:00:00Z";

double series(const std::string& text, const std::string& name_and_labels) {
  const auto at = text.find("\n" + name_and_labels + " ");
  return at == std::string::npos ? -1 : std::stod(text.substr(at + name_and_labels.size() + 2));
}

TEST_F(ServiceTest, AStreamedRunAndItsAnalysisAppearAsEventsAndInTheMetrics) {
  start_service(
      {"--rate-limit", "0"});  // no limit (the benchmarks' setting): the burst's default must follow
  EventStream events(port, tokens.at("viewer"));  // as a browser's EventSource: the token in the query
  ASSERT_TRUE(events.wait_connected());
  ASSERT_EQ(put("/api/v1/pumps/P-101/model", read_file_bytes(data_file("reference_pump/plant.json").string()))
                ->status,
            200);
  ASSERT_TRUE(events.wait_for("model.new", "pump_id", "P-101", 10s)) << events.seen();
  ASSERT_TRUE(replay(data_file("reference_pump/run_ref_1")));

  const auto fresh = events.wait_for("run.new", "run_id", kRefRun);
  ASSERT_TRUE(fresh) << events.seen() << server->log();
  EXPECT_EQ((*fresh)["pump_id"], "P-101");
  EXPECT_EQ((*fresh)["kind"], "identification");
  const auto status = events.wait_for("run.status", "run_id", kRefRun);
  ASSERT_TRUE(status) << events.seen();
  EXPECT_EQ((*status)["status"], "complete");
  const auto done = events.wait_for("job.done", "run_id", kRefRun);
  ASSERT_TRUE(done) << events.seen() << server->log();
  EXPECT_EQ((*done)["kind"], "analysis");
  EXPECT_EQ((*done)["model_version"], 1);
  EXPECT_EQ(json_of(get(run_url(kRefRun) + "/analysis"))["status"], "done");

  const auto r = client().Get("/metrics");  // no token
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const std::string& text = r->body;
  EXPECT_EQ(series(text, R"(ambdiag_ingest_runs_total{outcome="complete"})"), 1) << text;
  EXPECT_GE(series(text, "ambdiag_ingest_run_headers_total"), 1) << text;  // an agent may send it again
  EXPECT_GT(series(text, "ambdiag_ingest_blocks_stored_total"), 0) << text;
  EXPECT_EQ(series(text, R"(ambdiag_ingest_rejected_samples_total{reason="checksum"})"), 0) << text;
  EXPECT_EQ(series(text, R"(ambdiag_jobs{kind="analysis",status="done"})"), 1) << text;
  EXPECT_EQ(series(text, R"(ambdiag_job_duration_seconds_count{kind="analysis",outcome="done"})"), 1) << text;
  EXPECT_GT(series(text, R"(ambdiag_job_cpu_seconds_total{kind="analysis"})"), 0) << text;
  EXPECT_EQ(series(text, "ambdiag_event_streams"), 1) << text;
  EXPECT_GE(
      series(
          text,
          R"(ambdiag_http_requests_total{route="/api/v1/pumps/{pump_id}/model",method="PUT",status="200"})"),
      1)
      << text;

  const fs::path file = dir / "metrics.txt";
  std::ofstream(file) << text;
  const fs::path out = dir / "promtool.log";
  const int rc =
      std::system(("promtool check metrics < " + file.string() + " > " + out.string() + " 2>&1").c_str());
  EXPECT_EQ(WEXITSTATUS(rc), 0) << read_file_bytes(out.string());
  EXPECT_EQ(read_file_bytes(out.string()), "");
}

}  // namespace
}  // namespace ambdiag::testing
