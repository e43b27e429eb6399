// `ambdiag serve --db postgresql://...` with real processes: tokens made by
// `ambdiag token add` on the database, a run streamed by a real agent and
// read back over REST byte for byte, a token added while the server runs
// accepted at its next request, `ambdiag db list` on the same database; no
// password from the URI in any log.
#include <signal.h>

#include <atomic>
#include <thread>

#include "ambdiag/core/io_util.h"
#include "pg_cluster.h"
#include "service_fixture.h"

namespace ambdiag::testing {
namespace {

class PostgresServeTest : public ServiceTest {
 protected:
  void SetUp() override {
    const auto loc = postgres_test_location();
    if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
    // The test cluster trusts local logins and ignores the password; it is
    // there to be kept out of the logs.
    db = *loc + "&password=s3cret-in-uri";
  }
};

TEST_F(PostgresServeTest, AStreamedRunIsStoredAndServedByteForByteAndTokensTakeEffectAtOnce) {
  start_service();
  const fs::path run_dir = data_file("reference_pump/run_ref_1");
  const RunRecording rec = read_run(run_dir.string());
  auto agent = start_agent(run_dir, {"--fast", "--timeout", "60"});
  ASSERT_EQ(agent->wait(120s), 0) << agent->log() << "\n--- server ---\n" << server->log();

  const std::string expected = read_file_bytes((run_dir / "samples.f32").string());
  const auto samples = get(run_url(rec.run_id) + "/samples.f32");
  ASSERT_TRUE(samples);
  EXPECT_EQ(samples->status, 200);
  EXPECT_TRUE(samples->body == expected) << "REST samples differ from the recording (" << samples->body.size()
                                         << " vs " << expected.size() << " bytes)";
  const auto run = get(run_url(rec.run_id));
  ASSERT_TRUE(run);
  EXPECT_EQ(json_of(run).at("status"), "complete") << run->body;
  EXPECT_EQ(json_of(run).at("received_frames"), rec.frame_count());

  // A token added on the database while the server runs: accepted at once.
  const std::string late = add_token("late", "viewer");
  httplib::Headers h = {{"Authorization", "Bearer " + late}};
  EXPECT_EQ(client().Get("/api/v1/pumps", h)->status, 200);

  // The command line's other readers of the same database.
  Process list({AMBDIAG_CLI, "db", "list", "--db", db.string(), "--json"}, env, (dir / "list.log").string());
  ASSERT_EQ(list.wait(30s), 0) << list.log();
  EXPECT_NE(list.log().find(rec.run_id), std::string::npos) << list.log();

  server->signal(SIGTERM);
  ASSERT_EQ(server->wait(20s), 0) << server->log();
  EXPECT_EQ(stored_samples(rec.run_id), expected);  // and a reader of our own sees the same
  EXPECT_NE(server->log().find("password=***"), std::string::npos) << server->log();
  for (const auto& log : {server->log(), agent->log(), list.log()})
    EXPECT_EQ(log.find("s3cret-in-uri"), std::string::npos) << log;
}

TEST_F(PostgresServeTest, AnUnreachableDatabaseIsABadInputNamingItWithoutThePassword) {
  db = "postgresql://ambdiag:s3cret@/hist?host=/nonexistent-dir&connect_timeout=2";
  Process serve({AMBDIAG_CLI, "serve", "--db", db.string(), "--http-port", "0", "--domain", std::to_string(domain),
                 "--partition", partition},
                env, (dir / "serve.log").string());
  EXPECT_EQ(serve.wait(30s), 3) << serve.log();
  EXPECT_NE(serve.log().find("cannot connect"), std::string::npos) << serve.log();
  EXPECT_NE(serve.log().find("ambdiag:***@"), std::string::npos) << serve.log();
  EXPECT_EQ(serve.log().find("s3cret"), std::string::npos) << serve.log();
}

// The connections one `ambdiag serve` with every part holds on PostgreSQL
// (docs/deployment.md "Connections"), counted by PostgreSQL itself while
// 48 clients at once keep the REST workers busy: 1 (the ingest's writer)
// + 2 (ingest lease, timeouts) + 2 (REST writes, alarms) + 1 + 2 (job
// leases, two workers) + 16 (REST readers) + 2 (events tail and listener).
TEST_F(PostgresServeTest, OneServerHoldsABoundedNumberOfConnectionsUnderManyClients) {
  const std::string app = "conn_" + std::to_string(::getpid());
  db = db.string() + "&application_name=" + app;
  start_service({"--workers", "2", "--rate-limit", "0"});
  const std::string count_sql =
      "SELECT count(*) FROM pg_stat_activity WHERE application_name = '" + app + "'";
  std::atomic<bool> done{false};
  std::atomic<int> most{0}, failed{0};
  std::thread counter([&] {
    while (!done) {
      most = std::max(most.load(), std::stoi(pg_sql(*postgres_test_location(), count_sql)));
      std::this_thread::sleep_for(20ms);
    }
  });
  std::vector<std::thread> clients;
  for (int c = 0; c < 48; ++c)
    clients.emplace_back([&] {
      auto cl = client();
      for (int i = 0; i < 20; ++i) {
        const auto r = cl.Get("/api/v1/pumps", auth("viewer"));
        if (!r || r->status != 200) ++failed;
      }
    });
  for (auto& t : clients) t.join();
  done = true;
  counter.join();
  std::printf("connections of one server (every part, 2 workers) under 48 clients: at most %d\n", most.load());
  EXPECT_EQ(failed, 0);
  EXPECT_GT(most, 10) << "the readers were not used: the test did not test the bound";
  EXPECT_LE(most, 1 + 2 + 2 + 1 + 2 + 16 + 2);
}

}  // namespace
}  // namespace ambdiag::testing
