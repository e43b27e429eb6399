// End to end over real processes on loopback: ambdiag-agent replays a
// recording into `ambdiag serve`; the historian must hold it byte for byte.
#include <signal.h>

#include <httplib.h>

#include "ambdiag/server/rest_server.h"

#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(StreamTest, ReplayedRunIsStoredByteForByteAndVerified) {
  const fs::path run_dir = data_file("reference_pump/run_ref_1");
  const RunRecording rec = read_run(run_dir.string());
  auto server = start_server();
  const int port = rest_port(*server);
  ASSERT_GT(port, 0) << server->log();
  auto agent = start_agent(run_dir, {"--fast", "--timeout", "30"});
  const int rc = agent->wait(60s);
  ASSERT_EQ(rc, 0) << agent->log() << "\n--- server ---\n" << server->log();

  // Read back over REST while the server runs: the recording's bytes exactly.
  const std::string expected = read_file_bytes((run_dir / "samples.f32").string());
  httplib::Client http("127.0.0.1", port);
  const auto res = http.Get("/api/v1/runs/" + server::url_encode_segment(rec.run_id) + "/samples.f32");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_TRUE(res->body == expected) << "REST samples differ from the recording (" << res->body.size() << " vs "
                                     << expected.size() << " bytes)";
  const auto run = http.Get("/api/v1/runs/" + server::url_encode_segment(rec.run_id));
  ASSERT_TRUE(run);
  EXPECT_EQ(nlohmann::json::parse(run->body).at("status"), "complete") << run->body;
  EXPECT_EQ(nlohmann::json::parse(run->body).at("checksum_kind"), "xxh64") << run->body;  // protocol 1.1
  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(15s), 0) << server->log();

  const auto info = find_run(rec.run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  EXPECT_EQ(info->received_frames, rec.frame_count());
  EXPECT_TRUE(stored_samples(rec.run_id) == expected);
}

// Store-and-forward: no server at first, the spool (1 in memory, 1 MiB on
// disk) fills and the agent says so; when the server comes the backlog goes
// out, the source resumes, and the run arrives whole.
TEST_F(StreamTest, AgentSpoolsUntilFullThenForwardsWhenServerAppears) {
  const fs::path run_dir = data_file("reference_pump/run_ref_1");
  const RunRecording rec = read_run(run_dir.string());
  const fs::path cfg = write_scratch("agent.json", R"({"spool": {"memory_blocks": 1, "limit_bytes": 1048576}})");
  auto agent = start_agent(run_dir, {"--fast", "--config", cfg.string(), "--timeout", "30"});
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (agent->log().find("spool full") == std::string::npos && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(50ms);
  ASSERT_NE(agent->log().find("spool full"), std::string::npos) << agent->log();
  EXPECT_TRUE(agent->running());
  auto server = start_server();
  ASSERT_EQ(agent->wait(60s), 0) << agent->log() << "\n--- server ---\n" << server->log();
  EXPECT_NE(agent->log().find("source resumed"), std::string::npos) << agent->log();
  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(15s), 0) << server->log();
  const auto info = find_run(rec.run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  EXPECT_TRUE(stored_samples(rec.run_id) == read_file_bytes((run_dir / "samples.f32").string()));
}

TEST_F(StreamTest, AgentWithoutServerTimesOutWithClearMessage) {
  auto agent = start_agent(short_run(0.5, "P-101/no-server"), {"--fast", "--timeout", "2"});
  EXPECT_EQ(agent->wait(20s), 1);
  EXPECT_NE(agent->log().find("no server matched"), std::string::npos) << agent->log();
}

}  // namespace
}  // namespace ambdiag::testing
