// Fault tests over real processes on loopback (LABEL slow: each takes 5-15 s).
#include <signal.h>

#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

// kill -9 the server mid-run and restart it: the agent spools (to disk:
// memory_blocks 4), re-sends its backlog, the run completes with every
// block stored exactly once.
TEST_F(StreamTest, ServerKilledMidRunRunCompletesWithoutLossOrDuplicates) {
  const std::string run_id = "P-101/server-killed";
  const fs::path run_dir = short_run(6.0, run_id);
  const fs::path cfg = write_scratch("agent.json", R"({"spool": {"memory_blocks": 4, "limit_bytes": 67108864}, "block_frames": 128})");
  auto server = start_server();
  auto agent = start_agent(run_dir, {"--config", cfg.string(), "--timeout", "30"});
  ASSERT_TRUE(wait_status(run_id, storage::RunStatus::receiving, 10s)) << server->log();
  std::this_thread::sleep_for(1500ms);
  server->signal(SIGKILL);
  ASSERT_EQ(server->wait(5s), -SIGKILL);
  std::this_thread::sleep_for(2000ms);  // the agent streams on into its spool
  auto server2 = start_server();
  ASSERT_EQ(agent->wait(60s), 0) << agent->log() << "\n--- server ---\n" << server2->log();
  server2->signal(SIGTERM);
  EXPECT_EQ(server2->wait(15s), 0);

  const auto info = find_run(run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  const std::string expected = read_file_bytes((run_dir / "samples.f32").string());
  EXPECT_EQ(info->received_chunks, static_cast<int64_t>((expected.size() / (16 * 4) + 127) / 128));
  EXPECT_EQ(stored_samples(run_id), expected);
  EXPECT_NE(agent->log().find("server gone"), std::string::npos) << agent->log();
}

// kill -9 the agent mid-run: the server marks the run incomplete after its
// agent timeout.
TEST_F(StreamTest, AgentKilledMidRunRunMarkedIncomplete) {
  const std::string run_id = "P-101/agent-killed";
  auto server = start_server({"--agent-timeout", "1.5"});
  auto agent = start_agent(short_run(8.0, run_id), {});
  ASSERT_TRUE(wait_status(run_id, storage::RunStatus::receiving, 10s)) << server->log();
  std::this_thread::sleep_for(1000ms);
  agent->signal(SIGKILL);
  ASSERT_TRUE(wait_status(run_id, storage::RunStatus::incomplete, 10s)) << server->log();
  const auto info = find_run(run_id);
  EXPECT_NE(info->status_reason.find("silent"), std::string::npos) << info->status_reason;
  EXPECT_GT(info->received_chunks, 0);
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0);
}

}  // namespace
}  // namespace ambdiag::testing
