// Failover of the ingest holder at the default lease (3 s) with eight
// paced agents (failover_fixture.h), repeated with the holder alternating
// between two servers, then a pause past the lease. Prints each
// repetition's figures and their spread: the benchmark of docs/benchmarks.md
// ("Ingest failover"): AMBDIAG_FAILOVER_REPS=N sets the repetitions (3).
#include <stdlib.h>

#include "failover_fixture.h"

namespace ambdiag::testing {
namespace {

constexpr double kLeaseS = 3.0;  // serve's default
constexpr int kAgents = 8;
constexpr double kRunS = 8.0;          // 32 blocks of 512 frames at 2048 Hz
constexpr int64_t kChunksAtKill = 24;  // killed with about 2 s of every run still to come

int repetitions() {
  const char* v = getenv("AMBDIAG_FAILOVER_REPS");
  return v ? std::max(1, atoi(v)) : 3;
}

void print_spread(const char* what, std::vector<double> v) {
  std::sort(v.begin(), v.end());
  std::printf("%s: min %.2f s, median %.2f s, max %.2f s over %zu\n", what, v.front(), v[v.size() / 2], v.back(),
              v.size());
}

TEST_F(FailoverTest, KilledHoldersAreTakenOverWithinTheTargetsRepeatedly) {
  Member servers[2] = {start_member("A", kLeaseS), {}};
  ASSERT_TRUE(wait_role(servers[0], "holder", 20s)) << servers[0].process->log();
  servers[1] = start_member("B", kLeaseS);
  ASSERT_TRUE(wait_role(servers[1], "standby", 20s)) << servers[1].process->log();
  std::vector<double> taken, first_block, complete, verdicts;
  for (int rep = 0; rep < repetitions() && !HasFailure(); ++rep) {
    Member& holder = servers[rep % 2];
    Member& standby = servers[(rep + 1) % 2];
    const auto runs = fleet_runs(kAgents, kRunS, "SLOW" + std::to_string(rep));
    auto agents = start_agents(runs);
    ASSERT_TRUE(wait_chunks(runs, kChunksAtKill, 60s)) << logs({&holder, &standby});
    holder.process->signal(SIGKILL);
    const auto killed = Clock::now();
    const auto f = measure(standby, runs, agents, killed, 90s);
    f.print("repetition " + std::to_string(rep + 1) + ": kill -9 of " + holder.name + ", lease 3 s, " +
            std::to_string(kAgents) + " paced agents");
    EXPECT_GE(f.taken_over_s, 0);
    EXPECT_LT(f.taken_over_s, 8.0);  // the targets
    EXPECT_GE(f.runs_complete_s, 0);
    EXPECT_LT(f.runs_complete_s, 12.0);
    EXPECT_LT(f.agents_done_s, 12.0);
    taken.push_back(f.taken_over_s);
    first_block.push_back(f.first_block_s);
    complete.push_back(f.runs_complete_s);
    verdicts.push_back(f.agents_done_s);
    expect_complete_once(agents, runs, logs({&standby}));
    EXPECT_EQ(holder.process->wait(5s), -SIGKILL);
    holder = start_member(holder.name, kLeaseS);  // back as the standby
    ASSERT_TRUE(wait_role(holder, "standby", 20s)) << holder.process->log();
  }
  print_spread("taken over", taken);
  print_spread("first block committed by the new holder", first_block);
  print_spread("every run complete", complete);
  print_spread("every agent's verdict", verdicts);
  EXPECT_EQ(sql_int(db, "SELECT count(*) FROM runs"), static_cast<int64_t>(kAgents) * static_cast<int64_t>(taken.size()));
  for (auto& s : servers) {
    s.process->signal(SIGTERM);
    EXPECT_EQ(s.process->wait(20s), 0) << s.process->log();
  }
}

TEST_F(FailoverTest, APausedHolderOfEightAgentsIsFencedWhenWoken) {
  auto a = start_member("A", kLeaseS, {"--agent-timeout", "4"});
  ASSERT_TRUE(wait_role(a, "holder", 20s)) << a.process->log();
  auto b = start_member("B", kLeaseS);
  ASSERT_TRUE(wait_role(b, "standby", 20s)) << b.process->log();
  const auto runs = fleet_runs(kAgents, 12.0, "PAUSE");
  auto agents = start_agents(runs);
  ASSERT_TRUE(wait_chunks(runs, 4, 60s)) << logs({&a, &b});
  const auto paused = pause_until_taken_over(a, b, kLeaseS);
  ASSERT_TRUE(paused) << logs({&b});
  std::printf("paused holder taken over after %.2f s (lease 3 s)\n", since(*paused));
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<long>(1000 * std::max(0.0, 5.0 - since(*paused)))));
  a.process->signal(SIGCONT);
  ASSERT_TRUE(wait_role(a, "standby", 15s)) << a.process->log();
  const auto when_lost = health(a)["ingest"];
  expect_complete_once(agents, runs, logs({&a, &b}));
  const auto in_a = health(a)["ingest"];
  std::printf("woken holder: %lld commits fenced\n", static_cast<long long>(in_a.value("commits_fenced", 0)));
  EXPECT_EQ(group_of(a).value("lost", 0), 1);
  EXPECT_EQ(in_a.value("commits", -1), when_lost.value("commits", -2));
  EXPECT_EQ(in_a.value("runs_incomplete", -1), 0);
  for (auto* m : {&a, &b}) {
    m->process->signal(SIGTERM);
    EXPECT_EQ(m->process->wait(20s), 0) << m->process->log();
  }
}

}  // namespace
}  // namespace ambdiag::testing
