// Failover of the ingest holder with real processes (failover_fixture.h):
// two servers in one group on one SQLite file, a 1 s lease, three paced
// agents; the holder killed, or paused past its lease and woken.
#include "failover_fixture.h"

namespace ambdiag::testing {
namespace {

TEST_F(FailoverTest, AKilledHolderIsTakenOverAndItsRunsCompleteOnceSampleForSample) {
  auto a = start_member("A", 1.0);
  ASSERT_TRUE(wait_role(a, "holder", 15s)) << a.process->log();
  auto b = start_member("B", 1.0);
  ASSERT_TRUE(wait_role(b, "standby", 15s)) << b.process->log();
  EXPECT_EQ(group_of(b).value("holder", ""), "A");

  const auto runs = fleet_runs(3, 6.0, "KILL");
  auto agents = start_agents(runs);
  ASSERT_TRUE(wait_chunks(runs, 4, 30s)) << logs({&a, &b});  // every run begun under A
  a.process->signal(SIGKILL);
  const auto killed = Clock::now();
  EXPECT_EQ(a.process->wait(5s), -SIGKILL);
  const auto f = measure(b, runs, agents, killed, 60s);
  f.print("kill -9 of the holder, lease 1 s, 3 paced agents (6 s runs, killed after 1-2 s)");
  // The targets, with the default 3 s lease: taken over within 8 s,
  // the runs complete within 12 s. Here the lease is 1 s.
  EXPECT_GE(f.taken_over_s, 0) << logs({&b});
  EXPECT_LT(f.taken_over_s, 8.0);
  EXPECT_GE(f.first_block_s, f.taken_over_s - 0.1);
  EXPECT_GE(f.runs_complete_s, 0) << logs({&b});
  EXPECT_LT(f.runs_complete_s, 12.0);
  expect_complete_once(agents, runs, logs({&b}));

  const auto g = group_of(b);
  EXPECT_EQ(g.value("role", ""), "holder");
  EXPECT_EQ(g.value("epoch", 0), 2);
  EXPECT_EQ(g.value("takeovers", 0), 1);
  const auto in = health(b)["ingest"];
  EXPECT_GT(in.value("blocks_stored", 0), 0);  // the rest of the runs, after A's part
  EXPECT_EQ(in.value("runs_complete", 0), 3);
  EXPECT_EQ(in.value("runs_incomplete", -1), 0);  // no verdict but complete, each once
  b.process->signal(SIGTERM);
  EXPECT_EQ(b.process->wait(20s), 0) << b.process->log();
  EXPECT_NE(b.process->log().find("ingest group 'default': released"), std::string::npos);
}

// A holder paused past its lease and past its agent timeout: once woken it
// sees every run of its stale view timed out; the fence keeps it from
// storing or telling the agents so, and it stands by.
TEST_F(FailoverTest, APausedHolderIsTakenOverAndWhenWokenStoresAndAcknowledgesNothing) {
  auto a = start_member("A", 1.0, {"--agent-timeout", "2"});
  ASSERT_TRUE(wait_role(a, "holder", 15s)) << a.process->log();
  auto b = start_member("B", 1.0);
  ASSERT_TRUE(wait_role(b, "standby", 15s)) << b.process->log();

  const auto runs = fleet_runs(3, 8.0, "STOP");
  auto agents = start_agents(runs);
  ASSERT_TRUE(wait_chunks(runs, 4, 30s)) << logs({&a, &b});
  const auto paused = pause_until_taken_over(a, b, 1.0);
  ASSERT_TRUE(paused) << logs({&b});
  std::printf("paused holder taken over after %.2f s (lease 1 s)\n", since(*paused));
  // Past A's agent timeout (2 s): woken, all its runs look silent.
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<long>(1000 * std::max(0.0, 3.0 - since(*paused)))));
  a.process->signal(SIGCONT);

  nlohmann::json ga;
  for (const auto deadline = Clock::now() + 10s; Clock::now() < deadline; std::this_thread::sleep_for(20ms)) {
    ga = group_of(a);
    if (ga.value("role", "") == "standby" && ga.value("lost", 0) == 1) break;
  }
  ASSERT_EQ(ga.value("role", ""), "standby") << ga.dump() << "\n" << a.process->log();
  EXPECT_EQ(ga.value("lost", 0), 1);
  EXPECT_EQ(ga.value("holder", ""), "B");
  const auto stored_when_lost = health(a)["ingest"];

  expect_complete_once(agents, runs, logs({&a, &b}));
  const auto in_a = health(a)["ingest"];
  std::printf("woken holder: %lld commits fenced, %lld blocks stored before the pause and %lld after\n",
              static_cast<long long>(in_a.value("commits_fenced", 0)),
              static_cast<long long>(stored_when_lost.value("blocks_stored", 0)),
              static_cast<long long>(in_a.value("blocks_stored", 0) - stored_when_lost.value("blocks_stored", 0)));
  EXPECT_EQ(in_a.value("blocks_stored", -1), stored_when_lost.value("blocks_stored", -2));
  EXPECT_EQ(in_a.value("commits", -1), stored_when_lost.value("commits", -2));
  // Its stale timeouts were never committed, so no agent was told "incomplete".
  EXPECT_EQ(in_a.value("runs_incomplete", -1), 0);
  EXPECT_EQ(role(a), "standby");
  EXPECT_EQ(health(b)["ingest"].value("runs_complete", 0), 3);
  EXPECT_EQ(health(b)["ingest"].value("runs_incomplete", -1), 0);
  for (auto* m : {&a, &b}) {
    m->process->signal(SIGTERM);
    EXPECT_EQ(m->process->wait(20s), 0) << m->process->log();
  }
}

}  // namespace
}  // namespace ambdiag::testing
