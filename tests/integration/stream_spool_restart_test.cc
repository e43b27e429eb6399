// The agent's spool survives the agent: real processes on loopback.
#include <signal.h>

#include <fstream>

#include "stream_fixture.h"

namespace ambdiag::testing {
namespace {

class SpoolRestartTest : public StreamTest {
 protected:
  fs::path spool = dir / "spool";

  // Replays `run_dir` as fast as possible with no server until the whole run
  // (its end.json) is in the spool, then kill -9 the agent.
  void spool_whole_run_and_kill_agent(const fs::path& run_dir) {
    auto agent = start_agent(run_dir, {"--fast", "--timeout", "60"});
    const auto deadline = std::chrono::steady_clock::now() + 30s;
    while (!spooled_end() && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(20ms);
    ASSERT_TRUE(spooled_end()) << agent->log();
    agent->signal(SIGKILL);
    ASSERT_EQ(agent->wait(5s), -SIGKILL);
  }
  std::optional<fs::path> spooled_end() const {
    if (!fs::exists(spool)) return std::nullopt;
    for (const auto& e : fs::recursive_directory_iterator(spool))
      if (e.path().filename() == "end.json") return e.path();
    return std::nullopt;
  }
  std::unique_ptr<Process> start_forward() {
    return std::make_unique<Process>(
        std::vector<std::string>{AMBDIAG_AGENT, "forward", "--domain", std::to_string(domain), "--partition", partition, "--spool-dir",
                                 spool.string(), "--timeout", "30"},
        env, (dir / ("forward" + std::to_string(log_n++) + ".log")).string());
  }
};

// (0) Two agents given one spool folder: the second is refused at once
// (exit 3, naming the folder and the first agent's pid) and the first
// streams its run to the end; an agent killed with -9 frees the folder.
TEST_F(SpoolRestartTest, ASecondAgentOnTheSameSpoolFolderIsRefusedAndTheFirstCompletes) {
  auto server = start_server();
  const fs::path first_run = short_run(3.0, "LOCK/1"), second_run = short_run(0.5, "LOCK/2");
  auto first = start_agent(first_run);  // paced: 3 s of streaming
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  // The lock is held once the file holds the first agent's pid (written
  // after the flock; the file itself exists a moment before it).
  const auto lock_holder = [&] {
    std::ifstream in(spool / "agent.lock");
    std::string pid;
    in >> pid;
    return pid;
  };
  while (lock_holder() != std::to_string(first->pid()) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(20ms);
  auto second = start_agent(second_run, {"--fast"});
  ASSERT_EQ(second->wait(20s), 3) << second->log();
  EXPECT_NE(second->log().find("spool folder " + spool.string() + " is in use by another ambdiag-agent (pid " +
                               std::to_string(first->pid()) + ")"),
            std::string::npos)
      << second->log();
  ASSERT_EQ(first->wait(60s), 0) << first->log() << "\n--- server ---\n" << server->log();
  const auto info = find_run("LOCK/1");
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  EXPECT_FALSE(find_run("LOCK/2"));

  // No server now: a third agent takes the folder and waits for one; kill -9
  // it there. The kernel drops its lock: a fourth agent gets the folder.
  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(15s), 0) << server->log();
  auto third = start_agent(second_run, {"--fast", "--timeout", "60"});
  const auto holding = std::chrono::steady_clock::now() + 20s;
  while (third->log().find("run LOCK/2 of pump") == std::string::npos && std::chrono::steady_clock::now() < holding)
    std::this_thread::sleep_for(20ms);
  ASSERT_NE(third->log().find("run LOCK/2 of pump"), std::string::npos) << third->log();
  third->signal(SIGKILL);
  ASSERT_EQ(third->wait(5s), -SIGKILL);
  server = start_server();
  auto fourth = start_agent(second_run, {"--fast", "--timeout", "60"});
  EXPECT_EQ(fourth->wait(60s), 0) << fourth->log();
  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(15s), 0) << server->log();
  const auto second_info = find_run("LOCK/2");
  ASSERT_TRUE(second_info);
  EXPECT_EQ(second_info->status, storage::RunStatus::complete) << second_info->status_reason;
}

// (1) kill -9 while the server is down and the spool holds the run; then
// the server, then a new agent: the run is complete, stored once, equal to
// the recording sample for sample, and the spool is empty.
TEST_F(SpoolRestartTest, RunSpooledByAKilledAgentIsForwardedByTheNextOneExactlyOnce) {
  const fs::path run_dir = data_file("reference_pump/run_ref_1");
  const RunRecording rec = read_run(run_dir.string());
  spool_whole_run_and_kill_agent(run_dir);
  if (HasFatalFailure()) return;
  EXPECT_FALSE(find_run(rec.run_id));  // nothing reached a server

  auto server = start_server();
  auto agent = start_forward();
  ASSERT_EQ(agent->wait(60s), 0) << agent->log() << "\n--- server ---\n" << server->log();
  EXPECT_NE(agent->log().find("forwarding spooled run " + rec.run_id), std::string::npos) << agent->log();
  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(15s), 0) << server->log();

  const auto info = find_run(rec.run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, storage::RunStatus::complete) << info->status_reason;
  const int64_t frames = rec.frame_count();
  EXPECT_EQ(info->received_frames, frames);
  EXPECT_EQ(info->received_chunks, (frames + 511) / 512);
  EXPECT_TRUE(stored_samples(rec.run_id) == read_file_bytes((run_dir / "samples.f32").string()));
  // The run's folder is removed once the server gave its verdict; the
  // agents' lock file (agent.lock) stays.
  for (const auto& e : fs::directory_iterator(spool))
    EXPECT_EQ(e.path().filename(), "agent.lock") << "left in the spool: " << e.path();
}

// (2) a spool whose last block record was cut in the middle (a crash while
// appending): the agent says so, drops it, forwards the rest; the server
// finds the run short and marks it incomplete. Nothing crashes.
TEST_F(SpoolRestartTest, SpoolFileTruncatedMidBlockIsDroppedWithAClearMessage) {
  const std::string run_id = "P-101/torn-spool";
  const fs::path run_dir = short_run(1.0, run_id);
  spool_whole_run_and_kill_agent(run_dir);
  if (HasFatalFailure()) return;
  fs::path last_segment;
  for (const auto& e : fs::directory_iterator(spooled_end()->parent_path()))
    if (e.path().extension() == ".log" && e.path() > last_segment) last_segment = e.path();
  ASSERT_FALSE(last_segment.empty());
  fs::resize_file(last_segment, fs::file_size(last_segment) - 1000);

  auto server = start_server();
  auto agent = start_forward();
  EXPECT_EQ(agent->wait(60s), 1) << agent->log() << "\n--- server ---\n" << server->log();
  EXPECT_NE(agent->log().find("torn block record"), std::string::npos) << agent->log();
  ASSERT_TRUE(wait_status(run_id, storage::RunStatus::incomplete, 10s)) << server->log();
  EXPECT_TRUE(server->running());
  server->signal(SIGTERM);
  EXPECT_EQ(server->wait(15s), 0) << server->log();
}

}  // namespace
}  // namespace ambdiag::testing
