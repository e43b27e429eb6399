// A failover of PostgreSQL itself under a streaming `ambdiag serve`
// (docs/deployment.md, "PostgreSQL replication and failover"): the primary
// crashes (kill -9 of its postmaster) while paced agents stream, and its
// standby is promoted, as a plant's cluster manager (Patroni,
// pg_auto_failover) would do it. The server's URI names both hosts with
// target_session_attrs=read-write, so its reconnects find whichever is the
// primary; until the promotion its commits fail and it acknowledges
// nothing.
//
// The fault that tells the two replications apart: the standby is down for
// the last second before the crash (it restarts right after), as a standby
// that fell behind. With synchronous replication the primary's commits wait
// for it, so nothing is acknowledged that the standby lacks: every run
// completes, sample for sample. (Pausing only its WAL receiver does not
// tell them apart: a second of WAL fits in the socket's buffers.) With asynchronous replication the primary
// commits and acknowledges on; the agents delete those blocks; the
// promoted standby never had them: runs end incomplete. The second test is
// the control that shows the first one's fault bites.
#include <signal.h>

#include <cstdio>

#include "failover_fixture.h"
#include "pg_cluster.h"

namespace ambdiag::testing {
namespace {

// The ingest failover tests' paced runs, agents and waits (failover_fixture.h).
class PostgresFailoverTest : public FailoverTest {
 protected:
  fs::path pg_dir = fs::temp_directory_path() / ("ambdiag-pgfo-" + std::to_string(getpid()));
  std::optional<PgCluster> primary, standby;

  void SetUp() override {
    if (postgres_tests_disabled()) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
    primary = PgCluster::start(pg_dir / "primary");
    standby = PgCluster::start_standby(pg_dir / "standby", *primary, "standby_a");
    db = "postgresql:///postgres?host=" + primary->dir().string() + "," + standby->dir().string() +
         "&port=5432,5432&user=postgres&target_session_attrs=read-write&connect_timeout=2";
  }
  void TearDown() override {
    PgCluster::stop(pg_dir / "primary");
    PgCluster::stop(pg_dir / "standby");
    std::error_code ec;
    fs::remove_all(pg_dir, ec);
  }

  void replicate(bool synchronous) {
    pg_sql(primary->uri(), std::string("ALTER SYSTEM SET synchronous_standby_names = '") +
                               (synchronous ? "standby_a" : "") + "'");
    pg_sql(primary->uri(), "SELECT pg_reload_conf()");
    const std::string want = synchronous ? "sync" : "async";
    std::string state;
    for (const auto deadline = Clock::now() + 20s; Clock::now() < deadline && state != want;
         std::this_thread::sleep_for(50ms))
      state = pg_sql(primary->uri(), "SELECT sync_state FROM pg_stat_replication WHERE application_name = 'standby_a'");
    ASSERT_EQ(state, want);
  }

  struct Outcome {
    int complete = 0;     // runs complete in the historian, sample for sample
    int agents_ok = 0;    // agents that ended with their run verified complete
    int64_t blocks_missing = 0;  // of every run, against its recording
    double service_back_s = -1;  // from the promotion: the server's first commit on the new primary
  };

  // Streams `n` runs, stops the standby, lets the primary run on for a
  // second, crashes it, starts the standby again and promotes it.
  Outcome fail_over(int n, const std::string& tag) {
    Outcome out;
    auto server = start_server({"--workers", "0"});
    const int port = rest_port(*server);
    EXPECT_GT(port, 0) << server->log();
    const auto rs = fleet_runs(n, 8.0, tag);
    auto agents = start_agents(rs);
    EXPECT_TRUE(wait_chunks(rs, 4, 30s)) << server->log();

    standby->shut_down();
    std::this_thread::sleep_for(1s);
    const std::string primary_lsn = pg_sql(primary->uri(), "SELECT pg_current_wal_lsn()::text");
    primary->crash();
    const auto crashed = Clock::now();
    standby->start_again();
    std::this_thread::sleep_for(500ms);  // the cluster manager notices
    const auto commits_before = commits(port);  // none succeeds now: no primary
    std::printf("%s: WAL at the crash %s, on the standby %s\n", tag.c_str(), primary_lsn.c_str(),
                pg_sql(standby->uri(), "SELECT pg_last_wal_replay_lsn()::text").c_str());
    standby->promote();
    const auto promoted = Clock::now();
    std::printf("%s: primary crashed; standby promoted after %.2f s\n", tag.c_str(), since(crashed));
    for (const auto deadline = Clock::now() + 30s; Clock::now() < deadline; std::this_thread::sleep_for(20ms))
      if (commits(port) > commits_before) {
        out.service_back_s = since(promoted);
        break;
      }
    for (auto& a : agents) out.agents_ok += a->wait(120s) == 0 ? 1 : 0;
    for (const auto& r : rs) {
      const RunRecording rec = read_run(r.string());
      const auto info = find_run(rec.run_id);
      out.blocks_missing += (rec.frame_count() + 511) / 512 - (info ? info->received_chunks : 0);
      if (info && info->status == storage::RunStatus::complete &&
          stored_samples(rec.run_id) == read_file_bytes((r / "samples.f32").string()))
        ++out.complete;
    }
    std::printf("%s: first commit on the new primary %.2f s after the promotion; %d of %d runs complete, %d agents "
                "verified, %lld blocks missing\n",
                tag.c_str(), out.service_back_s, out.complete, n, out.agents_ok,
                static_cast<long long>(out.blocks_missing));
    std::fflush(stdout);
    server->signal(SIGTERM);
    EXPECT_EQ(server->wait(30s), 0) << server->log();
    return out;
  }

  // The ingest's commits so far (its health), -1 when it does not answer.
  static int64_t commits(int port) {
    const auto h = health_on_port(port);
    return h.contains("ingest") ? h["ingest"].value("commits", int64_t{-1}) : -1;
  }
};

TEST_F(PostgresFailoverTest, WithASynchronousStandbyAFailoverLosesNothingAcknowledged) {
  replicate(true);
  const auto out = fail_over(3, "SYNC");
  EXPECT_GE(out.service_back_s, 0);
  EXPECT_EQ(out.complete, 3);
  EXPECT_EQ(out.agents_ok, 3);
  EXPECT_EQ(out.blocks_missing, 0);
}

TEST_F(PostgresFailoverTest, WithAnAsynchronousStandbyTheSameFailoverLosesAcknowledgedBlocks) {
  replicate(false);
  const auto out = fail_over(3, "ASYNC");
  EXPECT_GE(out.service_back_s, 0);
  // The control: what the primary acknowledged during the standby's pause
  // is gone, and the agents deleted it.
  EXPECT_LT(out.complete, 3);
  EXPECT_GT(out.blocks_missing, 0);
  EXPECT_LT(out.agents_ok, 3);  // and the agents say so: nothing is lost silently
}

}  // namespace
}  // namespace ambdiag::testing
