// What is PostgreSQL's own in the historian: the location and its errors
// (a server that is not there, a login refused, a database that is not a
// historian or is newer, a reader before any writer), passwords masked in
// messages, the schema's bookkeeping and partitions, durability at commit,
// text PostgreSQL cannot hold, a connection lost and found again.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <functional>
#include <thread>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "pg_cluster.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::cut_chunks;
using ambdiag::testing::pg_sql;
using ambdiag::testing::run_json_text;
using ambdiag::testing::samples_bytes;

class PostgresTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto loc = ambdiag::testing::postgres_test_location();
    if (!loc) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
    location_ = *loc;
  }
  std::string location_;
};

TEST(PostgresLocation, URIsSelectPostgresAndPasswordsAreMasked) {
  EXPECT_TRUE(is_postgres_location("postgresql://u@h/db"));
  EXPECT_TRUE(is_postgres_location("postgres:///db?host=/tmp"));
  EXPECT_FALSE(is_postgres_location("/var/lib/ambdiag/h.db"));
  EXPECT_FALSE(is_postgres_location("postgresql.db"));
  EXPECT_EQ(display_location("postgresql://ambdiag:s3cret@db.plant:5432/hist?sslmode=require"),
            "postgresql://ambdiag:***@db.plant:5432/hist?sslmode=require");
  EXPECT_EQ(display_location("postgresql://ambdiag@db/hist?password=s3cret&sslmode=require"),
            "postgresql://ambdiag@db/hist?password=***&sslmode=require");
  EXPECT_EQ(display_location("postgresql://db/hist"), "postgresql://db/hist");
  EXPECT_EQ(display_location("h.db"), "h.db");
}

TEST_F(PostgresTest, AServerThatIsNotThereIsBadInputNamingTheLocationWithoutItsPassword) {
  const std::string uri = "postgresql://ambdiag:s3cret@/hist?host=/nonexistent-dir&connect_timeout=2";
  const auto msg = input_error_of([&] { Historian::open(uri); });
  EXPECT_NE(msg.find("cannot connect"), std::string::npos) << msg;
  EXPECT_NE(msg.find("ambdiag:***@"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("s3cret"), std::string::npos) << msg;
}

TEST_F(PostgresTest, ALoginRefusedIsBadInputWithoutThePassword) {
  // The cluster trusts local logins, so a role that does not exist is what
  // the server refuses.
  const std::string uri = location_ + "&user=nobody_here&password=s3cret";
  const auto msg = input_error_of([&] { Historian::open(uri); });
  EXPECT_NE(msg.find("nobody_here"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("s3cret"), std::string::npos) << msg;
}

TEST_F(PostgresTest, CreatesItsSchemaAtTheCurrentVersionOnceAndReopens) {
  { auto h = Historian::open(location_); }
  EXPECT_EQ(pg_sql(location_, "SELECT version FROM ambdiag_schema"), std::to_string(Historian::schema_version()));
  EXPECT_EQ(pg_sql(location_, "SELECT count(*) FROM ambdiag_schema"), "1");
  for (const char* t : {"pumps", "runs", "sample_chunks", "jobs", "tokens", "series_points", "alarm_events"})
    EXPECT_EQ(pg_sql(location_, std::string("SELECT count(*) FROM pg_tables WHERE schemaname = current_schema() "
                                            "AND tablename = '") + t + "'"),
              "1")
        << t;
  auto h = Historian::open(location_);  // nothing runs twice
  EXPECT_EQ(h.count_runs(), 0);
  auto r = Historian::open(location_, Historian::Mode::read);
  EXPECT_TRUE(r.list_pumps().empty());
}

TEST_F(PostgresTest, TwoWritersCreatingTheSchemaAtOnceCreateItOnce) {
  std::vector<std::thread> ts;
  std::atomic<int> failures{0};
  for (int i = 0; i < 4; ++i)
    ts.emplace_back([&] {
      try {
        Historian::open(location_);
      } catch (...) {
        ++failures;
      }
    });
  for (auto& t : ts) t.join();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(pg_sql(location_, "SELECT count(*) FROM ambdiag_schema"), "1");
}

TEST_F(PostgresTest, RefusesANewerSchemaAForeignDatabaseAndAReaderBeforeAnyWriter) {
  EXPECT_NE(input_error_of([&] { Historian::open(location_, Historian::Mode::read); }).find("no ambdiag historian"),
            std::string::npos);
  EXPECT_EQ(pg_sql(location_, "SELECT count(*) FROM pg_tables WHERE schemaname = current_schema()"), "0");  // reader created nothing
  { auto h = Historian::open(location_); }
  pg_sql(location_, "UPDATE ambdiag_schema SET version = version + 1");
  EXPECT_NE(input_error_of([&] { Historian::open(location_); }).find("newer than this program"), std::string::npos);
  EXPECT_NE(input_error_of([&] { Historian::open(location_, Historian::Mode::read); }).find("newer"), std::string::npos);

  const auto other = ambdiag::testing::postgres_test_location().value();
  pg_sql(other, "CREATE TABLE plant_data (x integer)");
  const auto msg = input_error_of([&] { Historian::open(other); });
  EXPECT_NE(msg.find("not an ambdiag historian"), std::string::npos) << msg;
  EXPECT_EQ(pg_sql(other, "SELECT count(*) FROM pg_tables WHERE schemaname = current_schema()"), "1");  // left untouched
}

TEST_F(PostgresTest, ChunksLandInThePartitionedTableWithTheirRunsTime) {
  auto h = Historian::open(location_);
  const auto header = run_header_from_json(run_json_text("P-7/a", 2));
  h.begin_run(header);
  const auto bytes = samples_bytes(300, 2, 1);
  h.put_chunks("P-7/a", cut_chunks(bytes, 2, 100));
  // In the partition of the run's UTC day, which the historian made ahead.
  const std::string part = "sample_chunks_d" + pg_sql(location_,
                                                      "SELECT to_char(CAST(created_at AS timestamptz) AT TIME ZONE 'UTC', "
                                                      "'YYYYMMDD') FROM runs");
  EXPECT_EQ(pg_sql(location_, "SELECT count(*) FROM " + part), "3");
  EXPECT_EQ(pg_sql(location_, "SELECT count(*) FROM sample_chunks_default"), "0");
  EXPECT_EQ(pg_sql(location_, "SELECT count(DISTINCT run_created_at) FROM sample_chunks"), "1");
  EXPECT_EQ(pg_sql(location_,
                   "SELECT count(*) FROM sample_chunks c JOIN runs r USING (run_id) WHERE c.run_created_at = "
                   "CAST(r.created_at AS timestamptz)"),
            "3");
  for (const std::string& table : {std::string("sample_chunks_default"), std::string("sample_chunks_kept"), part})
    EXPECT_EQ(pg_sql(location_, "SELECT attstorage FROM pg_attribute WHERE attrelid = '" + table +
                                    "'::regclass AND attname = 'data'"),
              "e")
        << table;  // EXTERNAL: out of line, not compressed
}

TEST_F(PostgresTest, EveryCommitIsDurableAtOnceAndTheListenerHearsOfIt) {
  auto h = Historian::open(location_);
  h.checkpoint_in_background();
  std::vector<std::uint64_t> heard;
  h.on_durable([&](std::uint64_t g) { heard.push_back(g); });
  const auto start = h.commit_generation();
  h.begin_run(run_header_from_json(run_json_text("P-7/a", 2)));
  EXPECT_EQ(h.commit_generation(), start + 1);
  EXPECT_EQ(h.durable_generation(), h.commit_generation());
  {
    auto batch = h.write_batch();
    h.put_chunks("P-7/a", cut_chunks(samples_bytes(100, 2, 1), 2, 50));
    h.mark_incomplete("P-7/a", "test");
    batch.commit();  // one commit for the batch
  }
  EXPECT_EQ(heard, (std::vector<std::uint64_t>{start + 1, start + 2}));
  h.read_samples("P-7/a");  // a read transaction commits nothing
  EXPECT_EQ(h.commit_generation(), start + 2);
  h.on_durable(nullptr);
  EXPECT_EQ(h.checkpoint_stats().durable_generation, start + 2);
}

TEST_F(PostgresTest, TextPostgresCannotHoldIsBadInputAndTheConnectionGoesOn) {
  auto h = Historian::open(location_);
  const std::string bad_utf8 = "P-7/\xff\xfe";
  EXPECT_THROW(h.find_run(bad_utf8), InputError);
  EXPECT_THROW(h.find_run(std::string("P-7/\0x", 6)), InputError);  // a NUL byte
  EXPECT_FALSE(h.find_run("P-7/a"));
  h.begin_run(run_header_from_json(run_json_text("P-7/a", 2)));
  EXPECT_TRUE(h.find_run("P-7/a"));
}

TEST_F(PostgresTest, AConnectionTheServerEndedIsOpenedAgainOutsideATransaction) {
  const std::string app = "reconnect_" + std::to_string(getpid());
  auto h = Historian::open(location_ + "&application_name=" + app);
  h.begin_run(run_header_from_json(run_json_text("P-7/a", 2)));
  ASSERT_TRUE(h.find_run("P-7/a"));
  // The server ends the historian's session (a restart, an administrator).
  EXPECT_EQ(pg_sql(location_, "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity WHERE application_name = '" +
                                  app + "'"),
            "1");
  // A read outside a transaction is made again on a new connection.
  EXPECT_TRUE(h.find_run("P-7/a"));
  h.begin_run(run_header_from_json(run_json_text("P-7/b", 2)));
  EXPECT_EQ(h.count_runs(), 2);
  // A statement this connection has not prepared yet: its PREPARE is what
  // finds the connection gone (a server started during a restart died so).
  pg_sql(location_, "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = '" + app + "'");
  EXPECT_EQ(h.list_runs("P-7").size(), 2u);
  // A write transaction's BEGIN too; one whose connection goes inside it fails, nothing stored.
  pg_sql(location_, "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = '" + app + "'");
  h.begin_run(run_header_from_json(run_json_text("P-7/c", 2)));
  {
    auto batch = h.write_batch();
    h.begin_run(run_header_from_json(run_json_text("P-7/d", 2)));
    pg_sql(location_, "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = '" + app + "'");
    EXPECT_THROW(h.begin_run(run_header_from_json(run_json_text("P-7/e", 2))), StorageError);
  }
  EXPECT_EQ(h.count_runs(), 3);
  EXPECT_FALSE(h.find_run("P-7/d"));
}

// A server this process reached before that is restarting: the next open
// waits for it (up to 10 s) instead of failing, so a thread that opens its
// historian then (a worker, a lease keeper) does not end the server; a
// location never reached still fails at once.
TEST(PostgresRestart, AnOpenWaitsForAServerReachedBeforeAndANewLocationFailsAtOnce) {
  if (ambdiag::testing::postgres_tests_disabled()) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1";
  const std::string dir = "/tmp/ambdiag-pg-reopen-" + std::to_string(getpid());
  auto cluster = ambdiag::testing::PgCluster::start(dir);
  const std::string loc = cluster.fresh_schema_uri("reopen");
  Historian::open(loc).begin_run(run_header_from_json(run_json_text("P-7/a", 2)));
  cluster.shut_down();
  std::thread later([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(800));
    cluster.start_again();
  });
  const auto t0 = std::chrono::steady_clock::now();
  std::optional<Historian> h;
  EXPECT_NO_THROW(h.emplace(Historian::open(loc)));
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  later.join();
  EXPECT_GE(waited_s, 0.5);  // it did wait for the start
  EXPECT_TRUE(h && h->find_run("P-7/a"));
  const auto t1 = std::chrono::steady_clock::now();
  EXPECT_THROW(Historian::open("postgresql:///postgres?host=" + dir + "-none&user=postgres"), InputError);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count(), 2.0);
  h.reset();
  ambdiag::testing::PgCluster::stop(dir);
}

}  // namespace
}  // namespace ambdiag::storage
