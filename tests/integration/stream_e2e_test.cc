// End to end over real processes on loopback: ambdiag-agent replays a
// recording into `ambdiag serve`; the historian must hold it byte for byte.
#include <signal.h>

#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(StreamTest, ReplayedRunIsStoredByteForByteAndVerified) {
  const fs::path run_dir = data_file("reference_pump/run_ref_1");
  const RunRecording rec = read_run(run_dir.string());
  auto server = start_server();
  auto agent = start_agent(run_dir, {"--fast", "--timeout", "30"});
  const int rc = agent->wait(60s);
  ASSERT_EQ(rc, 0) << agent->log() << "\n--- server ---\n" << server->log();
  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(15s), 0) << server->log();

  const auto info = find_run(rec.run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  EXPECT_EQ(info->received_frames, rec.frame_count());
  EXPECT_EQ(stored_samples(rec.run_id), read_file_bytes((run_dir / "samples.f32").string()));
}

TEST_F(StreamTest, AgentWithoutServerTimesOutWithClearMessage) {
  auto agent = start_agent(short_run(0.5, "P-101/no-server"), {"--fast", "--timeout", "2"});
  EXPECT_EQ(agent->wait(20s), 1);
  EXPECT_NE(agent->log().find("no server matched"), std::string::npos) << agent->log();
}

}  // namespace
}  // namespace ambdiag::testing
