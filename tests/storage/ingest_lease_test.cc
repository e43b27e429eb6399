// Ingest groups' leases (schema v7, ingest_lease.h): one holder per group,
// decided by compare-and-set in the database; a taken-over holder can
// neither renew nor pass the check in its commits.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

class IngestLeaseTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(IngestLeaseTest);

TEST_P(IngestLeaseTest, AGroupIsRegisteredHeldByNobodyAndTakenOnceFromWhatWasSeen) {
  auto h = Historian::open(location());
  const auto joined = h.join_ingest_group("site-a", "site-a,site-a/*", 3000);
  EXPECT_EQ(joined.group, "site-a");
  EXPECT_EQ(joined.partitions, "site-a,site-a/*");
  EXPECT_EQ(joined.holder, "");
  EXPECT_EQ(joined.epoch, 0);
  EXPECT_EQ(joined.lease_ms, 3000);
  EXPECT_EQ(h.join_ingest_group("site-a", "site-a,site-a/*", 1000).lease_ms, 3000);  // joining changes nothing

  const auto taken = h.take_ingest_lease(joined, "server-1", "site-a,site-a/*", 2000);
  ASSERT_TRUE(taken);
  EXPECT_EQ(taken->holder, "server-1");
  EXPECT_EQ(taken->epoch, 1);
  EXPECT_EQ(taken->lease_ms, 2000);
  EXPECT_FALSE(taken->acquired_at.empty());
  EXPECT_LT(taken->renewed_at, taken->expires_at);
  // What server-2 saw before server-1 took it is stale now.
  EXPECT_FALSE(h.take_ingest_lease(joined, "server-2", "site-a,site-a/*", 2000));
  EXPECT_EQ(h.find_ingest_lease("site-a")->holder, "server-1");

  // A standby that saw the holder stop renewing takes it: epoch 2.
  const auto seen = *h.find_ingest_lease("site-a");
  const auto over = h.take_ingest_lease(seen, "server-2", "site-a,site-a/*", 2000);
  ASSERT_TRUE(over);
  EXPECT_EQ(over->epoch, 2);
  EXPECT_EQ(h.list_ingest_leases().size(), 1u);
  EXPECT_FALSE(h.find_ingest_lease("site-b"));
}

TEST_P(IngestLeaseTest, ATakenOverHolderCannotRenewNorPassTheCheckInItsBatch) {
  const auto path = location();
  auto first = Historian::open(path);
  auto second = Historian::open(path);
  const auto joined = first.join_ingest_group("g", "*", 3000);
  const auto mine = first.take_ingest_lease(joined, "first", "*", 3000);
  ASSERT_TRUE(mine);
  EXPECT_TRUE(first.renew_ingest_lease("g", "first", mine->epoch, 3000));
  const auto renewed = *second.find_ingest_lease("g");
  EXPECT_GT(renewed.renewals, mine->renewals);  // what standbys watch

  ASSERT_TRUE(second.take_ingest_lease(renewed, "second", "*", 3000));
  EXPECT_FALSE(first.renew_ingest_lease("g", "first", mine->epoch, 3000));
  // The same name with the old epoch is not the holder either.
  EXPECT_FALSE(second.renew_ingest_lease("g", "first", mine->epoch + 1, 3000));
  EXPECT_TRUE(second.renew_ingest_lease("g", "second", mine->epoch + 1, 3000));

  // Inside a batch the check is part of the transaction: the caller rolls
  // the batch back, and nothing it wrote stays.
  {
    auto batch = first.write_batch();
    first.begin_run(run_header_from_json(testing::run_json_text("R-1", 2)));
    EXPECT_FALSE(first.renew_ingest_lease("g", "first", mine->epoch, 3000));
  }
  EXPECT_FALSE(first.find_run("R-1"));
  EXPECT_EQ(second.find_ingest_lease("g")->holder, "second");
}

TEST_P(IngestLeaseTest, AReleasedGroupIsTakenAtOnceAndItsOldHolderHoldsNothing) {
  auto h = Historian::open(location());
  const auto mine = h.take_ingest_lease(h.join_ingest_group("g", "*", 3000), "a", "*", 3000);
  ASSERT_TRUE(mine);
  EXPECT_FALSE(h.release_ingest_lease("g", "a", mine->epoch + 1));
  EXPECT_TRUE(h.release_ingest_lease("g", "a", mine->epoch));
  const auto free = *h.find_ingest_lease("g");
  EXPECT_EQ(free.holder, "");
  EXPECT_FALSE(h.renew_ingest_lease("g", "a", mine->epoch, 3000));
  EXPECT_FALSE(h.release_ingest_lease("g", "a", mine->epoch));
  const auto next = h.take_ingest_lease(free, "b", "*", 3000);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->epoch, mine->epoch + 1);
}

TEST_P(IngestLeaseTest, PartitionsOfAHeldGroupAreNotChangedByAnotherServer) {
  auto h = Historian::open(location());
  h.join_ingest_group("g", "site-a", 3000);
  // Nobody holds it: a new configuration takes over the row.
  EXPECT_EQ(h.join_ingest_group("g", "site-a,site-a/*", 3000).partitions, "site-a,site-a/*");
  const auto mine = h.take_ingest_lease(*h.find_ingest_lease("g"), "a", "site-a,site-a/*", 3000);
  ASSERT_TRUE(mine);
  try {
    h.join_ingest_group("g", "site-b", 3000);
    ADD_FAILURE() << "joined a held group with other partitions";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'site-a,site-a/*'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("'site-b'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("'a'"), std::string::npos) << msg;
  }
  EXPECT_EQ(h.find_ingest_lease("g")->partitions, "site-a,site-a/*");
  // A standby reading other partitions never takes it.
  EXPECT_FALSE(h.take_ingest_lease(*h.find_ingest_lease("g"), "b", "site-b", 3000));
}

TEST_P(IngestLeaseTest, BadArgumentsAreRefusedNamingWhatIsWrong) {
  auto h = Historian::open(location());
  EXPECT_THROW(h.join_ingest_group("", "*", 3000), InputError);
  EXPECT_THROW(h.join_ingest_group("g", "", 3000), InputError);
  EXPECT_THROW(h.join_ingest_group("g", "*", 0), InputError);
  EXPECT_TRUE(h.list_ingest_leases().empty());
  const auto joined = h.join_ingest_group("g", "*", 3000);
  EXPECT_THROW(h.take_ingest_lease(joined, "", "*", 3000), InputError);
  EXPECT_THROW(h.renew_ingest_lease("g", "a", 1, -5), InputError);
  EXPECT_EQ(h.find_ingest_lease("g")->epoch, 0);
  auto reader = Historian::open(h.path(), Historian::Mode::read);
  EXPECT_THROW(reader.join_ingest_group("g", "*", 3000), std::logic_error);
  EXPECT_EQ(reader.find_ingest_lease("g")->partitions, "*");
}

TEST(IngestLease, AVersion6FileIsMigratedAndKeepsItsRuns) {
  const auto path = db_path();
  Historian::open(path).begin_run(run_header_from_json(testing::run_json_text("R-6", 2)));
  downgrade_schema(path, 6);
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM sqlite_schema WHERE name = 'ingest_leases'"), 0);
  EXPECT_THROW(Historian::open(path, Historian::Mode::read), InputError);  // readers do not migrate
  auto h = Historian::open(path);
  EXPECT_TRUE(h.find_run("R-6"));
  EXPECT_EQ(h.join_ingest_group("g", "*", 3000).epoch, 0);
  EXPECT_EQ(raw_query_int(path, "PRAGMA user_version"), Historian::schema_version());
}

// Many standbys that saw the same expired lease race to take it, each on
// its own connection: exactly one wins.
TEST_P(IngestLeaseTest, OfStandbysRacingForTheSameLeaseExactlyOneWins) {
  const auto path = location();
  const auto seen = Historian::open(path).join_ingest_group("g", "*", 3000);
  constexpr int kStandbys = 6;
  std::atomic<int> winners{0};
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  for (int i = 0; i < kStandbys; ++i)
    threads.emplace_back([&, i] {
      auto h = Historian::open(path);
      while (!go) std::this_thread::yield();
      if (h.take_ingest_lease(seen, "s" + std::to_string(i), "*", 3000)) ++winners;
    });
  go = true;
  for (auto& t : threads) t.join();
  EXPECT_EQ(winners.load(), 1);
  EXPECT_EQ(Historian::open(path).find_ingest_lease("g")->epoch, 1);
}

}  // namespace
}  // namespace ambdiag::storage
